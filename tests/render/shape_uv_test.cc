// Built-in shapes' surface coordinates at a hit, against mitsuba 3.9.1's own (scalar_rgb,
// scene.ray_intersect on the same shape and ray, from Python): the (u, v) that textures read and
// the tangent dp_du that normal maps and anisotropic BSDFs turn with.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {
namespace {

std::unique_ptr<Scene> Build(const std::string& shapes) {
  const absl::StatusOr<SceneDesc> desc = LoadSceneString(
      "<scene version=\"3.0.0\"><sensor type=\"perspective\"/>" + shapes + "</scene>", "uv.xml",
      {});
  EXPECT_TRUE(desc.ok()) << desc.status();
  if (!desc.ok()) return nullptr;
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
  EXPECT_TRUE(scene.ok()) << scene.status();
  return scene.ok() ? std::move(*scene) : nullptr;
}

struct Expected {
  Vec3 origin, dir;
  float u, v;
  Vec3 dpdu;
};

void ExpectHits(const Scene& scene, const std::vector<Expected>& cases) {
  for (const Expected& e : cases) {
    SurfaceHit hit;
    ASSERT_TRUE(scene.Intersect(Ray{e.origin, e.dir, 100}, &hit));
    const std::string at = "ray from (" + std::to_string(e.origin.x) + ", " +
                           std::to_string(e.origin.y) + ", " + std::to_string(e.origin.z) + ")";
    EXPECT_NEAR(hit.u, e.u, 1e-4f) << at;
    EXPECT_NEAR(hit.v, e.v, 1e-4f) << at;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(hit.dpdu[c], e.dpdu[c], 1e-3f) << at << " dpdu " << c;
  }
}

// One hit on each face: Mitsuba's cube lays (u, v) out face by face in its own way (cube.cpp's
// texcoords); a box textured in Mitsuba showed its texture turned or mirrored on every face here.
TEST(ShapeUvTest, CubeFacesAreLaidOutAsMitsubas) {
  const auto scene = Build("<shape type=\"cube\"/>");
  ASSERT_NE(scene, nullptr);
  ExpectHits(*scene, {
                         {{0.5f, -0.5f, 5}, {0, 0, -1}, 0.25f, 0.75f, {0, 2, 0}},
                         {{0.3f, 0.2f, -5}, {0, 0, 1}, 0.4f, 0.65f, {0, -2, 0}},
                         {{5, 0.5f, -0.5f}, {-1, 0, 0}, 0.75f, 0.75f, {0, 2, 0}},
                         {{-5, 0.3f, 0.6f}, {1, 0, 0}, 0.65f, 0.8f, {0, 2, 0}},
                         {{0.2f, 5, 0.7f}, {0, -1, 0}, 0.4f, 0.15f, {-2, 0, 0}},
                         {{-0.4f, -5, 0.1f}, {0, 1, 0}, 0.55f, 0.3f, {0, 0, 2}},
                     });
}

// A sphere's (u, v) come from its own coordinates, so they turn with its to_world (they were
// taken from world directions: a rotated globe showed its texture unrotated), and a to_world
// that mirrors turns its normals inward, as Mitsuba's sphere does (sphere.cpp flips them when
// the transform's determinant is negative). Rays from (0.3, 0.2, 5) straight down.
TEST(ShapeUvTest, SpheresTurnTheirCoordinatesWithToWorld) {
  const Vec3 o(0.3f, 0.2f, 5), down(0, 0, -1);
  const auto plain = Build("<shape type=\"sphere\"/>");
  ASSERT_NE(plain, nullptr);
  ExpectHits(*plain, {{o, down, 0.09358355f, 0.1174127f, {-1.256637f, 1.884956f, 0}}});
  const auto turned = Build(
      "<shape type=\"sphere\"><transform name=\"to_world\"><rotate x=\"1\" angle=\"90\"/>"
      "</transform></shape>");
  ASSERT_NE(turned, nullptr);
  ExpectHits(*turned, {{o, down, 0.2004735f, 0.5640942f, {-5.860564f, 0, 1.884956f}}});
  const std::string mirror =
      "<transform name=\"to_world\"><scale x=\"-1.5\" y=\"1.5\" z=\"1.5\"/>"
      "<rotate x=\"1\" angle=\"30\"/><translate x=\"0.2\"/></transform>";
  const auto mirrored = Build("<shape type=\"sphere\">" + mirror + "</shape>");
  ASSERT_NE(mirrored, nullptr);
  ExpectHits(*mirrored, {{o, down, 0.2673285f, 0.2102454f, {5.748014f, -0.5441398f, -0.3141593f}}});
  SurfaceHit hit;
  ASSERT_TRUE(mirrored->Intersect(Ray{o, down, 100}, &hit));
  EXPECT_NEAR(hit.ng.z, -0.9888266f, 1e-5f);  // Mitsuba's n: inward
  EXPECT_NEAR(hit.ns.z, -0.9888266f, 1e-5f);

  // Through an instance: the same coordinates as the sphere's own to_world gives; a mirroring
  // instance keeps the sphere's outside outside (Mitsuba moves an instance's normals with its
  // normal transform).
  const auto instanced = Build(
      "<shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\"/></shape>"
      "<shape type=\"instance\"><ref id=\"g\"/>" +
      mirror + "</shape>");
  ASSERT_NE(instanced, nullptr);
  ExpectHits(*instanced,
             {{o, down, 0.2673285f, 0.2102454f, {5.748014f, -0.5441398f, -0.3141593f}}});
  ASSERT_TRUE(instanced->Intersect(Ray{o, down, 100}, &hit));
  EXPECT_NEAR(hit.ng.z, 0.9888266f, 1e-5f);
}

}  // namespace
}  // namespace irfarm
