// The caustic photon map (render/caustic_map.h) against a caustic with a closed form, and the
// records' side of the split: record paths with the map leave out the light it holds, add it
// where they land, and so count every light once (mirror caustics of an area light; a spot's
// highlight on a rough mirror, a glossy caustic of a delta light).
//
// The scene: a perfect mirror (conductor, material none, reflectance 1) filling the plane z = 0,
// a 0.5 x 0.5 lamp at z = 1 facing down at it, and a diffuse ceiling at z = 3 facing down. The
// ceiling gets no light from the lamp directly; what the mirror sends it is the light of the
// lamp's mirror image (z = -1, facing up): E = L * (projected solid angle of the image), by
// Lambert's formula. The lamp's own back blocks the reflected light over the ceiling near the
// axis only (|x|, |y| below about 1); the checks are at 1.5 to 3.
#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <cmath>
#include <memory>
#include <string>

#include "render/caustic_map.h"
#include "render/environment_sun.h"
#include "render/image.h"
#include "render/path_tracer.h"
#include "render/sampling.h"
#include "render/scene.h"
#include "render/scene_loader.h"
#include "render/solid_angle.h"

namespace irfarm {
namespace {

constexpr float kRadiance = 10;

constexpr char kScene[] = R"(<scene version="3.0.0">
  <sensor type="perspective"/>
  <bsdf type="diffuse" id="white"/>
  <bsdf type="conductor" id="mirror"><string name="material" value="none"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><scale x="10" y="10"/></transform>
    <ref id="mirror"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale x="0.25" y="0.25"/><rotate x="1" angle="180"/><translate z="1"/></transform>
    <ref id="white"/>
    <emitter type="area"><rgb name="radiance" value="10, 10, 10"/></emitter>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale x="10" y="10"/><rotate x="1" angle="180"/><translate z="3"/></transform>
    <ref id="white"/>
  </shape>
</scene>)";

// `name`: the scene file's path, which relative file names (an envmap) are read beside.
std::unique_ptr<Scene> Build(const std::string& xml = kScene,
                             const std::string& name = "caustic.xml") {
  absl::StatusOr<SceneDesc> desc = LoadSceneString(xml, name, {});
  EXPECT_TRUE(desc.ok()) << desc.status();
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
  EXPECT_TRUE(scene.ok()) << scene.status();
  return scene.ok() ? std::move(*scene) : nullptr;
}

// Irradiance at ceiling point (x, y, 3), facing down, from the lamp's mirror image.
double Analytic(float x, float y) {
  const Vec3 image[4] = {Vec3(-0.25f, -0.25f, -1), Vec3(0.25f, -0.25f, -1), Vec3(0.25f, 0.25f, -1),
                         Vec3(-0.25f, 0.25f, -1)};
  return kRadiance * PolygonProjectedSolidAngle(Vec3(x, y, 3), Vec3(0, 0, -1), image, 4);
}

// The test scene's map: 200k photons stored, seed 7 (nullptr when the build failed).
std::unique_ptr<CausticMap> BuildMap(const Scene& scene, CausticMapStats* stats) {
  tbb::task_arena arena(2);
  CausticMapSettings settings;
  settings.target_photons = 200000;
  settings.seed = 7;
  return CausticMap::Build(scene, settings, arena, stats);
}

TEST(CausticMapTest, MirrorCausticMatchesItsClosedForm) {
  const std::unique_ptr<Scene> scene = Build();
  ASSERT_NE(scene, nullptr);
  ASSERT_TRUE(CausticMap::SceneHasCaustics(*scene));
  CausticMapStats stats;
  const std::unique_ptr<CausticMap> map = BuildMap(*scene, &stats);
  ASSERT_NE(map, nullptr);
  EXPECT_GE(stats.stored, 200000);
  // Over [1.5, 3]^2 (a quadrant of the ring the image lights evenly), 16 x 16 points. Each
  // estimate averages 64 photons (relative standard deviation 1/8); neighbouring estimates share
  // photons, and the region holds about area / (pi r^2) = 2.25 / (pi 0.14^2) = 36 independent
  // ones (r: the 64th photon's distance at the map's density, about 1000 photons per unit area
  // there), so the mean's standard error is about 2%: 6% is three of them. A wrong flux (pi, the
  // emitted count) or a photon stored at the wrong side is off by far more.
  double sum_map = 0, sum_exact = 0;
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 16; ++j) {
      const float x = 1.5f + 1.5f * (i + 0.5f) / 16, y = 1.5f + 1.5f * (j + 0.5f) / 16;
      sum_map += Luminance(map->Irradiance(Vec3(x, y, 3), Vec3(0, 0, -1)));
      sum_exact += Analytic(x, y);
    }
  EXPECT_NEAR(sum_map / sum_exact, 1.0, 0.06)
      << "map " << sum_map / 256 << " exact " << sum_exact / 256;
  // The other side of the ceiling gets nothing; nor does the mirror (its photons go on).
  EXPECT_EQ(Luminance(map->Irradiance(Vec3(2, 2, 3), Vec3(0, 0, 1))), 0.0f);
  EXPECT_EQ(Luminance(map->Irradiance(Vec3(2, 2, 0), Vec3(0, 0, 1))), 0.0f);
}

