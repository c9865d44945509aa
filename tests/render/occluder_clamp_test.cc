// The occluder clamp of secondary records (IrrcacheSettings::occluder_reach): a record made at
// level 1 next to a thin panel standing on the floor must not reach the floor behind the panel,
// whatever its footprint, and without the panel the same record keeps its footprint's spacing.
// Real scene, real rays, real cache: the record is computed by the integrator, inserted and
// looked up at the relaxed accuracy the final pass uses.
#include <gtest/gtest.h>

#include <memory>
#include <optional>
#include <string>

#include "cache/irradiance_cache.h"
#include "render/irrcache_integrator.h"
#include "render/renderer.h"
#include "render/sampling.h"
#include "render/scene_loader.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

// A grey floor (the y = 0 plane, facing +y) under a uniform sky; with `panel`, a thin panel in the
// plane x = 0.2 stands on it (y in [0, 2], z in [-1, 1]); with `post` instead, a post as high and
// 0.02 wide (z in [-0.01, 0.01]) stands there.
std::string FloorXml(bool panel, bool post = false) {
  std::string xml = R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="-2, 1, 0" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="24"/></film>
  </sensor>
  <bsdf type="diffuse" id="gray"><rgb name="reflectance" value="0.5"/></bsdf>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="5"/></transform>
    <ref id="gray"/>
  </shape>
)";
  if (panel)
    xml += R"(  <shape type="rectangle">
    <transform name="to_world"><rotate y="1" angle="90"/><translate x="0.2" y="1"/></transform>
    <ref id="gray"/>
  </shape>
)";
  if (post)
    xml += R"(  <shape type="rectangle">
    <transform name="to_world"><rotate y="1" angle="90"/><scale z="0.01"/><translate x="0.2" y="1"/></transform>
    <ref id="gray"/>
  </shape>
)";
  return xml + "</scene>\n";
}

// A level-1 record at the origin, with a footprint of 0.1 scene units per "pixel" (a wide ray
// cone: the min-spacing floor alone would make it valid 0.15 units around at accuracy a, 0.3 at
// the relaxed accuracy), inserted into a
// cache whose lookups may relax to the final pass's accuracy.
struct RecordSetup {
  LoadedScene built;
  IrrcacheSettings settings;
  std::unique_ptr<IrradianceCache> cache;
  IrradianceRecord record;
  float a_max = 0;
};

RecordSetup MakeRecord(bool panel, int level = 1, float footprint = 0.1f, bool plane = true,
                       bool post = false, std::optional<float> plane_fraction = std::nullopt) {
  RecordSetup s;
  s.settings.occluder_plane = plane;
  if (plane_fraction) s.settings.occluder_plane_fraction = *plane_fraction;
  s.built =
      BuildLoaded(LoadSceneString(FloorXml(panel, post), ::testing::TempDir() + "/s.xml", {}));
  const Scene& scene = *s.built.scene;
  CacheSettings cs;
  cs.bounds = scene.bounds();
  s.a_max = s.settings.accuracy * s.settings.relaxed_factor;
  cs.max_accuracy = s.a_max;
  s.cache = std::make_unique<IrradianceCache>(cs);
  const IrrcacheIntegrator integrator(scene, s.cache.get(), s.settings);
  SurfaceHit hit;
  EXPECT_TRUE(scene.Intersect(Ray{Vec3(0, 1, 0), Vec3(0, -1, 0)}, &hit));
  EXPECT_NEAR(hit.p.y, 0, 1e-5);
  Rng rng(7, 1);
  RenderCounters counters;
  s.record =
      integrator.ComputeRecord(hit, Vec3(0, 1, 0), 1, footprint, rng, counters, nullptr, level);
  s.cache->Insert(s.record);
  return s;
}

bool Found(const RecordSetup& s, const Vec3& x, int level = 1) {
  Vec3 e;
  return s.cache->Lookup(x, Vec3(0, 1, 0), s.a_max, &e, nullptr, level);
}

