// Shadow rays through pass-through surfaces (mask, null): Scene::Occluded lets a ray through a
// masked surface with the surface's pass probability, independently at each surface it crosses
// (both sides of a sphere), and reads a textured opacity at the same (u, v) as Intersect does.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>

#include "render/sampling.h"
#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {
namespace {

// Two unit-square planes (rectangle: [-1,1]^2 at z = 0) with opacity 0.25 (z = 0) and 0.5
// (z = 1), a sphere of opacity 0.5 at x = 5, a null-material plane at z = 3 (always passes),
// and at x = -5 a plane whose opacity is a checkerboard of 1 and 0.
constexpr char kScene[] = R"(<scene version="3.0.0">
  <sensor type="perspective"/>
  <bsdf type="diffuse" id="white"/>
  <bsdf type="mask" id="quarter"><float name="opacity" value="0.25"/><ref id="white"/></bsdf>
  <bsdf type="mask" id="half"><float name="opacity" value="0.5"/><ref id="white"/></bsdf>
  <bsdf type="mask" id="checker">
    <texture type="checkerboard" name="opacity">
      <rgb name="color0" value="1, 1, 1"/>
      <rgb name="color1" value="0, 0, 0"/>
      <transform name="to_uv"><scale x="4" y="4"/></transform>
    </texture>
    <ref id="white"/>
  </bsdf>
  <bsdf type="null" id="nothing"/>
  <shape type="rectangle"><ref id="quarter"/></shape>
  <shape type="rectangle"><transform name="to_world"><translate z="1"/></transform><ref id="half"/></shape>
  <shape type="rectangle"><transform name="to_world"><translate z="3"/></transform><ref id="nothing"/></shape>
  <shape type="sphere"><point name="center" x="5" y="0" z="0"/><float name="radius" value="1"/><ref id="half"/></shape>
  <shape type="rectangle"><transform name="to_world"><translate x="-5"/></transform><ref id="checker"/></shape>
</scene>)";

std::unique_ptr<Scene> Build() {
  absl::StatusOr<SceneDesc> desc = LoadSceneString(kScene, "pass.xml", {});
  EXPECT_TRUE(desc.ok()) << desc.status();
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
  EXPECT_TRUE(scene.ok()) << scene.status();
  return scene.ok() ? std::move(*scene) : nullptr;
}

// Fraction of n shadow rays from (cx, cy, z0) + a random offset within +-0.4 in x and y, along
// +z, of length len, that get through.
double PassFraction(const Scene& scene, float cx, float cy, float z0, float len, int n) {
  Rng rng(11, 12);
  int passed = 0;
  for (int i = 0; i < n; ++i) {
    Ray r{Vec3(cx + 0.8f * (rng.Next() - 0.5f), cy + 0.8f * (rng.Next() - 0.5f), z0), Vec3(0, 0, 1),
          len};
    passed += !scene.Occluded(r);
  }
  return double(passed) / n;
}

// Binomial tolerance: 5 standard deviations of a fraction p over n rays.
double Tolerance(double p, int n) { return 5 * std::sqrt(p * (1 - p) / n); }

TEST(PassThroughTest, ShadowRaysPassMaskedSurfacesWithTheirPassProbability) {
  const auto scene = Build();
  ASSERT_NE(scene, nullptr);
  const int n = 40000;
  // One plane (opacity 0.25), both planes (x 0.5), and all three (the null one passes always).
  EXPECT_NEAR(PassFraction(*scene, 0, 0, -1, 1.5f, n), 0.75, Tolerance(0.75, n));
  EXPECT_NEAR(PassFraction(*scene, 0, 0, -1, 2.5f, n), 0.375, Tolerance(0.375, n));
  EXPECT_NEAR(PassFraction(*scene, 0, 0, -1, 5.0f, n), 0.375, Tolerance(0.375, n));
  // Through the sphere, in and out: two independent crossings of opacity 0.5; ending inside it,
  // one.
  EXPECT_NEAR(PassFraction(*scene, 5, 0, -3, 6.0f, n), 0.25, Tolerance(0.25, n));
  EXPECT_NEAR(PassFraction(*scene, 5, 0, -3, 3.0f, n), 0.5, Tolerance(0.5, n));
}

