// --target-error's stall rule (render/cache_refinement.h), on the figures its rounds measured.
#include "render/cache_refinement.h"

#include <gtest/gtest.h>

namespace irfarm {
namespace {

TEST(CacheRefinementTest, StallsWhenARoundRemovesLittleOfNeitherPart) {
  // A round that lowered a and took a tenth off: a leak neither part explains.
  EXPECT_TRUE(RefinementStalled({1.0e-2, 2e-3}, {0.9e-2, 1.5e-3}, false, 2e-3));
  // A rays-only round whose noise part did not fall (the rays do not reach the light that makes
  // it: veach-ajar's door gap) stalls too.
  EXPECT_TRUE(RefinementStalled({2.3e-2, 2.0e-2}, {2.0e-2, 1.8e-2}, true, 2e-3));
  // A round that took more than a third off goes on.
  EXPECT_FALSE(RefinementStalled({1.0e-2, 5e-3}, {0.6e-2, 2e-3}, false, 2e-3));
}

TEST(CacheRefinementTest, ARaysOnlyRoundThatLeftInterpolationErrorDoesNotStall) {
  // living-room at E = 2e-2 (seed 7): a = 0.4 at 128 rays, 7.18e-2 of which 7.02e-2 noise; at 4x
  // the rays 6.72e-2, noise 1.79e-2. Lowering a (the next round) brought it to 2.2e-2.
  EXPECT_FALSE(RefinementStalled({7.18e-2, 7.02e-2}, {6.72e-2, 1.79e-2}, true, 1e-2));
  // The same figures after a round that lowered a: stalled.
  EXPECT_TRUE(RefinementStalled({7.18e-2, 7.02e-2}, {6.72e-2, 1.79e-2}, false, 1e-2));
  // The noise part lost less than a third to the rays (they do not reach what makes it): stalled.
  EXPECT_TRUE(RefinementStalled({7.0e-2, 6.8e-2}, {6.0e-2, 5.0e-2}, true, 1e-2));
  // bench/make_room.py 401 --lamps bulb at E = 4e-3 (seed 7): a = 0.36, 128 -> 427 rays, the
  // noise 6.8e-3 -> 4.3e-3 and 2.8e-3 of interpolation left, the share 2.55e-3. Lowering a was not
  // tried: not stalled (it stopped here at 2.5 E before).
  EXPECT_FALSE(RefinementStalled({6.80e-3, 6.80e-3}, {7.08e-3, 4.32e-3}, true, 2.55e-3));
  // Within twice the cache's share, stopping leaves the image within about 1.5 E: stalled.
  EXPECT_TRUE(RefinementStalled({7.18e-2, 7.02e-2}, {6.72e-2, 1.79e-2}, true, 4e-2));
}

}  // namespace
}  // namespace irfarm
