// Lamps that are triangle meshes (a ceiling disk by a wall, an upright tube by another), whose
// triangles the light tree picks (render/light_tree.h), against Mitsuba 3 on
// tests/data/scenes/mesh-lamps (reference: Mitsuba 3.9.1 at 16384 spp, make_reference.py there).
// irfarm's `path` and `irrcache` at 256 spp must be within Mitsuba's own error at 256 spp against
// that reference (the largest of 8 seeds: reference.json). Variants that light the room
// differently, by as much as a lost or doubled share of a lamp's triangles would, must fail it.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "render_test_util.h"

namespace irfarm {
namespace {

// reference.json: the largest of mitsuba_full_256spp_relmse_vs_ref (8 seeds).
constexpr double kMitsuba256SppMax = 9.58e-3;

LoadedScene Variant(const std::string& from, const std::string& to) {
  std::ifstream f(TestScenePath("mesh-lamps"));
  std::stringstream ss;
  ss << f.rdbuf();
  std::string xml = ss.str();
  const size_t at = xml.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) xml.replace(at, from.size(), to);
  return BuildLoaded(LoadSceneString(xml, TestScenePath("mesh-lamps"), {}));
}

Image Reference() {
  absl::StatusOr<Image> ref =
      ReadExr(std::string(IRFARM_TEST_DATA) + "/scenes/mesh-lamps/reference.exr");
  EXPECT_TRUE(ref.ok()) << ref.status();
  return ref.ok() ? *ref : Image();
}

TEST(MeshLampsTest, PathAndIrrcacheMatchMitsubaWithinItsNoise) {
  const LoadedScene scene = BuildLoaded(LoadSceneFile(TestScenePath("mesh-lamps"), {}));
  const Image ref = Reference();
  const double path = CompareImages(RenderWith(scene, "path", 256, 1).image, ref).relmse;
  const double irrcache = CompareImages(RenderWith(scene, "irrcache", 256, 1).image, ref).relmse;
  std::printf("MEASURED path %.3g, irrcache %.3g (256 spp); Mitsuba 256 spp at most %.3g\n", path,
              irrcache, kMitsuba256SppMax);
  EXPECT_LT(path, kMitsuba256SppMax);
  EXPECT_LT(irrcache, kMitsuba256SppMax);
}

TEST(MeshLampsTest, ALampLitWronglyIsFarFromMitsuba) {
  const Image ref = Reference();
  struct Case {
    const char* what;
    LoadedScene scene;
  } cases[] = {
      {"tube at 0.75 of its radiance", Variant(R"(value="30,32,36")", R"(value="22.5,24,27")")},
      {"disk at half its radiance", Variant(R"(value="12,11,9.5")", R"(value="6,5.5,4.75")")},
  };
  for (const Case& c : cases) {
    const double e = CompareImages(RenderWith(c.scene, "path", 256, 1).image, ref).relmse;
    std::printf("MEASURED %s: %.3g\n", c.what, e);
    EXPECT_GT(e, kMitsuba256SppMax) << c.what;
  }
}

}  // namespace
}  // namespace irfarm
