// Lamps that are triangle meshes (a ceiling disk by a wall, an upright tube by another), whose
// triangles the light tree picks (render/light_tree.h), against Mitsuba 3 on
// tests/data/scenes/mesh-lamps (reference: Mitsuba 3.9.1 at 16384 spp, make_reference.py there).
// irfarm's `path` and `irrcache` at 256 spp must be within Mitsuba's own error at 256 spp against
// that reference (the largest of 8 seeds: reference.json). Variants that light the room
// differently, by as much as a lost or doubled share of a lamp's triangles would, must fail it.
#include <gtest/gtest.h>

#include "render_test_util.h"

namespace irfarm {
namespace {

constexpr char kScene[] = "mesh-lamps";

TEST(MeshLampsTest, PathAndIrrcacheMatchMitsubaWithinItsNoise) {
  ExpectWithinMitsuba256Spp(kScene, BuildLoaded(LoadSceneFile(TestScenePath(kScene), {})));
}

TEST(MeshLampsTest, ALampLitWronglyIsFarFromMitsuba) {
  ExpectFarFromMitsuba256Spp(kScene, "tube at 0.75 of its radiance",
                             LoadVariant(kScene, R"(value="30,32,36")", R"(value="22.5,24,27")"));
  ExpectFarFromMitsuba256Spp(kScene, "disk at half its radiance",
                             LoadVariant(kScene, R"(value="12,11,9.5")", R"(value="6,5.5,4.75")"));
}

}  // namespace
}  // namespace irfarm
