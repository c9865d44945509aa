// Tests of render/camera.h's Project, the inverse of Direction: a point on the ray through image
// point (x, y) projects back to (x, y), for a look-at camera, one with a scaled and sheared
// to_world, and a cropped film; points behind the camera are refused.
#include "render/camera.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace irfarm {
namespace {

// Projects points along the rays through random image points at random distances; 1e-3 px is
// float rounding of a few dot products at distances up to 100 units.
void ExpectRoundTrip(const Camera& cam, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> ux(0, float(cam.width())), uy(0, float(cam.height()));
  std::uniform_real_distribution<float> ut(0.1f, 100.0f);
  for (int i = 0; i < 1000; ++i) {
    const float x = ux(rng), y = uy(rng), t = ut(rng);
    const Vec3 p = cam.origin() + cam.Direction(x, y) * t;
    float px = -1, py = -1;
    ASSERT_TRUE(cam.Project(p, &px, &py)) << x << " " << y << " " << t;
    EXPECT_NEAR(px, x, 1e-3f * std::max(1.0f, t / 10));
    EXPECT_NEAR(py, y, 1e-3f * std::max(1.0f, t / 10));
    EXPECT_FALSE(cam.Project(cam.origin() - cam.Direction(x, y) * t, &px, &py));
  }
}

TEST(CameraTest, ProjectInvertsDirection) {
  CameraDesc d;
  d.to_world = Mat4::LookAt(Vec3(1, 2, 5), Vec3(0, 0.5f, 0), Vec3(0, 1, 0));
  d.fov_x_deg = 39.3f;
  d.width = 160;
  d.height = 96;
  ExpectRoundTrip(Camera(d), 1);
}

TEST(CameraTest, ProjectInvertsDirectionWithShearAndCrop) {
  CameraDesc d;
  Mat4 m = Mat4::LookAt(Vec3(-3, 1, 2), Vec3(0, 0, 0), Vec3(0, 0, 1)) * Mat4::Scale(1, 2, 0.5);
  m.m[0][1] += 0.3;  // shear: the camera basis is not orthogonal
  d.to_world = m;
  d.fov_x_deg = 70;
  d.film_width = 400;
  d.film_height = 300;
  d.crop_x = 120;
  d.crop_y = 40;
  d.width = 100;
  d.height = 80;
  ExpectRoundTrip(Camera(d), 2);
}

}  // namespace
}  // namespace irfarm