// A render thread's lookups reuse the last answer within a tenth of its site's radius
// (CausticReuse): over a raster of the ceiling at a pixel's spacing, swept in scanlines as a tile
// is, the answers are fresh lookups' except near the edges of sites' cells, where a neighbouring
// site's estimate (from mostly the same 64 photons) is taken instead. Their sums agree within 1%
// (a tenth of a site's radius past each cell edge changes sites: 7% of the points here, whose
// estimates differ by a few percent; measured 0.08%); and a reused answer never crosses to the
// other side of a surface or to another surface. Reuse within the whole radius changes 66% of
// the answers and the sum by 1.2%.
TEST(CausticMapTest, ReuseGivesTheAnswersOfFreshLookups) {
  const std::unique_ptr<Scene> scene = Build();
  ASSERT_NE(scene, nullptr);
  CausticMapStats stats;
  const std::unique_ptr<CausticMap> map = BuildMap(*scene, &stats);
  ASSERT_NE(map, nullptr);
  CausticReuse reuse;
  double sum_fresh = 0, sum_reused = 0;
  long differ = 0, n = 0;
  for (int j = 0; j < 300; ++j)
    for (int i = 0; i < 300; ++i, ++n) {
      const Vec3 p(1.5f + 0.005f * float(i), 1.5f + 0.005f * float(j), 3);
      const float fresh = Luminance(map->Irradiance(p, Vec3(0, 0, -1)));
      const float reused = Luminance(map->Irradiance(p, Vec3(0, 0, -1), &reuse));
      sum_fresh += fresh;
      sum_reused += reused;
      differ += fresh != reused;
    }
  ASSERT_GT(sum_fresh, 0);
  EXPECT_NEAR(sum_reused / sum_fresh, 1.0, 0.01) << differ << " of " << n << " answers differ";
  EXPECT_LT(differ, n / 2) << differ;
  ASSERT_GT(Luminance(map->Irradiance(Vec3(2, 2, 3), Vec3(0, 0, -1), &reuse)), 0.0f);
  EXPECT_EQ(Luminance(map->Irradiance(Vec3(2, 2, 3), Vec3(0, 0, 1), &reuse)), 0.0f);
  ASSERT_GT(Luminance(map->Irradiance(Vec3(2, 2, 3), Vec3(0, 0, -1), &reuse)), 0.0f);
  EXPECT_EQ(Luminance(map->Irradiance(Vec3(2, 2, 0), Vec3(0, 0, -1), &reuse)), 0.0f);
}

// The same mirror lit by a point light instead: a delta light seen through a delta bounce, which
// no path from the camera can reach (neither irfarm's path integrator nor Mitsuba's renders that
// caustic), so the map leaves it out too and the scene builds none.
TEST(CausticMapTest, DeltaLightsMakeNoCaustics) {
  std::string xml = kScene;
  const std::string lamp =
      xml.substr(xml.find("<emitter type=\"area\">"),
                 xml.find("</emitter>") + 10 - xml.find("<emitter type=\"area\">"));
  xml.replace(xml.find(lamp), lamp.size(), "");
  xml.replace(xml.rfind("</scene>"), 8,
              "<emitter type=\"point\"><point name=\"position\" x=\"0\" y=\"0\" z=\"1\"/>"
              "<rgb name=\"intensity\" value=\"10\"/></emitter></scene>");
  const std::unique_ptr<Scene> scene = Build(xml);
  ASSERT_NE(scene, nullptr);
  ASSERT_EQ(scene->lights().size(), 1u);
  EXPECT_FALSE(CausticMap::SceneHasCaustics(*scene));
  CausticMapStats stats;
  EXPECT_EQ(BuildMap(*scene, &stats), nullptr);
  EXPECT_EQ(stats.emitted, 0);
}

