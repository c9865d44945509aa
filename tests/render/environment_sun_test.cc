// An environment map's sun (render/environment_sun.h) as direct light (IrrcacheSettings::
// direct_sun): the records leave its directions out of the environment's light, and DirectLight
// takes one sample of it at every shading point.
//
// The scene: a dim sky (0.05) with a 2 x 2 texel sun of irradiance about 5, 50 degrees up, over a
// diffuse floor, and a black panel that shades part of the floor from the sun. The checks:
// - the sun is found where it is, and a sky without one (or a broad bright patch) has none;
// - a record with the split counts the environment's light from every direction but the sun's:
//   its mean is the brute-force integral of L cos V over the other directions (a fine grid of
//   directions with a shadow ray each), and the record without the split adds the sun's own
//   integral (tolerances: four standard errors of the records' means, measured, and the grid's
//   own 1%); where the sun is not shaded the split records vary far less;
// - a camera sample on the floor (Li: DirectLight plus the cache's irradiance) has the same mean
//   with and without the split (four standard errors). In the open its variance is higher with
//   the split (one sun sample per camera sample, where the whole record found the sun with its
//   environment samples); in a room lit through a window the records' variance is what the split
//   removes (the image figures in docs/bench/sun-caustics-2026-12-05/).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "cache/irradiance_cache.h"
#include "render/environment_sun.h"
#include "render/image.h"
#include "render/irrcache_integrator.h"
#include "render/renderer.h"
#include "render/sampling.h"
#include "render/scene_loader.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

constexpr int kMapW = 256, kMapH = 128;

// The sun's direction (towards the sky): 50 degrees up, towards +x +z.
Vec3 SunDirection() {
  const float e = 50 * kPi / 180;
  return Normalize(Vec3(std::cos(e) * 0.6f, std::sin(e), std::cos(e) * 0.8f));
}

// A 256 x 128 lat-long map: 0.05 everywhere, and `sun_texels` x `sun_texels` texels around the
// sun's direction whose radiance sums to irradiance `sun_e` (at normal incidence). Placed as
// Mitsuba's envmap reads a map (Texture::EvalLatLong): column x at u = (x + 0.5) / w, row y at
// v = y / (h - 1), each row 1 / (h - 1) of v high.
std::string WriteSky(const std::string& name, int sun_texels, float sun_e) {
  Image map(kMapW, kMapH);
  for (Vec3& p : map.pixels) p = Vec3(0.05f);
  if (sun_texels > 0) {
    float u, v;
    EnvmapUv(SunDirection(), &u, &v);
    const float half = 0.5f * float(sun_texels - 1);
    const int x0 = int(std::lround(u * kMapW - 0.5f - half));
    const int y0 = int(std::lround(v * (kMapH - 1) - half));
    const float texel = (2 * kPi / kMapW) * (kPi / (kMapH - 1)) *
                        std::sin((float(y0) + half) * kPi / float(kMapH - 1));
    for (int y = y0; y < y0 + sun_texels; ++y)
      for (int x = x0; x < x0 + sun_texels; ++x)
        map.pixels[size_t(y) * kMapW + size_t(x)] =
            Vec3(sun_e / (float(sun_texels * sun_texels) * texel));
  }
  EXPECT_TRUE(WriteExr(map, ::testing::TempDir() + "/" + name).ok());
  return name;
}

std::string SceneXml(const std::string& map) {
  return FloorAndPanelScene(
      R"(<emitter type="envmap"><string name="filename" value=")" + map + R"("/></emitter>)",
      R"(<rotate x="1" angle="-90"/><scale value="0.5"/><translate y="1"/>)");
}

LoadedScene Load(const std::string& map) {
  return BuildLoaded(
      LoadSceneString(SceneXml(map), ::testing::TempDir() + "/sun-scene-" + map + ".xml", {}));
}

