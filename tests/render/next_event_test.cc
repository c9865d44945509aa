// Next-event estimation of every light at each path vertex (PathSettings::all_lights, the
// default) against one light picked by its unoccluded contribution, on room-c (three lamps, a
// sun through a window, a sky: the sun's weight is large everywhere but it reaches few points),
// quarter size, path at 64 spp, two seeds per mode:
//  - both estimators are unbiased: each mode's image mean, per channel, within 4 standard
//    errors of the Mitsuba reference's (standard error from the two seeds' per-pixel
//    differences, plus the reference's own 1e-3 share as in GoldenImageTest);
//  - every light is the less noisy: half the relMSE between the two seeds (each render's
//    noise) at most half that of picking one (measured at full size, 16 spp: 5.8e-2 -> 6.1e-3).
#include <gtest/gtest.h>

#include <cmath>

#include "render/renderer.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

RenderOutput RenderPath(const LoadedScene& s, bool all_lights, uint64_t seed) {
  RenderSettings settings = *SettingsForScene(s.desc, "path");
  settings.spp = 64;
  settings.seed = seed;
  settings.irrcache.path.all_lights = all_lights;
  settings.firefly_filter = false;  // MeanStandardError takes the pixels as independent
  return Render(*s.scene, settings);
}

TEST(NextEventTest, EveryLightIsUnbiasedAndLessNoisyThanOnePicked) {
  const LoadedScene s = LoadQuarter("room-c");
  const Image ref = QuarterReference("room-c");
  double noise[2] = {0, 0};
  for (const bool all : {false, true}) {
    const RenderOutput a = RenderPath(s, all, 1), b = RenderPath(s, all, 2);
    ASSERT_EQ(a.image.width, ref.width);
    ASSERT_EQ(a.image.height, ref.height);
    EXPECT_EQ(a.stats.nonfinite_pixels, 0);
    noise[all] = CompareImages(a.image, b.image).relmse / 2;
    const ImageError m = CompareImages(a.image, ref);
    const Vec3 se = MeanStandardError(a.image, b.image, m.mean_ref);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(m.mean_test[c], m.mean_ref[c], 4 * se[c])
          << (all ? "every light" : "one light") << ", channel " << c;
  }
  RecordProperty("noise_one_light", std::to_string(noise[0]));
  RecordProperty("noise_every_light", std::to_string(noise[1]));
  EXPECT_LT(noise[1], noise[0] / 2) << "one light " << noise[0] << ", every light " << noise[1];
}

}  // namespace
}  // namespace irfarm