// Where few photons find a caustic bounce (here a mirror of 0.2 x 0.2 on a diffuse floor under
// the lamp instead of the whole plane: about 1% of the lamp's cosine-distributed photons, below
// kLeastCausticShare), the caustics carry little of the light and no map is kept, judged on the
// first batch. Without the floor most photons would leave the scene, which does not count.
TEST(CausticMapTest, NoMapWhereCausticsCarryLittleLight) {
  std::string xml = kScene;
  const std::string mirror = R"(<scale x="10" y="10"/></transform>
    <ref id="mirror"/>)";
  ASSERT_NE(xml.find(mirror), std::string::npos);
  xml.replace(xml.find(mirror), mirror.size(), R"(<scale x="0.1" y="0.1"/></transform>
    <ref id="mirror"/>)");
  const std::string without_floor = xml;
  xml.replace(xml.rfind("</scene>"), 8, R"(<shape type="rectangle">
    <transform name="to_world"><scale x="10" y="10"/><translate z="-0.001"/></transform>
    <ref id="white"/>
  </shape></scene>)");
  const std::unique_ptr<Scene> scene = Build(xml);
  ASSERT_NE(scene, nullptr);
  ASSERT_TRUE(CausticMap::SceneHasCaustics(*scene));
  CausticMapStats stats;
  EXPECT_EQ(BuildMap(*scene, &stats), nullptr);
  EXPECT_EQ(stats.emitted, 65536);
  EXPECT_EQ(stats.stored, 0);
  // Without the floor the photons that miss the mirror leave the scene: the mirror's caustic is
  // then most of the light that lands, and the map is kept.
  const std::unique_ptr<Scene> open_scene = Build(without_floor);
  ASSERT_NE(open_scene, nullptr);
  EXPECT_NE(BuildMap(*open_scene, &stats), nullptr);
  EXPECT_GT(stats.stored, 0);
}

// The records' side of the split, at ceiling points x (facing down): a record path with the map
// (PathSettings::caustics) leaves out the light that reached x through non-diffuse lobes only,
// and adds the map's caustic wherever it lands further on the way, so that records plus the map
// at x count every light once: pi * mean(path with map) + E_map(x) = pi * mean(path without).
// Returns both sides over `points` ceiling points in [1.5, 3]^2, with their standard errors.
struct Split {
  double with_map = 0, without = 0, se_with = 0, se_without = 0, map_at_x = 0;
  double var_with = 0, var_without = 0;  // per ray, of pi * radiance
};
Split RecordSplit(const Scene& scene, const CausticMap& map, float lo, float hi, float z,
                  int points, int rays) {
  Split out;
  const int side = int(std::lround(std::sqrt(double(points))));
  for (const bool use_map : {false, true}) {
    PathSettings path;
    path.caustics = use_map ? &map : nullptr;
    Rng rng(3, use_map ? 1 : 2);
    RenderCounters counters;
    double sum = 0, sum2 = 0;
    long n = 0;
    for (int i = 0; i < side; ++i)
      for (int j = 0; j < side; ++j) {
        const Vec3 x(lo + (hi - lo) * (i + 0.5f) / float(side),
                     lo + (hi - lo) * (j + 0.5f) / float(side), z - 1e-3f);
        if (use_map) out.map_at_x += Luminance(map.Irradiance(x, Vec3(0, 0, -1)));
        for (int k = 0; k < rays; ++k, ++n) {
          const Vec3 l = CosineHemisphere(rng.Next(), rng.Next());
          const Ray ray{x, Vec3(l.x, l.y, -l.z), INFINITY};
          const double v = kPi * Luminance(TracePath(scene, ray, 1, true, path, rng, counters));
          sum += v;
          sum2 += v * v;
        }
      }
    const double mean = sum / double(n), var = sum2 / double(n) - mean * mean;
    (use_map ? out.with_map : out.without) = mean;
    (use_map ? out.se_with : out.se_without) = std::sqrt(var / double(n));
    (use_map ? out.var_with : out.var_without) = var;
  }
  out.map_at_x /= double(side * side);
  return out;
}