TEST(OccluderClampTest, SecondaryRecordDoesNotReachBehindAThinPanel) {
  const RecordSetup s = MakeRecord(true);
  ASSERT_GT(s.record.irradiance.x, 0);
  // The panel is 0.2 away: the validity radius stays within 0.7 x the nearest hit (>= 0.2).
  EXPECT_LT(s.a_max * s.record.radius, 0.2f);
  EXPECT_FALSE(Found(s, Vec3(0.25f, 0, 0)));  // behind the panel
  EXPECT_FALSE(Found(s, Vec3(0.21f, 0, 0)));  // just behind it
  EXPECT_TRUE(Found(s, Vec3(-0.1f, 0, 0)));   // on the record's side, nearer than the panel
}

TEST(OccluderClampTest, WithoutThePanelTheFootprintSpacingStays) {
  const RecordSetup s = MakeRecord(false);
  // min_spacing_px footprints of 0.1 units: valid 0.15 units around at accuracy a.
  EXPECT_GE(s.settings.accuracy * s.record.radius, s.settings.min_spacing_px * 0.1f * 0.999f);
  EXPECT_TRUE(Found(s, Vec3(0.21f, 0, 0)));
  EXPECT_TRUE(Found(s, Vec3(0.25f, 0, 0)));
}

// A camera record (level 0) keeps its spacing floor (1.5 footprints: 0.3 units at a footprint of
// 0.2, past the panel at 0.2), but its occluder plane (IrrcacheSettings::occluder_plane) keeps it
// from the floor behind the panel; without the panel it reaches there.
TEST(OccluderClampTest, CameraRecordKeepsItsFloorButNotBehindAPanel) {
  const RecordSetup s = MakeRecord(true, 0, 0.2f);
  ASSERT_GT(s.record.irradiance.x, 0);
  EXPECT_GE(s.settings.accuracy * s.record.radius, s.settings.min_spacing_px * 0.2f * 0.999f);
  EXPECT_FALSE(Found(s, Vec3(0.25f, 0, 0), 0));  // behind the panel
  EXPECT_FALSE(Found(s, Vec3(0.21f, 0, 0), 0));
  EXPECT_TRUE(Found(s, Vec3(-0.1f, 0, 0), 0));
  EXPECT_TRUE(Found(s, Vec3(0.15f, 0, 0), 0));  // nearer than the panel

  const RecordSetup open = MakeRecord(false, 0, 0.2f);
  EXPECT_TRUE(Found(open, Vec3(0.25f, 0, 0), 0));
  EXPECT_TRUE(Found(open, Vec3(0.21f, 0, 0), 0));

  // With the plane off (as before it), the same record reaches behind the panel.
  const RecordSetup off = MakeRecord(true, 0, 0.2f, false);
  EXPECT_TRUE(Found(off, Vec3(0.25f, 0, 0), 0));
}

// A camera record by a post (IrrcacheSettings::occluder_plane_fraction): the post is its
// nearest hit, but few of its rays (about 1.6% cosine-weighted) hit anything within twice that
// distance, so it keeps no plane and reaches the floor behind the post, which the post hardly
// shades; by the panel (about 15% of its rays that close) the same record keeps its plane. With
// the fraction at 0 (every record a plane) the post's record is cut off behind the post.
TEST(OccluderClampTest, CameraRecordByASmallObjectKeepsNoPlane) {
  const RecordSetup post = MakeRecord(false, 0, 0.2f, true, true);
  ASSERT_GT(post.record.irradiance.x, 0);
  EXPECT_GE(post.settings.accuracy * post.record.radius,
            post.settings.min_spacing_px * 0.2f * 0.999f);
  EXPECT_EQ(Length(post.record.occluder), 0.0f);
  EXPECT_TRUE(Found(post, Vec3(0.25f, 0, 0), 0));  // behind the post

  const RecordSetup panel = MakeRecord(true, 0, 0.2f);
  EXPECT_GT(Length(panel.record.occluder), 0.19f);
  EXPECT_LT(Length(panel.record.occluder), 0.4f);

  const RecordSetup every = MakeRecord(false, 0, 0.2f, true, true, 0.0f);
  EXPECT_GT(Length(every.record.occluder), 0.19f);
  EXPECT_FALSE(Found(every, Vec3(0.25f, 0, 0), 0));
}

}  // namespace
}  // namespace irfarm