TEST(PassThroughTest, TexturedOpacityIsReadWhereIntersectReadsIt) {
  const auto scene = Build();
  ASSERT_NE(scene, nullptr);
  Rng rng(3, 4);
  int opaque = 0, checked = 0;
  for (int i = 0; i < 4000; ++i) {
    const Vec3 o(-5 + 1.9f * (rng.Next() - 0.5f), 1.9f * (rng.Next() - 0.5f), -1);
    SurfaceHit hit;
    ASSERT_TRUE(scene->Intersect(Ray{o, Vec3(0, 0, 1), 2}, &hit));
    // The checkerboard's cell at Intersect's (u, v) (to_uv scales by 4); skip points within a
    // hair of a cell edge, where float rounding may fall either way.
    const float u = 4 * hit.u, v = 4 * hit.v;
    const float fu = u - std::floor(u), fv = v - std::floor(v);
    if (std::abs(fu - 0.5f) < 1e-3f || std::abs(fv - 0.5f) < 1e-3f || fu < 1e-3f || fv < 1e-3f)
      continue;
    // Opaque (color0) where exactly one fractional part is above 0.5: a checkerboard read as one
    // number picks its colours the other way round from its colour lookup, as Mitsuba's eval_1.
    const bool expect_opaque = (fu > 0.5f) != (fv > 0.5f);
    EXPECT_EQ(scene->Occluded(Ray{o, Vec3(0, 0, 1), 2}), expect_opaque)
        << "at (" << o.x << ", " << o.y << "), uv (" << hit.u << ", " << hit.v << ")";
    opaque += expect_opaque;
    ++checked;
  }
  // Both kinds of cell were tested.
  EXPECT_GT(opaque, checked / 4);
  EXPECT_LT(opaque, 3 * checked / 4);
}

// A thin pane of glass (thindielectric, relative index 1.5, tilted 60 degrees about x) passes
// shadow rays with its transmittance 1 - 2F / (1 + F) (F: the Fresnel equations, written out
// here) at the angle they meet it, from either side; a ray towards a delta light does not pass
// (Mitsuba's shadow rays stop at it, and no path reaches a delta light through it).
TEST(PassThroughTest, ThinPanePassesShadowRaysWithItsTransmittance) {
  const std::string xml = R"(<scene version="3.0.0">
  <sensor type="perspective"/>
  <bsdf type="thindielectric" id="pane"><float name="int_ior" value="1.5"/>
    <float name="ext_ior" value="1"/></bsdf>
  <shape type="rectangle"><transform name="to_world"><scale value="10"/>
    <rotate x="1" angle="60"/></transform><ref id="pane"/></shape>
</scene>)";
  absl::StatusOr<SceneDesc> desc = LoadSceneString(xml, "pane.xml", {});
  ASSERT_TRUE(desc.ok()) << desc.status();
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
  ASSERT_TRUE(scene.ok()) << scene.status();
  const auto transmittance = [](double mu) {
    const double eta = 1.5, ct = std::sqrt(1 - (1 - mu * mu) / (eta * eta));
    const double rs = (mu - eta * ct) / (mu + eta * ct), rp = (eta * mu - ct) / (eta * mu + ct);
    const double f = 0.5 * (rs * rs + rp * rp);
    return 1 - 2 * f / (1 + f);
  };
  const Vec3 n(0, -std::sin(kPi / 3), std::cos(kPi / 3));  // the pane's normal
  const int count = 40000;
  // Directions at 0, 60 and 80 degrees from the normal, from the front and from the back.
  for (const float deg : {0.0f, 60.0f, 80.0f}) {
    for (const float side : {1.0f, -1.0f}) {
      const float th = deg * kPi / 180;
      const Vec3 d = (n * std::cos(th) + Vec3(1, 0, 0) * std::sin(th)) * -side;
      Rng rng(5, 6);
      int passed = 0, passed_delta = 0;
      for (int i = 0; i < count; ++i) {
        // A point on the pane (spanned by x and its tilted y axis), 2 units before it.
        const Vec3 on = Vec3(rng.Next() - 0.5f, 0, 0) +
                        Vec3(0, std::cos(kPi / 3), std::sin(kPi / 3)) * (rng.Next() - 0.5f);
        const Vec3 o = on - d * 2;
        passed += !(*scene)->Occluded(Ray{o, d, 4});
        passed_delta += !(*scene)->Occluded(Ray{o, d, 4}, true);
      }
      const double t = transmittance(std::cos(th));
      EXPECT_NEAR(double(passed) / count, t, Tolerance(t, count))
          << deg << " degrees, side " << side;
      EXPECT_EQ(passed_delta, 0) << deg << " degrees, side " << side;
    }
  }
}

}  // namespace
}  // namespace irfarm
