// Properties of the renderer that do not need a reference image: `path` is deterministic for a
// seed whatever the thread count and tiling; the stress-scale scenes render like cornell-box;
// max_depth counts vertices as Mitsuba does; the record map marks computed records.
#include <gtest/gtest.h>
#include <algorithm>
#include <utility>

#include <fstream>

#include <filesystem>

#include <cmath>
#include <cstdio>

#include "render_test_util.h"

namespace irfarm {
namespace {

TEST(RenderPropertiesTest, PathIsDeterministicWhateverTheThreadCount) {
  const LoadedScene s = LoadQuarter("cornell-box");
  const RenderOutput one = RenderWith(s, "path", 8, 42, 1);
  const RenderOutput two = RenderWith(s, "path", 8, 42, 2);
  ASSERT_EQ(one.image.pixels.size(), two.image.pixels.size());
  for (size_t i = 0; i < one.image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(one.image.pixels[i][c], two.image.pixels[i][c]) << i;
  const RenderOutput other_seed = RenderWith(s, "path", 8, 43, 2);
  EXPECT_GT(CompareImages(one.image, other_seed.image).relmse, 0);
}

TEST(RenderPropertiesTest, RectanglesAssembleIntoTheWholeImage) {
  const LoadedScene s = LoadQuarter("cornell-box");
  RenderSettings settings = *SettingsForScene(s.desc, "path");
  settings.spp = 4;
  settings.seed = 5;
  // The firefly filter works within the rect it is given (a worker's tile): a firefly by the
  // rect's edge spreads over the part of its 5 x 5 inside it, so that pixel and its neighbours
  // may differ from the whole image's. Without it the rect's pixels are the whole image's.
  settings.firefly_filter = false;
  const RenderOutput whole = Render(*s.scene, settings);
  const PixelRect rect{10, 20, 37, 41};
  const RenderOutput part = RenderRect(*s.scene, settings, nullptr, rect);
  ASSERT_EQ(part.image.width, rect.width());
  for (int y = rect.y0; y < rect.y1; ++y)
    for (int x = rect.x0; x < rect.x1; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(part.image.at(x - rect.x0, y - rect.y0)[c], whole.image.at(x, y)[c]);
}

// The stress-scale scenes are cornell-box times 1e-3 and 1e4. With the same seed the path tracer
// makes the same random decisions, so the images must agree far below the noise level; the
// irradiance cache must reach the same error as on cornell-box (issue: within 1.5x).
TEST(RenderPropertiesTest, ScaleDoesNotChangeTheImage) {
  const LoadedScene base = LoadQuarter("cornell-box");
  const Image ref = QuarterReference("cornell-box");
  const RenderOutput base_path = RenderWith(base, "path", 16, 9);
  const RenderOutput base_path2 = RenderWith(base, "path", 16, 10);
  const double noise = CompareImages(base_path.image, base_path2.image).relmse / 2;
  // The same record rays at every scale: the pilot's balance times records against samples and
  // picks other rays from run to run on a loaded machine, which is not what is compared here.
  auto irrcache = [](const LoadedScene& s) {
    RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
    settings.seed = 9;
    settings.irrcache.balance_record_rays = false;
    return Render(*s.scene, settings).image;
  };
  const double base_irr = CompareImages(irrcache(base), ref).relmse;
  for (const char* name : {"stress-scale-tiny", "stress-scale-huge"}) {
    const LoadedScene s = LoadQuarter(name);
    const RenderOutput p = RenderWith(s, "path", 16, 9);
    EXPECT_LT(CompareImages(p.image, base_path.image).relmse, 0.01 * noise) << name;
    const double irr = CompareImages(irrcache(s), ref).relmse;
    EXPECT_LT(irr, 1.5 * base_irr) << name;
  }
}

TEST(RenderPropertiesTest, MaxDepthCountsVerticesLikeMitsuba) {
  for (const char* integrator : {"path", "irrcache"}) {
    absl::StatusOr<SceneDesc> desc =
        LoadSceneFile(TestScenePath("cornell-box"),
                      LoadOptions{{{"resx", "32"}, {"resy", "32"}, {"max_depth", "1"}}});
    ASSERT_TRUE(desc.ok());
    auto scene = Scene::Build(*desc);
    ASSERT_TRUE(scene.ok());
    RenderSettings settings = *SettingsForScene(*desc, integrator);
    settings.spp = 4;
    const RenderOutput emitters_only = Render(**scene, settings);
    // Only pixels that see the light are lit; most of the image is black.
    int black = 0;
    for (const Vec3& p : emitters_only.image.pixels) black += IsBlack(p);
    EXPECT_GT(black, int(emitters_only.image.pixels.size() * 9 / 10)) << integrator;
    EXPECT_LT(black, int(emitters_only.image.pixels.size())) << integrator;
    // max_depth 0: Mitsuba's path returns nothing at all, the lamp seen included.
    desc = LoadSceneFile(TestScenePath("cornell-box"),
                         LoadOptions{{{"resx", "32"}, {"resy", "32"}, {"max_depth", "0"}}});
    ASSERT_TRUE(desc.ok());
    scene = Scene::Build(*desc);
    ASSERT_TRUE(scene.ok());
    settings = *SettingsForScene(*desc, integrator);
    settings.spp = 4;
    const RenderOutput nothing = Render(**scene, settings);
    black = 0;
    for (const Vec3& p : nothing.image.pixels) black += IsBlack(p);
    EXPECT_EQ(black, int(nothing.image.pixels.size())) << integrator;
  }
}

// The sensor's near_clip and far_clip clip camera rays as Mitsuba 3's do: a black panel 0.005
// in front of the camera hides a glowing wall at 2 unless near_clip passes it, and the wall is
// not seen past far_clip. (Before, both were read and ignored.)
TEST(RenderPropertiesTest, CameraRaysSeeFromNearClipToFarClip) {
  const auto mean = [](const char* near_clip, const char* far_clip, const char* integrator) {
    const std::string xml = std::string(R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="30"/>
    <float name="near_clip" value=")") +
                            near_clip + R"("/>
    <float name="far_clip" value=")" +
                            far_clip + R"("/>
    <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, -1" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
      <rfilter type="box"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="10"/><translate z="-2"/></transform>
    <emitter type="area"><rgb name="radiance" value="1"/></emitter>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><translate z="-0.005"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
  </shape>
</scene>
)";
    const LoadedScene s = BuildLoaded(LoadSceneString(xml, "clip.xml", {}));
    RenderSettings settings = *SettingsForScene(s.desc, integrator);
    settings.spp = 2;
    const RenderOutput out = Render(*s.scene, settings);
    double sum = 0;
    for (const Vec3& p : out.image.pixels) sum += p.y;
    return sum / double(out.image.pixels.size());
  };
  for (const char* integrator : {"path", "irrcache"}) {
    EXPECT_NEAR(mean("0.01", "1e4", integrator), 1.0, 1e-4) << integrator;  // past the panel
    EXPECT_EQ(mean("0.001", "1e4", integrator), 0.0) << integrator;         // the panel
    EXPECT_EQ(mean("0.01", "1.5", integrator), 0.0) << integrator;          // the wall too far
  }
}

// A twosided surface with a mask on its back only: shadow rays that meet its back pass with the
// mask's probability (0.75 here), those that meet its front (a plain diffuse) never do, as paths
// sampling its sides do (Bsdf::PassThrough's side). Before, the front answered for both sides.
TEST(RenderPropertiesTest, ShadowRaysPassATwosidedSurfaceByTheSideTheyMeet) {
  const LoadedScene s = BuildLoaded(LoadSceneString(R"(<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/>
    <integer name="height" value="8"/></film></sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="10"/><translate z="0.5"/></transform>
    <bsdf type="twosided">
      <bsdf type="diffuse"/>
      <bsdf type="mask"><float name="opacity" value="0.25"/><bsdf type="diffuse"/></bsdf>
    </bsdf>
  </shape>
</scene>
)",
                                                    "twosided.xml", {}));
  ASSERT_TRUE(s.scene);
  constexpr int kN = 4000;
  int up = 0, down = 0;  // shadow rays through the panel from below (its back) and from above
  Rng rng(3, 4);
  for (int i = 0; i < kN; ++i) {
    const float x = 8 * rng.Next() - 4, y = 8 * rng.Next() - 4;
    up += !s.scene->Occluded(Ray{Vec3(x, y, 0), Vec3(0, 0, 1), 1.0f});
    down += !s.scene->Occluded(Ray{Vec3(x, y, 1), Vec3(0, 0, -1), 1.0f});
  }
  const double pass = double(up) / kN, sigma = std::sqrt(0.75 * 0.25 / kN);
  std::printf("MEASURED through the back %.4f (expected 0.75 +- %.4f), the front %d of %d\n", pass,
              sigma, down, kN);
  EXPECT_NEAR(pass, 0.75, 4 * sigma);
  EXPECT_EQ(down, 0);
}

// A mask over a BSDF that itself lets light straight through (here another mask) passes shadow
// rays where either does: 1 - a (1 - nested) = 1 - 0.25 (1 - 0.5) = 0.875, as often as its Sample
// takes the null lobe (Mitsuba's eval_null_transmission). It passed 1 - a = 0.75 before, while
// paths passed 0.875: light sampling and BSDF sampling disagreed under MIS.
TEST(RenderPropertiesTest, ShadowRaysPassAMaskAndWhatItMasks) {
  const LoadedScene s = BuildLoaded(LoadSceneString(R"(<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/>
    <integer name="height" value="8"/></film></sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="10"/><translate z="0.5"/></transform>
    <bsdf type="mask"><float name="opacity" value="0.25"/>
      <bsdf type="mask"><float name="opacity" value="0.5"/><bsdf type="diffuse"/></bsdf>
    </bsdf>
  </shape>
</scene>
)",
                                                    "masks.xml", {}));
  ASSERT_TRUE(s.scene);
  constexpr int kN = 4000;
  int passed = 0, null_lobe = 0;
  Rng rng(5, 6);
  SurfaceHit hit;
  ASSERT_TRUE(s.scene->Intersect(Ray{Vec3(0, 0, 0), Vec3(0, 0, 1), INFINITY}, &hit));
  const Bsdf& m = s.scene->material(hit.material);
  for (int i = 0; i < kN; ++i) {
    const float x = 8 * rng.Next() - 4, y = 8 * rng.Next() - 4;
    passed += !s.scene->Occluded(Ray{Vec3(x, y, 0), Vec3(0, 0, 1), 1.0f});
    const BsdfSample b =
        m.Sample(BsdfContext{}, Vec3(0, 0, 1), rng.Next(), rng.Next(), rng.Next(), kAllLobes);
    null_lobe += b.lobe == kNullTransmission;
  }
  const double pass = double(passed) / kN, sigma = std::sqrt(0.875 * 0.125 / kN);
  std::printf(
      "MEASURED shadow rays through %.4f, Sample's null lobe %.4f (expected 0.875 +- %.4f)\n", pass,
      double(null_lobe) / kN, sigma);
  EXPECT_NEAR(pass, 0.875, 4 * sigma);
  EXPECT_NEAR(double(null_lobe) / kN, 0.875, 4 * sigma);
}

// An area lamp on a shape with a null bsdf (Mitsuba's Blender exporter writes area lights so):
// the camera sees its emission, rays pass through it, and it lights the floor. Mitsuba 3.9.1's
// path tracer on this 16 x 16 scene (box filter, 2 x 1024 spp): image mean 0.55714 (SE 6e-5)
// for a rectangle lamp, 0.61144 (SE 1.4e-4) for a sphere, whose centre pixels are 1.4715 (its
// front's emission plus the floor seen through it). irfarm refused such scenes.
TEST(RenderPropertiesTest, NullBsdfLampsAreSeenAndPassedThrough) {
  const auto scene = [](const std::string& shape) {
    return BuildLoaded(LoadSceneString(R"(<scene version="3.0.0">
  <integrator type="path"/>
  <sensor type="perspective"><float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/>
      <rfilter type="box"/></film></sensor>
  <shape type=")" + shape + R"("><bsdf type="null"/>
    <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="5"/><translate z="-1"/>
    </transform><bsdf type="diffuse"/></shape>
</scene>
)",
                                       "null-lamp.xml", {}));
  };
  struct Case {
    const char* shape;
    double mean, se, centre;
  };
  for (const Case& c :
       {Case{"rectangle", 0.55714, 6e-5, 1.0}, Case{"sphere", 0.61144, 1.4e-4, 1.4715}}) {
    const LoadedScene s = scene(c.shape);
    ASSERT_TRUE(s.scene) << c.shape;
    const RenderOutput a = RenderWith(s, "path", 1024, 1, 0, false),
                       b = RenderWith(s, "path", 1024, 2, 0, false);
    const auto [mean, se] = MeanOfTwo(a.image, b.image);
    double centre = 0;
    for (int y = 7; y <= 8; ++y)
      for (int x = 7; x <= 8; ++x) centre += (a.image.at(x, y).x + b.image.at(x, y).x) / 8;
    std::printf(
        "MEASURED %s: mean %.5f (SE %.5f) against Mitsuba's %.5f; centre %.4f against %.4f\n",
        c.shape, mean, se, c.mean, centre, c.centre);
    EXPECT_NEAR(mean, c.mean, 5 * std::sqrt(se * se + c.se * c.se)) << c.shape;
    EXPECT_NEAR(centre, c.centre, 0.02) << c.shape;
  }
}

