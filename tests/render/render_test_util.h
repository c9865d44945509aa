// Shared helpers for the rendering tests: load a test scene at reduced resolution, render it,
// and compare with its low-resolution reference (tests/data/scenes/<name>/reference-x4.exr, the
// Mitsuba reference box-filtered by 4 in each direction).
#pragma once

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "render/image.h"
#include "render/irrcache_integrator.h"
#include "render/render_request.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {

// A diffuse floor (8 x 8 at y = 0, reflectance 0.5) and a black panel placed by the transform
// `panel`, seen from (0, 3, -3) at 16 x 16 pixels, lit by `emitter` (an <emitter> element): the
// scene of the tests of an environment map's light at records.
inline std::string FloorAndPanelScene(const std::string& emitter, const std::string& panel) {
  return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0, 3, -3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
  </sensor>
  )" + emitter +
         R"(
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="4"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world">)" +
         panel + R"(</transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
  </shape>
</scene>
)";
}

// The mean and variance of the luminance of n records (IrrcacheIntegrator::ComputeRecord) at the
// floor point below p (normal +y), record i from its own stream (seed + i, stream); none may have
// a non-finite sample.
struct RecordStats {
  double mean = 0, var = 0;
};
inline RecordStats FloorRecords(const Scene& scene, const IrrcacheSettings& settings, const Vec3& p,
                                int n, uint64_t seed, uint64_t stream) {
  const IrrcacheIntegrator integrator(scene, nullptr, settings);  // ComputeRecord only
  SurfaceHit hit;
  EXPECT_TRUE(scene.Intersect(Ray{p + Vec3(0, 0.05f, 0), Vec3(0, -1, 0), INFINITY}, &hit));
  RenderCounters counters;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; ++i) {
    Rng rng(seed + uint64_t(i), stream);
    const double e =
        Luminance(integrator.ComputeRecord(hit, Vec3(0, 1, 0), 1, 0.01f, rng, counters).irradiance);
    sum += e;
    sum2 += e * e;
  }
  EXPECT_EQ(counters.nonfinite_samples, 0u);
  RecordStats s;
  s.mean = sum / n;
  s.var = std::max(0.0, sum2 / n - s.mean * s.mean);
  return s;
}

inline std::string TestScenePath(const std::string& name) {
  return std::string(IRFARM_TEST_DATA) + "/scenes/" + name + "/scene.xml";
}

struct LoadedScene {
  SceneDesc desc;
  std::unique_ptr<Scene> scene;
};

// Builds the Embree scene of a loaded description (test failures, not exceptions, on errors).
inline LoadedScene BuildLoaded(const absl::StatusOr<SceneDesc>& desc) {
  LoadedScene s;
  EXPECT_TRUE(desc.ok()) << desc.status();
  s.desc = *desc;
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(s.desc);
  EXPECT_TRUE(scene.ok()) << scene.status();
  s.scene = std::move(*scene);
  return s;
}

// Loads test scene `name` at 1/`factor` of its resolution (matching reference-x<factor>.exr).
inline LoadedScene LoadScaledDown(const std::string& name, int factor) {
  absl::StatusOr<SceneDesc> full = LoadSceneFile(TestScenePath(name), LoadOptions{});
  EXPECT_TRUE(full.ok()) << full.status();
  if (!full.ok()) return LoadedScene{};
  LoadOptions opt;
  opt.defines["resx"] = std::to_string(full->camera.width / factor);
  opt.defines["resy"] = std::to_string(full->camera.height / factor);
  return BuildLoaded(LoadSceneFile(TestScenePath(name), opt));
}

// Loads test scene `name` at 1/4 of its resolution (matching reference-x4.exr).
inline LoadedScene LoadQuarter(const std::string& name) { return LoadScaledDown(name, 4); }

// relmse_est_ref_vs_truth from the scene's reference.json; box-filtering by `bin` x `bin` divides
// the variance of the reference's noise by bin^2 (by 16: the error of reference-x4.exr); 0 when
// absent.
inline double ReferenceError(const std::string& name, int bin = 4) {
  std::ifstream f(std::string(IRFARM_TEST_DATA) + "/scenes/" + name + "/reference.json");
  if (!f) return 0;
  const nlohmann::json j = nlohmann::json::parse(f, nullptr, /*allow_exceptions=*/false);
  EXPECT_FALSE(j.is_discarded()) << name << "/reference.json is not JSON";
  if (!j.is_object() || !j.contains("relmse_est_ref_vs_truth")) return 0;
  return j["relmse_est_ref_vs_truth"].get<double>() / double(bin * bin);
}

// Image `file` of test scene `name` (a test failure, and an empty image, when it cannot be read).
inline Image SceneImage(const std::string& name, const std::string& file) {
  absl::StatusOr<Image> ref =
      ReadExr(std::string(IRFARM_TEST_DATA) + "/scenes/" + name + "/" + file);
  EXPECT_TRUE(ref.ok()) << ref.status();
  return ref.ok() ? *ref : Image();
}

inline Image QuarterReference(const std::string& name) {
  return SceneImage(name, "reference-x4.exr");
}

// The full-size reference (reference.exr).
inline Image FullReference(const std::string& name) { return SceneImage(name, "reference.exr"); }

