// Camera lookups weigh records at the wider accuracy a * lookup_factor and make a new record only
// where none counts at a (IrrcacheSettings::lookup_factor, lookup_agreement), through the
// integrator's one lookup rule (IrrcacheIntegrator::CachedIrradiance) on a real cache. The expected
// answers are Ward's weights (1 / eps) computed here from the records' positions.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "cache/irradiance_cache.h"
#include "render/irrcache_integrator.h"
#include "render/scene_loader.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

constexpr char kFloorXml[] = R"(<scene version="3.0.0">
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0, 2, -2" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="12"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="5"/></transform>
    <bsdf type="diffuse"/>
  </shape>
</scene>
)";

// A record on the floor (normal +y) at (x, 0, z), radius 1, grey irradiance e.
IrradianceRecord FloorRecord(float x, float z, float e) {
  IrradianceRecord r;
  r.position = Vec3(x, 0, z);
  r.normal = Vec3(0, 1, 0);
  r.radius = 1;
  r.irradiance = Vec3(e, e, e);
  return r;
}

struct CacheOnFloor {
  LoadedScene built;
  IrrcacheSettings settings;
  std::unique_ptr<IrradianceCache> cache;
  std::unique_ptr<IrrcacheIntegrator> integrator;

  CacheOnFloor(float lookup_factor, const std::vector<IrradianceRecord>& records) {
    built = BuildLoaded(LoadSceneString(kFloorXml, ::testing::TempDir() + "/floor.xml", {}));
    settings.accuracy = 0.1f;
    settings.lookup_factor = lookup_factor;
    CacheSettings cs;
    cs.bounds = built.scene->bounds();
    cs.max_accuracy = settings.accuracy * std::max(lookup_factor, settings.relaxed_factor);
    cache = std::make_unique<IrradianceCache>(cs);
    for (const IrradianceRecord& r : records) cache->Insert(r);
    integrator = std::make_unique<IrrcacheIntegrator>(*built.scene, cache.get(), settings);
  }
  // The answer at the origin (normal +y), through the octree walk and through a pixel region;
  // both must agree.
  bool At(Vec3* E) const {
    LookupInfo info, info_near;
    Vec3 e_near;
    LookupRegion region;
    const bool walk =
        integrator->CachedIrradiance(Vec3(0, 0, 0), Vec3(0, 1, 0), 0, 0, 0, nullptr, E, &info);
    const bool near = integrator->CachedIrradiance(Vec3(0, 0, 0), Vec3(0, 1, 0), 0, 0.05f, 0.1f,
                                                   &region, &e_near, &info_near);
    EXPECT_EQ(walk, near);
    if (walk && near) {
      EXPECT_NEAR(e_near.x, E->x, 1e-5f * E->x);
    }
    return walk;
  }
};

// One record within a (eps 0.05, weight 20) of value 1 and two at eps 0.12 (weight 1 / 0.12
// each, within 1.5 a only) of value `far`.
std::vector<IrradianceRecord> NearAndFar(float far) {
  return {FloorRecord(0.05f, 0, 1), FloorRecord(0.12f, 0, far), FloorRecord(-0.12f, 0, far)};
}

TEST(WideLookupTest, AveragesTheWiderRecordsWhereTheyAgree) {
  const CacheOnFloor s(1.5f, NearAndFar(1.2f));
  Vec3 E;
  ASSERT_TRUE(s.At(&E));
  const float w_near = 1 / 0.05f, w_far = 1 / 0.12f;
  const float expect = (w_near * 1 + 2 * w_far * 1.2f) / (w_near + 2 * w_far);  // 1.09
  EXPECT_NEAR(E.x, expect, 1e-4f);
}

TEST(WideLookupTest, WardsRuleAtFactorOneUsesOnlyTheRecordWithinA) {
  const CacheOnFloor s(1.0f, NearAndFar(1.2f));
  Vec3 E;
  ASSERT_TRUE(s.At(&E));
  EXPECT_NEAR(E.x, 1.0f, 1e-5f);
}

TEST(WideLookupTest, TheRecordsWithinAAnswerWhereTheWiderOnesDisagree) {
  // The wider mean would be 1.91: 91% above the record within a, past lookup_agreement (25%):
  // structure (a lamp's edge), not noise.
  const CacheOnFloor s(1.5f, NearAndFar(3.0f));
  Vec3 E;
  ASSERT_TRUE(s.At(&E));
  EXPECT_NEAR(E.x, 1.0f, 1e-5f);
}

TEST(WideLookupTest, ARecordIsDueWhereNoneCountsAtA) {
  // Only records at eps 0.12: a lookup at 1.5 a finds them, but records stay spaced for a.
  const CacheOnFloor s(1.5f, {FloorRecord(0.12f, 0, 1), FloorRecord(-0.12f, 0, 1)});
  Vec3 E(-1, -1, -1);
  EXPECT_FALSE(s.At(&E));
  Vec3 wide;
  EXPECT_TRUE(s.cache->Lookup(Vec3(0, 0, 0), Vec3(0, 1, 0), 0.15f, &wide, nullptr));
}

}  // namespace
}  // namespace irfarm
