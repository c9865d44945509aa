// Tests of a secondary record's occluder plane (cache/occluder_plane.h): the 6-byte packing keeps
// the plane, and a record does not count beyond its nearest occluder, in the weight rule and
// through the cache's own storage.
#include "cache/occluder_plane.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cache/irradiance_cache.h"
#include "cache/irradiance_weight.h"

namespace irfarm {
namespace {

TEST(OccluderPlaneTest, PackingKeepsDirectionAndDistance) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<float> u(-1, 1), e(-30, 30);
  for (int i = 0; i < 10000; ++i) {
    Vec3 d(u(gen), u(gen), u(gen));
    if (Length(d) < 1e-3f) continue;
    d = Normalize(d);
    const float dist = std::exp2(e(gen));
    const Vec3 back = UnpackOccluder(PackOccluder(d * dist));
    // 16-bit octahedral directions: within 1e-4 rad; 1024 steps per octave: within 0.04%.
    EXPECT_LT(Length(Cross(Normalize(back), d)), 1e-4f) << i;
    EXPECT_GT(Dot(back, d), 0.0f) << i;
    EXPECT_NEAR(Length(back) / dist, 1.0f, 4e-4f) << i;
  }
}

TEST(OccluderPlaneTest, NothingToPackMeansNoOccluder) {
  EXPECT_EQ(LengthSquared(UnpackOccluder(PackOccluder(Vec3()))), 0.0f);
  EXPECT_EQ(LengthSquared(UnpackOccluder(PackOccluder(Vec3(INFINITY, 0, 0)))), 0.0f);
  EXPECT_EQ(LengthSquared(UnpackOccluder(PackOccluder(Vec3(NAN, 0, 0)))), 0.0f);
  // Beyond 2^32 or below 2^-32: not representable, so no plane (the record counts as before).
  EXPECT_EQ(LengthSquared(UnpackOccluder(PackOccluder(Vec3(0, 0, 1e12f)))), 0.0f);
  EXPECT_EQ(LengthSquared(UnpackOccluder(PackOccluder(Vec3(0, 0, 1e-12f)))), 0.0f);
}

// A record on a floor 0.1 from a partition at x = 0.1 (its nearest hit), reaching 0.5: points
// before the partition count, points past it do not.
IrradianceRecord FloorRecordByPartition() {
  IrradianceRecord r;
  r.position = Vec3(0, 0, 0);
  r.normal = Vec3(0, 1, 0);
  r.radius = 0.5f;
  r.irradiance = Vec3(1);
  r.level = 1;
  r.occluder = Vec3(0.1f, 0, 0);
  return r;
}

TEST(OccluderPlaneTest, ARecordDoesNotCountBeyondItsOccluder) {
  const IrradianceRecord r = FloorRecordByPartition();
  const Vec3 n(0, 1, 0);
  EXPECT_GT(RecordWeight(Vec3(0.09f, 0, 0), n, 1.0f, r), 0);
  EXPECT_GT(RecordWeight(Vec3(-0.3f, 0, 0.2f), n, 1.0f, r), 0);  // away from it
  EXPECT_GT(RecordWeight(Vec3(0.05f, 0, 0.3f), n, 1.0f, r), 0);  // along it
  EXPECT_EQ(RecordWeight(Vec3(0.11f, 0, 0), n, 1.0f, r), 0);
  EXPECT_EQ(RecordWeight(Vec3(0.2f, 0, 0.1f), n, 1.0f, r), 0);
  IrradianceRecord plain = r;
  plain.occluder = Vec3();  // no plane: the same points count
  EXPECT_GT(RecordWeight(Vec3(0.2f, 0, 0.1f), n, 1.0f, plain), 0);
}

TEST(OccluderPlaneTest, TheCacheKeepsThePlane) {
  CacheSettings s;
  s.bounds.Extend(Vec3(-1, -1, -1));
  s.bounds.Extend(Vec3(1, 1, 1));
  s.max_accuracy = 1.0f;
  IrradianceCache cache(s);
  cache.Insert(FloorRecordByPartition());
  const Vec3 n(0, 1, 0);
  Vec3 e;
  LookupInfo info;
  EXPECT_TRUE(cache.Lookup(Vec3(0.09f, 0, 0), n, 1.0f, &e, &info, 1));
  EXPECT_EQ(info.records_used, 1);
  EXPECT_FALSE(cache.Lookup(Vec3(0.2f, 0, 0.1f), n, 1.0f, &e, &info, 1));
  EXPECT_TRUE(cache.LookupBruteForce(Vec3(0.09f, 0, 0), n, 1.0f, &e, &info, 1));
  EXPECT_FALSE(cache.LookupBruteForce(Vec3(0.2f, 0, 0.1f), n, 1.0f, &e, &info, 1));
}

}  // namespace
}  // namespace irfarm
