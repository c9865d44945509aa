// Lamps that are not rectangles (a spot light, a point light, a small sphere lamp) over real
// interiors' finishes (a rough plastic floor, a rough aluminium box), against Mitsuba 3 on
// tests/data/scenes/bulb-lamps (reference: Mitsuba 3.9.1 at 16384 spp, make_reference.py there),
// the kind of room bench/make_room.py makes with --lamps bulb --finish glossy. irfarm's `path` and
// `irrcache` at 256 spp must be within Mitsuba's own error at 256 spp against that reference (the
// largest of 8 seeds: reference.json). Variants that get a lamp's intensity or the spot's cone
// wrong must fail it.
#include <gtest/gtest.h>

#include "render_test_util.h"

namespace irfarm {
namespace {

constexpr char kScene[] = "bulb-lamps";

TEST(BulbLampsTest, PathAndIrrcacheMatchMitsubaWithinItsNoise) {
  ExpectWithinMitsuba256Spp(kScene, BuildLoaded(LoadSceneFile(TestScenePath(kScene), {})));
}

TEST(BulbLampsTest, ALampLitWronglyIsFarFromMitsuba) {
  ExpectFarFromMitsuba256Spp(kScene, "spot at 0.8 of its intensity",
                             LoadVariant(kScene, R"(value="25,23,19")", R"(value="20,18.4,15.2")"));
  ExpectFarFromMitsuba256Spp(kScene, "spot's soft edge 5 degrees narrower",
                             LoadVariant(kScene, R"(name="cutoff_angle" value="35")",
                                         R"(name="cutoff_angle" value="30")"));
  ExpectFarFromMitsuba256Spp(kScene, "point light at half its intensity",
                             LoadVariant(kScene, R"(value="3,3.2,3.6")", R"(value="1.5,1.6,1.8")"));
  ExpectFarFromMitsuba256Spp(kScene, "sphere lamp at 0.75 of its radiance",
                             LoadVariant(kScene, R"(value="120,108,90")", R"(value="90,81,67.5")"));
}

}  // namespace
}  // namespace irfarm
