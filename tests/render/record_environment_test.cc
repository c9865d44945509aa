// Sampling an environment map by its radiance in the irradiance-cache integrator.
//
// A record's environment-map samples (IrrcacheSettings::environment_samples): next-event samples
// of the map by its radiance beside the record's strata, weighed by the balance heuristic. Under a
// dim map with one small bright patch and a black panel that shades part of the floor, records
// with them and records of strata alone must agree in the mean (both are unbiased; the tolerance
// is the two means' own standard errors, measured here), and theirs must vary much less.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "render/image.h"
#include "render/irrcache_integrator.h"
#include "render/path_tracer.h"
#include "render/render_counters.h"
#include "render/scene_loader.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

// Writes the map beside the scene (TempDir) and returns its name. 64 x 32 lat-long: 0.05
// everywhere, a 3 x 3 patch of 200 about 50 degrees up (a window or a studio lamp seen from the
// floor: about 0.5% of the sky, most of the light).
std::string WritePatchMap() {
  Image map(64, 32);
  for (Vec3& p : map.pixels) p = Vec3(0.05f, 0.05f, 0.05f);
  for (int y = 6; y < 9; ++y)
    for (int x = 20; x < 23; ++x) map.pixels[size_t(y) * 64 + size_t(x)] = Vec3(200, 180, 160);
  EXPECT_TRUE(WriteExr(map, ::testing::TempDir() + "/patch-map.exr").ok());
  return "patch-map.exr";  // beside the scene file
}

std::string SceneXml(const std::string& map) {
  return FloorAndPanelScene(
      R"(<emitter type="envmap"><string name="filename" value=")" + map + R"("/></emitter>)",
      R"(<rotate x="0" y="1" z="1" angle="70"/><scale value="0.7"/><translate y="0.6"/>)");
}

// `n` records of `rays` rays at floor point (x, z), each from its own stream.
RecordStats Records(const Scene& scene, float env_samples, float x, float z, int rays, int n) {
  IrrcacheSettings settings;
  settings.record_rays = rays;
  settings.environment_samples = env_samples;
  return FloorRecords(scene, settings, Vec3(x, 0, z), n, 1000, 3);
}

TEST(RecordEnvironmentTest, MapSamplesAgreeWithStrataAndVaryLess) {
  const std::string map = WritePatchMap();
  LoadedScene built =
      BuildLoaded(LoadSceneString(SceneXml(map), ::testing::TempDir() + "/patch-scene.xml", {}));
  const Scene& scene = *built.scene;
  ASSERT_TRUE(scene.light_sampler().has_environment_map());
  constexpr int kRays = 256, kRecords = 600;
  // Points in the open, by the panel and under it.
  const float points[][2] = {{1.5f, 1.2f}, {0.3f, -0.2f}, {-0.2f, 0.4f}, {0.0f, 0.0f}};
  int shaded = 0;
  double open = 0;
  for (const auto& pt : points) {
    const RecordStats strata = Records(scene, 0.0f, pt[0], pt[1], kRays, kRecords);
    const RecordStats mis = Records(scene, 0.25f, pt[0], pt[1], kRays, kRecords);
    const double se = std::sqrt((strata.var + mis.var) / kRecords);
    EXPECT_NEAR(mis.mean, strata.mean, 4 * se)
        << "at (" << pt[0] << ", " << pt[1] << "): " << mis.mean << " against " << strata.mean;
    if (open == 0) open = strata.mean;
    std::printf("at (%.1f, %.1f): strata %.4f (var %.3g), with map samples %.4f (var %.3g)\n",
                pt[0], pt[1], strata.mean, strata.var, mis.mean, mis.var);
    if (strata.mean < 0.7 * open) {  // the patch hidden: little to gain, nothing to lose
      ++shaded;
      continue;
    }
    EXPECT_LT(mis.var, strata.var / 4) << "at (" << pt[0] << ", " << pt[1] << "): variance "
                                       << mis.var << " against " << strata.var;
  }
  // The panel hides the patch from at least one of the points: visibility is part of the check.
  EXPECT_GE(shaded, 1);
}

// A glossy vertex of a camera path samples the map by its radiance too (GlossyDirect), and a
// glossy sample that reaches the map is weighed against that (EnvironmentMisWeight): the two
// pdfs must be the same, or the weights do not sum to 1. A rough silver plane reflecting the
// patch, seen from above: irrcache's Li and the path tracer (its own, consistent MIS) agree in the
// mean over many samples of one pixel, within 4 standard errors of the two means.
TEST(RecordEnvironmentTest, GlossyVertexWeighsTheMapAsItSamplesIt) {
  const std::string map = WritePatchMap();
  const std::string xml = R"(<scene version="3.0.0">
  <sensor type="perspective"/>
  <emitter type="envmap"><string name="filename" value=")" +
                          map + R"("/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="4"/></transform>
    <bsdf type="roughconductor"><string name="material" value="Ag"/><float name="alpha" value="0.2"/></bsdf>
  </shape>
</scene>
)";
  LoadedScene built =
      BuildLoaded(LoadSceneString(xml, ::testing::TempDir() + "/glossy-scene.xml", {}));
  const Scene& scene = *built.scene;
  IrrcacheSettings settings;
  const IrrcacheIntegrator integrator(scene, nullptr, settings);  // no diffuse lobe: no cache
  PathSettings path;
  path.env_importance = true;  // as `path` renders
  RenderCounters counters;
  // Rays from above onto the plane, in a fan: some see the patch in their lobe, some do not.
  constexpr int kSamples = 200000;
  double sum[2] = {0, 0}, sum2[2] = {0, 0};
  for (int i = 0; i < kSamples; ++i) {
    Rng rng(uint64_t(i), 11);
    const float a = 2 * kPi * float(i % 16) / 16;
    const Ray ray{Vec3(0, 1, 0), Normalize(Vec3(0.8f * std::cos(a), -1, 0.8f * std::sin(a))),
                  INFINITY};
    const double l[2] = {Luminance(integrator.Li(ray, LightStrata{}, rng, counters, nullptr)),
                         Luminance(TracePath(scene, ray, 1, false, path, rng, counters))};
    for (int k = 0; k < 2; ++k) {
      sum[k] += l[k];
      sum2[k] += l[k] * l[k];
    }
  }
  EXPECT_EQ(counters.nonfinite_samples, 0u);
  double mean[2], var[2];
  for (int k = 0; k < 2; ++k) {
    mean[k] = sum[k] / kSamples;
    var[k] = std::max(0.0, sum2[k] / kSamples - mean[k] * mean[k]);
  }
  const double se = std::sqrt((var[0] + var[1]) / kSamples);
  std::printf("irrcache %.5f, path %.5f, se %.5f\n", mean[0], mean[1], se);
  EXPECT_NEAR(mean[0], mean[1], 4 * se);
}

}  // namespace
}  // namespace irfarm
