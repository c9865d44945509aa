// Mitsuba 3's thinlens sensor against Mitsuba itself, on tests/data/scenes/thinlens (objects out
// of focus; reference: Mitsuba 3.9.1 at 16384 spp, make_reference.py beside the scene). irfarm's
// `path` at 256 spp must be within Mitsuba's own error at 256 spp against that reference (the
// largest of 8 seeds: reference.json), and the same scene through a pinhole must be far from it,
// so the test sees a missing lens.
#include <gtest/gtest.h>

#include <string>

#include "render_test_util.h"

namespace irfarm {
namespace {

constexpr double kMitsuba256SppMax = 3.75e-4;  // reference.json: mitsuba_256spp_vs_ref_max

TEST(ThinLensTest, PathMatchesMitsubaWithinItsNoiseAndAPinholeDoesNot) {
  const LoadedScene scene = BuildLoaded(LoadSceneFile(TestScenePath("thinlens"), {}));
  ASSERT_GT(scene.desc.camera.aperture_radius, 0);
  const absl::StatusOr<Image> ref =
      ReadExr(std::string(IRFARM_TEST_DATA) + "/scenes/thinlens/reference.exr");
  ASSERT_TRUE(ref.ok()) << ref.status();
  const RenderOutput out = RenderWith(scene, "path", 256, 1);
  const double err = CompareImages(out.image, *ref).relmse;
  RecordProperty("relmse", std::to_string(err));
  // Measured: 2.7e-4.
  EXPECT_LT(err, kMitsuba256SppMax);

  SceneDesc pinhole = scene.desc;
  pinhole.camera.aperture_radius = 0;
  const LoadedScene sharp = BuildLoaded(pinhole);
  const double sharp_err = CompareImages(RenderWith(sharp, "path", 256, 1).image, *ref).relmse;
  // Measured: 1.2e-2.
  EXPECT_GT(sharp_err, 10 * kMitsuba256SppMax);
}

}  // namespace
}  // namespace irfarm