// The largest of Mitsuba's own full-size 256-spp errors against the reference
// (mitsuba_full_256spp_relmse_vs_ref in reference.json, written by mitsuba_reference.py with
// full_256); 0 when absent.
inline double Mitsuba256SppMax(const std::string& name) {
  std::ifstream f(std::string(IRFARM_TEST_DATA) + "/scenes/" + name + "/reference.json");
  const nlohmann::json j = nlohmann::json::parse(f, nullptr, /*allow_exceptions=*/false);
  EXPECT_TRUE(j.is_object()) << name << "/reference.json";
  double worst = 0;
  if (j.is_object() && j.contains("mitsuba_full_256spp_relmse_vs_ref"))
    for (const auto& v : j["mitsuba_full_256spp_relmse_vs_ref"])
      worst = std::max(worst, v.get<double>());
  EXPECT_GT(worst, 0) << name << ": no Mitsuba 256-spp errors in reference.json";
  return worst;
}

// Test scene `name` with `from` replaced by `to` in its XML (`from` must occur exactly once).
inline LoadedScene LoadVariant(const std::string& name, const std::string& from,
                               const std::string& to) {
  std::ifstream f(TestScenePath(name));
  std::stringstream ss;
  ss << f.rdbuf();
  std::string xml = ss.str();
  const size_t at = xml.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  EXPECT_EQ(xml.find(from, at + 1), std::string::npos) << from;
  if (at != std::string::npos) xml.replace(at, from.size(), to);
  return BuildLoaded(LoadSceneString(xml, TestScenePath(name), {}));
}

// The mean over pixels and channels of two images of one scene (different seeds) and its
// standard error: pixels are independent, so Var(mean of one image) = sum_p Var(pixel p) / n^2
// with Var(pixel p) estimated by (a_p - b_p)^2 / 2; the mean of both images has half of that.
struct ImageMean {
  double mean = 0;
  double std_err = 0;
};
inline ImageMean MeanOfTwo(const Image& a, const Image& b) {
  double sum = 0, var_sum = 0;
  const double n = 3.0 * double(a.pixels.size());
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      sum += double(a.pixels[i][c]) + b.pixels[i][c];
      const double d = double(a.pixels[i][c]) - b.pixels[i][c];
      var_sum += d * d / 2;
    }
  }
  return {sum / (2 * n), std::sqrt(var_sum / 2) / n};
}

// `firefly_filter` off where a test estimates a standard error from per-pixel differences between
// renders: those assume independent pixels, and a spread firefly shares its error among 25 (the
// image's mean is the same with or without it).
inline RenderOutput RenderWith(const LoadedScene& s, const std::string& integrator, int spp,
                               uint64_t seed, int threads = 0, bool firefly_filter = true) {
  RenderRequest request;
  request.firefly_filter = firefly_filter;
  request.integrator = integrator;
  request.spp = spp;
  request.seed = seed;
  request.threads = threads;
  const absl::StatusOr<RenderSettings> settings = SettingsFor(s.desc, request);
  EXPECT_TRUE(settings.ok()) << settings.status();
  return Render(*s.scene, *settings);
}

// Test scene `name` rendered by `path` and by `irrcache` at 256 spp (seed 1), full size: each
// must be below Mitsuba's own largest error at 256 spp against the reference.
inline void ExpectWithinMitsuba256Spp(const std::string& name, const LoadedScene& scene) {
  const Image ref = FullReference(name);
  const double bound = Mitsuba256SppMax(name);
  const double path = CompareImages(RenderWith(scene, "path", 256, 1).image, ref).relmse;
  const double irrcache = CompareImages(RenderWith(scene, "irrcache", 256, 1).image, ref).relmse;
  std::printf("MEASURED path %.3g, irrcache %.3g (256 spp); Mitsuba 256 spp at most %.3g\n", path,
              irrcache, bound);
  EXPECT_LT(path, bound) << name;
  EXPECT_LT(irrcache, bound) << name;
}

// A variant of test scene `name` (`what` it gets wrong) rendered by `path` at 256 spp must be
// above that bound: the test above can fail.
inline void ExpectFarFromMitsuba256Spp(const std::string& name, const char* what,
                                       const LoadedScene& variant) {
  const double e =
      CompareImages(RenderWith(variant, "path", 256, 1).image, FullReference(name)).relmse;
  std::printf("MEASURED %s: %.3g\n", what, e);
  EXPECT_GT(e, Mitsuba256SppMax(name)) << what;
}

// Per channel, the standard error of image a's mean, estimated from two independent renders a
// and b of the same settings (var(a_p) ~ (a_p - b_p)^2 / 2 per pixel, pixels independent), plus
// `ref_share` of the reference's mean (the reference's own share of the tolerance).
inline Vec3 MeanStandardError(const Image& a, const Image& b, const Vec3& mean_ref,
                              double ref_share = 1e-3) {
  Vec3 se;
  const double n = double(std::max<size_t>(1, a.pixels.size()));
  for (int c = 0; c < 3; ++c) {
    double var_sum = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i) {
      const double d = double(a.pixels[i][c]) - double(b.pixels[i][c]);
      var_sum += d * d / 2;
    }
    se[c] = float(std::sqrt(var_sum) / n + ref_share * mean_ref[c]);
  }
  return se;
}

}  // namespace irfarm