// Brute force: the floor point's irradiance from the environment over the directions outside
// the sun's region (*sky) and inside it (*sun), on a fine (theta, phi) grid over the hemisphere
// (cells of 0.09 degrees: the sun's region holds about a thousand) with a shadow ray each.
void Irradiance(const Scene& scene, const Vec3& p, double* sky, double* sun) {
  const EnvironmentSun& region = scene.environment_sun();
  constexpr int kTheta = 1024, kPhi = 4096;
  *sky = *sun = 0;
  for (int i = 0; i < kTheta; ++i) {
    const double t0 = 0.5 * kPi * i / kTheta, t1 = 0.5 * kPi * (i + 1) / kTheta;
    const float theta = float(0.5 * (t0 + t1));
    // The band's projected solid angle per phi cell: (sin^2 t1 - sin^2 t0) / 2 * dphi.
    const double w =
        0.5 * (std::sin(t1) * std::sin(t1) - std::sin(t0) * std::sin(t0)) * (2 * kPi / kPhi);
    for (int j = 0; j < kPhi; ++j) {
      const float phi = 2 * kPi * (float(j) + 0.5f) / kPhi;
      const Vec3 d(std::sin(theta) * std::cos(phi), std::cos(theta),
                   std::sin(theta) * std::sin(phi));
      if (scene.Occluded(Ray{p + Vec3(0, 1e-4f, 0), d, INFINITY})) continue;
      (region.Contains(d) ? *sun : *sky) += w * Luminance(scene.EvalEnvironment(d));
    }
  }
}

RecordStats Records(const Scene& scene, bool direct_sun, const Vec3& p, int rays, int n) {
  IrrcacheSettings settings;
  settings.record_rays = rays;
  settings.direct_sun = direct_sun;
  return FloorRecords(scene, settings, p, n, 2000, 5);
}

TEST(EnvironmentSunTest, FoundWhereItIsAndOnlyThere) {
  LoadedScene with = Load(WriteSky("sun-sky.exr", 2, 5));
  const EnvironmentSun& sun = with.scene->environment_sun();
  ASSERT_FALSE(sun.empty());
  EXPECT_GT(Dot(sun.axis(), SunDirection()), std::cos(0.02f));
  EXPECT_LT(sun.radius(), EnvironmentSun::kSunMaxRadius);
  EXPECT_TRUE(sun.Contains(SunDirection()));
  EXPECT_FALSE(sun.Contains(Normalize(SunDirection() + Vec3(0.1f, 0, 0))));
  EXPECT_NEAR(sun.irradiance(), 5.0, 0.5);
  // Its samples' density is right where the light is: the mean of L / pdf over its samples is
  // the region's integral of the environment's luminance L, measured here by brute force
  // (Contains and L on a fine grid of directions around the axis), within 4 standard errors and
  // 0.2% (the grid). And the region lies within radius() of the axis.
  Rng rng(1, 2);
  double est = 0, est2 = 0;
  constexpr int kN = 20000;
  for (int i = 0; i < kN; ++i) {
    Vec3 d;
    float pdf;
    sun.Sample(rng.Next(), rng.Next(), rng.Next(), &d, &pdf);
    EXPECT_TRUE(sun.Contains(d));
    const double v = Luminance(with.scene->EvalEnvironment(d)) / double(pdf);
    est += v;
    est2 += v * v;
  }
  const double cap = 2 * kPi * (1 - std::cos(double(sun.radius())));
  Vec3 s, t;
  MakeFrame(sun.axis(), &s, &t);
  constexpr int kGrid = 1000;  // over the square of half-width radius() in the axis' tangent plane
  const double step = 2.0 * sun.radius() / kGrid;
  double region = 0, light = 0;
  for (int i = 0; i < kGrid; ++i)
    for (int j = 0; j < kGrid; ++j) {
      const double x = -sun.radius() + (i + 0.5) * step, y = -sun.radius() + (j + 0.5) * step;
      const double r2 = x * x + y * y;
      const Vec3 d = Normalize(s * float(x) + t * float(y) + sun.axis());
      if (!sun.Contains(d)) continue;
      // The plane's area element maps to solid angle by cos^3 of the angle from the axis.
      const double omega = step * step / std::pow(1 + r2, 1.5);
      region += omega;
      light += omega * Luminance(with.scene->EvalEnvironment(d));
    }
  const double mean = est / kN, se = std::sqrt((est2 / kN - mean * mean) / kN);
  EXPECT_NEAR(mean, light, 4 * se + 0.002 * light);
  EXPECT_GT(region, 0.2 * cap);
  EXPECT_LT(region, cap);
  std::printf("MEASURED region %.3e sr (cap %.3e); its light %.4f, samples' L/pdf %.4f (se %.1e)\n",
              region, cap, light, mean, se);
  // A sky without a sun, and one whose bright patch is 20 degrees wide (a studio's softbox),
  // have none.
  LoadedScene dim = Load(WriteSky("dim-sky.exr", 0, 0));
  EXPECT_TRUE(dim.scene->environment_sun().empty());
  LoadedScene broad = Load(WriteSky("broad-sky.exr", 14, 5));
  EXPECT_TRUE(broad.scene->environment_sun().empty());
}