// A thindielectric pane with smoothed normals passes shadow rays by the cosine to its shading
// normal, as its Sample (and Mitsuba's) sees the surface: a pane whose vertex normals lean 60
// degrees from its plane's normal, crossed straight through, lets 1 - R'(cos 60) = 0.8362 of
// them pass (eta 1.5; R' = F + (1 - F)^2 F / (1 - F^2), the pane's two faces), not the 0.9231
// of its geometric cosine, which the shadow rays used while paths used the shading one.
TEST(RenderPropertiesTest, PanesPassShadowRaysByTheirShadingNormal) {
  const std::string dir = ::testing::TempDir() + "/pane_normals";
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/pane.obj") << "v -5 -5 0.5\nv 5 -5 0.5\nv 5 5 0.5\nv -5 5 0.5\n"
                                      "vn 0.8660254 0 0.5\n"
                                      "f 1//1 2//1 3//1\nf 1//1 3//1 4//1\n";
  const LoadedScene s = BuildLoaded(LoadSceneString(R"(<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/>
    <integer name="height" value="8"/></film></sensor>
  <shape type="obj"><string name="filename" value="pane.obj"/>
    <bsdf type="thindielectric"><float name="int_ior" value="1.5"/>
      <float name="ext_ior" value="1"/></bsdf></shape>
</scene>
)",
                                                    dir + "/pane.xml", {}));
  ASSERT_TRUE(s.scene);
  constexpr int kN = 4000;
  int passed = 0;
  Rng rng(7, 8);
  for (int i = 0; i < kN; ++i) {
    const float x = 6 * rng.Next() - 3, y = 6 * rng.Next() - 3;
    passed += !s.scene->Occluded(Ray{Vec3(x, y, 0), Vec3(0, 0, 1), 1.0f});
  }
  const double pass = double(passed) / kN, sigma = std::sqrt(0.8362 * 0.1638 / kN);
  std::printf("MEASURED %.4f of shadow rays pass (expected 0.8362 +- %.4f)\n", pass, sigma);
  EXPECT_NEAR(pass, 0.8362, 4 * sigma);
}

