// Shared helpers for the rendering tests: load a test scene at reduced resolution, render it,
// and compare with its low-resolution reference (tests/data/scenes/<name>/reference-x4.exr, the
// Mitsuba reference box-filtered by 4 in each direction).
#pragma once

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "render/image.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {

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

// Loads test scene `name` at 1/4 of its resolution (matching reference-x4.exr).
inline LoadedScene LoadQuarter(const std::string& name) {
  absl::StatusOr<SceneDesc> full = LoadSceneFile(TestScenePath(name), LoadOptions{});
  EXPECT_TRUE(full.ok()) << full.status();
  LoadOptions opt;
  opt.defines["resx"] = std::to_string(full->camera.width / 4);
  opt.defines["resy"] = std::to_string(full->camera.height / 4);
  return BuildLoaded(LoadSceneFile(TestScenePath(name), opt));
}

// relmse_est_ref_vs_truth from the scene's reference.json; box-filtering by 4x4 divides the
// variance of the reference's noise by 16 (the error of reference-x4.exr); 0 when absent.
inline double ReferenceError(const std::string& name) {
  std::ifstream f(std::string(IRFARM_TEST_DATA) + "/scenes/" + name + "/reference.json");
  if (!f) return 0;
  const nlohmann::json j = nlohmann::json::parse(f, nullptr, /*allow_exceptions=*/false);
  EXPECT_FALSE(j.is_discarded()) << name << "/reference.json is not JSON";
  if (!j.is_object() || !j.contains("relmse_est_ref_vs_truth")) return 0;
  return j["relmse_est_ref_vs_truth"].get<double>() / 16.0;
}

inline Image QuarterReference(const std::string& name) {
  absl::StatusOr<Image> ref =
      ReadExr(std::string(IRFARM_TEST_DATA) + "/scenes/" + name + "/reference-x4.exr");
  EXPECT_TRUE(ref.ok()) << ref.status();
  return ref.ok() ? *ref : Image();
}

inline RenderOutput RenderWith(const LoadedScene& s, const std::string& integrator, int spp,
                               uint64_t seed, int threads = 0) {
  RenderSettings settings = *SettingsForScene(s.desc, integrator);
  if (spp > 0) settings.spp = spp;
  settings.seed = seed;
  settings.threads = threads;
  return Render(*s.scene, settings);
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