// pi * mean(with) + E_map(x) = pi * mean(without), within four standard errors of the two means
// (from their own samples) and of the map's mean over the 16 points (each estimate averages 64
// photons, 1/8 relative; the points' discs barely overlap: 1/32).
void ExpectCountedOnce(const Split& s) {
  const double tol = 4 * std::sqrt(s.se_with * s.se_with + s.se_without * s.se_without +
                                   std::pow(s.map_at_x / 32, 2));
  EXPECT_NEAR(s.with_map + s.map_at_x, s.without, tol)
      << "with " << s.with_map << " map " << s.map_at_x << " without " << s.without;
}

constexpr char kMirror[] =
    R"(<bsdf type="conductor" id="mirror"><string name="material" value="none"/></bsdf>)";
constexpr char kRoughMirror[] =
    R"(<bsdf type="roughconductor" id="mirror"><string name="material" value="none"/><float name="alpha" value="0.1"/></bsdf>)";

// The test scene with the floor a rough mirror (alpha 0.1) and the lamp replaced by `emitter`;
// with `small_ceiling` the ceiling is 10 x 10 (light from the side passes its edge).
std::string RoughMirrorScene(const std::string& emitter, bool small_ceiling) {
  std::string xml = kScene;
  xml.replace(xml.find(kMirror), std::string(kMirror).size(), kRoughMirror);
  const size_t a =
      xml.find("<shape type=\"rectangle\">\n    <transform name=\"to_world\"><scale x=\"0.25\"");
  const size_t b = xml.find("</shape>", a) + 8;
  xml.replace(a, b - a, emitter);
  if (small_ceiling) {
    const std::string ceiling = R"(<scale x="10" y="10"/><rotate x="1" angle="180"/>)";
    xml.replace(xml.find(ceiling), ceiling.size(),
                R"(<scale x="5" y="5"/><rotate x="1" angle="180"/>)");
  }
  return xml;
}

// A one-light scene whose light reaches the ceiling (z = 3) only through a glossy highlight:
// the map holds that light, the record paths at ceiling points in [lo, hi]^2 leave it out, count
// each light once with the map, and their variance per ray falls below a tenth.
void ExpectHighlightIsTheMaps(const std::string& xml, float lo, float hi,
                              const std::string& name = "caustic.xml") {
  const std::unique_ptr<Scene> scene = Build(xml, name);
  ASSERT_NE(scene, nullptr);
  ASSERT_EQ(scene->lights().size(), 1u);
  ASSERT_TRUE(CausticMap::SceneHasCaustics(*scene));
  CausticMapStats stats;
  const std::unique_ptr<CausticMap> map = BuildMap(*scene, &stats);
  ASSERT_NE(map, nullptr);
  EXPECT_GE(stats.stored, 200000);
  const Split s = RecordSplit(*scene, *map, lo, hi, 3.0f, 16, 60000);
  ExpectCountedOnce(s);
  EXPECT_GT(s.map_at_x, 0.5 * s.without);
  EXPECT_LT(s.var_with, 0.1 * s.var_without)
      << "variance per ray with the map " << s.var_with << ", without " << s.var_without;
}

// The mirror: from the ceiling, rays towards the mirror reach the lamp by one delta bounce. With
// the map they count none of it (the lamp's image is the map's at x; the ceiling's own caustic,
// seen in the mirror, is added from the map where the path lands on it), without the map the
// paths find it (a ray sees the image with probability about 0.2%).
TEST(CausticMapTest, RecordPathsAndMapCountMirrorLightOnce) {
  const std::unique_ptr<Scene> scene = Build();
  ASSERT_NE(scene, nullptr);
  CausticMapStats stats;
  const std::unique_ptr<CausticMap> map = BuildMap(*scene, &stats);
  ASSERT_NE(map, nullptr);
  const Split s = RecordSplit(*scene, *map, 1.5f, 3.0f, 3.0f, 16, 60000);
  ExpectCountedOnce(s);
  // Most of the light at x is the lamp's image: the map's part is the larger one.
  EXPECT_GT(s.map_at_x, s.with_map);
}

// A glossy caustic of a delta light: a spot 1 above a rough mirror (roughconductor, alpha 0.1,
// reflectance 1) filling z = 0, pointing down; a diffuse ceiling at z = 3. The spot's highlight
// lights the ceiling around the axis; a record path from the ceiling finds it only where its ray
// meets the floor near the highlight's reflection point (next-event estimation through the
// glossy lobe): the rare, bright strata that blotch a cache. The map holds that light (photons
// from the spot, reflected by the glossy lobe), the record paths leave it out and count each
// light once with the map, and their variance per ray falls: the point of the split.
TEST(CausticMapTest, SpotHighlightOnGlossyFloorIsTheMaps) {
  const std::string xml = RoughMirrorScene(
      R"(<emitter type="spot"><transform name="to_world"><lookat origin="0, 0, 1" target="0, 0, 0" up="0, 1, 0"/></transform>)"
      R"(<rgb name="intensity" value="10"/><float name="cutoff_angle" value="30"/><float name="beam_width" value="25"/></emitter>)",
      false);
  ExpectHighlightIsTheMaps(xml, 0.2f, 1.0f);
}