TEST(RenderPropertiesTest, RecordMapMarksComputedRecords) {
  const LoadedScene s = LoadQuarter("cornell-box");
  RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
  settings.spp = 4;
  settings.record_map = true;
  const RenderOutput out = Render(*s.scene, settings);
  int marked = 0;
  for (const Vec3& p : out.record_map.pixels) marked += p.x >= 1e3f;
  EXPECT_GT(marked, 0);
  EXPECT_LE(uint64_t(marked), out.stats.counters.records_computed);
  EXPECT_EQ(out.stats.records_in_cache, out.stats.counters.records_computed);
}

// The environment lights a diffuse surface at the path's last allowed bounce: with max_depth 2
// (Mitsuba's `direct` integrator reads so) a diffuse plane of albedo 0.5 under a constant sky
// of 1 is 0.5 everywhere (E = pi, L = 0.5 E / pi; path's next-event estimation has it, as
// Mitsuba's). irrcache, which takes the sky from its records, read no records there (they would
// hold a second bounce) and rendered the plane black; at max_depth 3 the records carry it.
TEST(RenderPropertiesTest, TheSkyLightsTheLastBounceUnderMaxDepth) {
  for (const char* depth : {"2", "3"}) {
    const LoadedScene s = BuildLoaded(LoadSceneString(std::string(R"(<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value=")") +
                                                          depth + R"("/></integrator>
  <sensor type="perspective"><float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/>
      <rfilter type="box"/></film></sensor>
  <shape type="rectangle"><transform name="to_world"><scale value="100"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
</scene>
)",
                                                      "sky.xml", {}));
    ASSERT_TRUE(s.scene);
    for (const char* integrator : {"path", "irrcache"}) {
      const RenderOutput a = RenderWith(s, integrator, 16, 1, 0, false),
                         b = RenderWith(s, integrator, 16, 2, 0, false);
      const auto [mean, se] = MeanOfTwo(a.image, b.image);
      std::printf("MEASURED max_depth %s %s: mean %.6f (SE %.6f), exact 0.5\n", depth, integrator,
                  mean, se);
      // Cosine-weighted sky samples make every sample 0.5 up to float rounding (1e-4 covers
      // single-precision sums over the image); else 5 standard errors of the two seeds.
      EXPECT_NEAR(mean, 0.5, std::max(5 * se, 1e-4)) << depth << " " << integrator;
    }
  }
}

}  // namespace
}  // namespace irfarm
