// A scene far from the origin renders like the same scene at the origin (issue 10, part 6): the
// cornell box with the camera, every shape and the light translated by (1e6, 2e5, -5e5), as in a
// georeferenced building model (float32 alone has 0.06-unit steps at 1e6; the box is 2 units),
// and translated and rotated, both rendered at 1/4 resolution with both integrators and held to
// the same bounds as the untranslated box in golden_image_test: path within 1.5x its noise
// (relMSE of two seeds / 2) plus the reference's own error, irrcache within 1.5x the path
// tracer's expected error at 256 spp plus the reference's error.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "render_test_util.h"

namespace irfarm {
namespace {

// The cornell-box scene text with `transform` (XML transform steps) appended to every to_world,
// and given as the to_world of the OBJ shape that has none.
std::string MovedCornellBox(const std::string& transform) {
  std::ifstream f(TestScenePath("cornell-box"));
  std::stringstream ss;
  ss << f.rdbuf();
  std::string s = ss.str();
  for (size_t at = 0; (at = s.find("</transform>", at)) != std::string::npos;) {
    s.insert(at, transform);
    at += transform.size() + 12;
  }
  const std::string obj = "<string name=\"filename\" value=\"meshes/large-box.obj\"/>";
  const size_t at = s.find(obj);
  EXPECT_NE(at, std::string::npos);
  s.insert(at + obj.size(), "<transform name=\"to_world\">" + transform + "</transform>");
  return s;
}

LoadedScene LoadMoved(const std::string& transform) {
  return BuildLoaded(LoadSceneString(MovedCornellBox(transform), TestScenePath("cornell-box"),
                                     LoadOptions{{{"resx", "64"}, {"resy", "64"}}}));
}

constexpr int kPathSpp = 64;

class FarFromOriginTest : public ::testing::TestWithParam<const char*> {
 protected:
  static void SetUpTestSuite() {
    const LoadedScene base = LoadQuarter("cornell-box");
    const Image a = RenderWith(base, "path", kPathSpp, 1).image;
    const Image b = RenderWith(base, "path", kPathSpp, 2).image;
    noise_ = CompareImages(a, b).relmse / 2;
  }
  static double noise_;
};
double FarFromOriginTest::noise_ = 0;

TEST_P(FarFromOriginTest, RendersLikeTheSceneAtTheOrigin) {
  const LoadedScene s = LoadMoved(GetParam());
  // Re-centred on load (near the box's centre, which the move takes to (1e6, 2e5, -5e5)); the
  // box at the origin is not.
  EXPECT_NEAR(s.desc.world_origin[0], 1e6, 2);
  EXPECT_NEAR(s.desc.world_origin[1], 2e5, 2);
  EXPECT_NEAR(s.desc.world_origin[2], -5e5, 2);
  EXPECT_EQ(LoadQuarter("cornell-box").desc.world_origin, (std::array<double, 3>{0, 0, 0}));
  const Image ref = QuarterReference("cornell-box");
  const double ref_err = ReferenceError("cornell-box");
  const RenderOutput path = RenderWith(s, "path", kPathSpp, 1);
  EXPECT_EQ(path.stats.nonfinite_pixels, 0);
  const double path_err = CompareImages(path.image, ref).relmse;
  const RenderOutput irr = RenderWith(s, "irrcache", 0, 3);
  EXPECT_EQ(irr.stats.nonfinite_pixels, 0);
  const double irr_err = CompareImages(irr.image, ref).relmse;
  const double path256 = noise_ * kPathSpp / 256.0;
  std::printf("MEASURED %s: path relMSE %.5f (bound %.5f), irrcache %.5f (bound %.5f)\n",
              GetParam(), path_err, 1.5 * noise_ + ref_err, irr_err, 1.5 * path256 + ref_err);
  EXPECT_LT(path_err, 1.5 * noise_ + ref_err);
  EXPECT_LT(irr_err, 1.5 * path256 + ref_err);
}

INSTANTIATE_TEST_SUITE_P(Moves, FarFromOriginTest,
                         ::testing::Values("<translate x=\"1e6\" y=\"2e5\" z=\"-5e5\"/>",
                                           "<rotate x=\"1\" y=\"2\" z=\"3\" angle=\"37\"/>"
                                           "<translate x=\"1e6\" y=\"2e5\" z=\"-5e5\"/>"),
                         [](const auto& info) {
                           return info.index == 0 ? "Translated" : "RotatedAndTranslated";
                         });

}  // namespace
}  // namespace irfarm

namespace irfarm {
namespace {

// Points given directly (a sphere's centre, a point light's position) are taken in double too:
// at x = 1e6 + 0.3 float32 rounds to steps of 0.0625 (1e6 + 0.3125); re-centred they keep 0.3.
TEST(FarFromOriginLoaderTest, PointsGivenDirectlyKeepTheirPrecision) {
  const std::string xml = R"(<scene version="3.0.0">
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="1000000, 0, 5" target="1000000, 0, 0" up="0, 1, 0"/></transform>
  </sensor>
  <shape type="sphere"><point name="center" x="1000000.3" y="0" z="0"/><float name="radius" value="0.5"/></shape>
  <shape type="sphere"><point name="center" x="999999.7" y="0" z="0"/><float name="radius" value="0.5"/></shape>
  <emitter type="point"><point name="position" x="1000000.55" y="1.125" z="0"/></emitter>
</scene>)";
  absl::StatusOr<SceneDesc> desc = LoadSceneString(xml, "far.xml", {});
  ASSERT_TRUE(desc.ok()) << desc.status();
  const double ox = desc->world_origin[0];
  EXPECT_NEAR(ox, 1e6, 0.1);
  ASSERT_EQ(desc->shapes.size(), 2u);
  EXPECT_NEAR(ox + double(desc->shapes[0].center.x), 1000000.3, 1e-5);
  EXPECT_NEAR(ox + double(desc->shapes[1].center.x), 999999.7, 1e-5);
  ASSERT_EQ(desc->emitters.size(), 1u);
  EXPECT_NEAR(ox + double(desc->emitters[0].position.x), 1000000.55, 1e-5);
  EXPECT_NEAR(desc->emitters[0].position.y, 1.125, 1e-6);
  // The camera looks at the spheres' centre from 5 units away, wherever the origin went.
  EXPECT_NEAR(ox + desc->camera.to_world.m[0][3], 1e6, 1e-5);
  EXPECT_NEAR(desc->camera.to_world.m[2][3], 5, 1e-9);
}

}  // namespace
}  // namespace irfarm