// The sun's glossy caustic: a directional light travelling at 45 degrees (-x, down) over the
// rough mirror (alpha 0.1) filling z = 0, with a 10 x 10 diffuse ceiling at z = 3 facing down
// and no lamp. The sun reaches the floor past the ceiling's edge (x > 2 on the floor), whose
// highlight lights the ceiling around x = x_floor - 3; the ceiling's points see no sun directly.
// As for the spot: the map holds that light (photons from a disc across the sun that covers the
// floor), the record paths leave it out, each light is counted once and the variance per ray
// falls. With a perfect mirror instead there is no map: the sun through a delta lobe is light
// no path tracer renders.
TEST(CausticMapTest, SunHighlightOnGlossyFloorIsTheMaps) {
  const std::string xml =
      RoughMirrorScene(R"(<emitter type="directional"><vector name="direction" value="-1, 0, -1"/>)"
                       R"(<rgb name="irradiance" value="10"/></emitter>)",
                       true);
  ExpectHighlightIsTheMaps(xml, 0.5f, 2.5f);

  std::string smooth = xml;
  smooth.replace(smooth.find(kRoughMirror), std::string(kRoughMirror).size(), kMirror);
  const std::unique_ptr<Scene> smooth_scene = Build(smooth);
  ASSERT_NE(smooth_scene, nullptr);
  EXPECT_FALSE(CausticMap::SceneHasCaustics(*smooth_scene));
}

// The environment's sun (EnvironmentSun): the sun test's scene lit instead by an envmap (a dim
// sky of 0.05 and a 3 x 3 texel sun of irradiance about 10, in the sun's direction above). The
// map takes the sun's highlight from its directions only (the sky's reflection in the floor
// stays with the records: counted once all the same), and the records' variance per ray falls.
TEST(CausticMapTest, EnvironmentSunHighlightIsTheMaps) {
  Image sky(256, 128);
  for (Vec3& p : sky.pixels) p = Vec3(0.05f);
  // Towards the sky along (1, 0, 1) / sqrt(2): u = 0.375, v = 0.5 (EnvmapUv).
  const float texel = (2 * kPi / 256) * (kPi / 128);
  for (int y = 63; y < 66; ++y)
    for (int x = 95; x < 98; ++x) sky.pixels[size_t(y) * 256 + size_t(x)] = Vec3(10 / (9 * texel));
  const std::string path = ::testing::TempDir() + "/caustic-sun-sky.exr";
  const std::string name = ::testing::TempDir() + "/caustic-sun.xml";
  ASSERT_TRUE(WriteExr(sky, path).ok());
  const std::string xml = RoughMirrorScene(
      R"(<emitter type="envmap"><string name="filename" value="caustic-sun-sky.exr"/></emitter>)",
      true);
  const std::unique_ptr<Scene> scene = Build(xml, name);
  ASSERT_NE(scene, nullptr);
  const EnvironmentSun& sun = scene->environment_sun();
  ASSERT_FALSE(sun.empty());
  EXPECT_GT(Dot(sun.axis(), Normalize(Vec3(1, 0, 1))), std::cos(0.02f));
  EXPECT_TRUE(sun.Contains(Normalize(Vec3(1, 0, 1))));
  EXPECT_FALSE(sun.Contains(Normalize(Vec3(1, 0, 0.8f))));
  EXPECT_NEAR(sun.irradiance(), 10.0, 1.0);
  ExpectHighlightIsTheMaps(xml, 0.5f, 2.5f, name);
  // Without the sun there is no environment sun and no map.
  for (Vec3& p : sky.pixels) p = Vec3(0.05f);
  ASSERT_TRUE(WriteExr(sky, path).ok());
  const std::unique_ptr<Scene> dim = Build(xml, name);
  ASSERT_NE(dim, nullptr);
  EXPECT_TRUE(dim->environment_sun().empty());
  EXPECT_FALSE(CausticMap::SceneHasCaustics(*dim));
}

}  // namespace
}  // namespace irfarm