// A sun of the real size (0.27 degrees: 3 x 3 texels of a 2048 x 1024 map), smaller than one of
// the region's grid cells (0.35 degrees): Sample picks sub-cells finer than the map's texels, so
// one sample's estimate of the sun's irradiance, L cos / pdf, hardly varies. A perfect sampler of
// this uniform disc gives every sample the same value; a point drawn uniformly within whole cells
// would fall on the sky (value about 0) as often as on the sun (relative deviation above 1).
TEST(EnvironmentSunTest, SamplesOfASunSmallerThanACellAgree) {
  constexpr int kW = 2048, kH = 1024, kTexels = 3;
  constexpr float kSunE = 5;
  Image map(kW, kH);
  for (Vec3& p : map.pixels) p = Vec3(0.05f);
  float u0, v0;
  EnvmapUv(SunDirection(), &u0, &v0);
  const int x0 = int(u0 * kW) - 1, y0 = int(v0 * kH) - 1;
  double omega = 0;
  for (int y = y0; y < y0 + kTexels; ++y)
    omega += kTexels * (2 * kPi / kW) * (kPi / kH) * std::sin((y + 0.5) * kPi / kH);
  for (int y = y0; y < y0 + kTexels; ++y)
    for (int x = x0; x < x0 + kTexels; ++x)
      map.pixels[size_t(y) * kW + size_t(x)] = Vec3(float(kSunE / omega));
  ASSERT_TRUE(WriteExr(map, ::testing::TempDir() + "/small-sun.exr").ok());
  LoadedScene loaded = Load("small-sun.exr");
  const Scene& scene = *loaded.scene;
  const EnvironmentSun& sun = scene.environment_sun();
  ASSERT_FALSE(sun.empty());
  Rng rng(3, 4);
  constexpr int kN = 20000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < kN; ++i) {
    Vec3 d;
    float pdf;
    sun.Sample(rng.Next(), rng.Next(), rng.Next(), &d, &pdf);
    ASSERT_GT(pdf, 0);
    const double e = Luminance(scene.EvalEnvironment(d)) * Dot(d, sun.axis()) / pdf;
    sum += e;
    sum2 += e * e;
  }
  const double mean = sum / kN, sd = std::sqrt(std::max(0.0, sum2 / kN - mean * mean));
  // The region's irradiance: the sun's 5 plus the sky's 0.05 over the region's solid angle.
  EXPECT_NEAR(mean, kSunE, 0.05 * kSunE);
  EXPECT_LT(sd / mean, 0.25) << "mean " << mean;
}

TEST(EnvironmentSunTest, RecordsLeaveTheSunToDirectLight) {
  LoadedScene built = Load(WriteSky("sun-sky.exr", 2, 5));
  const Scene& scene = *built.scene;
  ASSERT_FALSE(scene.environment_sun().empty());
  constexpr int kRays = 256, kRecords = 400;
  // In the open, and in the panel's shadow (the sun 50 degrees up over a panel 1 above).
  const Vec3 points[] = {Vec3(-2, 0, -2), Vec3(-0.6f, 0, -0.8f)};
  for (const Vec3& p : points) {
    double sky, sun;
    Irradiance(scene, p, &sky, &sun);
    const RecordStats split = Records(scene, true, p, kRays, kRecords);
    const RecordStats whole = Records(scene, false, p, kRays, kRecords);
    std::printf(
        "at (%.1f, %.1f): sky %.4f sun %.4f; records split %.4f (var %.3g), whole %.4f "
        "(var %.3g)\n",
        p.x, p.z, sky, sun, split.mean, split.var, whole.mean, whole.var);
    EXPECT_NEAR(split.mean, sky, 4 * std::sqrt(split.var / kRecords) + 0.01 * sky);
    EXPECT_NEAR(whole.mean, sky + sun, 4 * std::sqrt(whole.var / kRecords) + 0.01 * (sky + sun));
    if (sun > sky) {
      EXPECT_LT(split.var, whole.var / 10);
    }
  }
}

TEST(EnvironmentSunTest, CameraSamplesAgreeWithAndWithoutTheSplit) {
  LoadedScene built = Load(WriteSky("sun-sky.exr", 2, 5));
  const Scene& scene = *built.scene;
  RenderSettings render;
  render.integrator = "irrcache";
  // A camera ray onto the floor in the open; each sample with a fresh cache (its own record).
  const Ray ray{Vec3(-2, 1, -3), Normalize(Vec3(0, -1, 1)), INFINITY};
  constexpr int kSamples = 400;
  double mean[2], var[2];
  for (const bool split : {false, true}) {
    IrrcacheSettings settings;
    settings.record_rays = 256;
    settings.direct_sun = split;
    double sum = 0, sum2 = 0;
    RenderCounters counters;
    for (int i = 0; i < kSamples; ++i) {
      IrradianceCache cache(CacheSettingsFor(scene, render));
      const IrrcacheIntegrator integrator(scene, &cache, settings);
      Rng rng(uint64_t(i), 9);
      const double l = Luminance(integrator.Li(ray, LightStrata{}, rng, counters, nullptr));
      sum += l;
      sum2 += l * l;
    }
    EXPECT_EQ(counters.nonfinite_samples, 0u);
    mean[split] = sum / kSamples;
    var[split] = std::max(0.0, sum2 / kSamples - mean[split] * mean[split]);
  }
  std::printf("whole %.5f (var %.3g), split %.5f (var %.3g)\n", mean[0], var[0], mean[1], var[1]);
  EXPECT_NEAR(mean[1], mean[0], 4 * std::sqrt((var[0] + var[1]) / kSamples));
}

// The path integrator samples the sun as direct light too (PathSettings::direct_sun, set by the
// final pass where IrrcacheSettings::direct_sun is on): the image is the same as with the sun left
// to the environment's own samples (means within their noise), and much less noisy. Noise per
// render from two seeds: mean over pixels of (a - b)^2 / 2.
TEST(EnvironmentSunTest, PathIntegratorSamplesTheSunAsDirectLight) {
  LoadedScene built = Load(WriteSky("sun-sky.exr", 2, 5));
  double mean[2], noise[2];
  for (const bool sun : {false, true}) {
    Image img[2];
    for (int k = 0; k < 2; ++k) {
      RenderSettings settings = *SettingsForScene(built.desc, "path");
      settings.spp = 64;
      settings.seed = uint64_t(11 + k);
      settings.irrcache.direct_sun = sun;
      const RenderOutput out = Render(*built.scene, settings);
      EXPECT_EQ(out.stats.counters.nonfinite_samples, 0u);
      img[k] = out.image;
    }
    double sum = 0, diff2 = 0;
    const size_t n = img[0].pixels.size();
    for (size_t i = 0; i < n; ++i) {
      const double a = Luminance(img[0].pixels[i]), b = Luminance(img[1].pixels[i]);
      sum += a + b;
      diff2 += (a - b) * (a - b);
    }
    mean[sun] = sum / double(2 * n);
    noise[sun] = diff2 / double(2 * n);  // per pixel, one render
  }
  std::printf(
      "MEASURED image mean %.4f / %.4f (environment's samples / sun as direct light), "
      "pixel variance %.3g / %.3g\n",
      mean[0], mean[1], noise[0], noise[1]);
  // The mean of 256 pixels of two renders: its variance is the pixels' over 512.
  EXPECT_NEAR(mean[1], mean[0], 4 * std::sqrt((noise[0] + noise[1]) / 512));
  EXPECT_LT(noise[1], noise[0] / 4);
}

}  // namespace
}  // namespace irfarm
