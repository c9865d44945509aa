// Records' occluder planes (IrradianceRecord::occluder) across the wire (RecordBatch.occluders)
// and snapshot files (version 2): they arrive intact, a sender or file without them gives
// records without a plane, a malformed or non-finite occluder is refused, and a received
// record's plane keeps it from the other side of its occluder in the receiver's cache.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "cache/irradiance_cache.h"
#include "cache/snapshot.h"
#include "service/record_codec.h"

namespace irfarm {
namespace {

IrradianceRecord Record(float x, const Vec3& occluder) {
  IrradianceRecord r;
  r.position = Vec3(x, 0, 0);
  r.normal = Vec3(0, 1, 0);
  r.irradiance = Vec3(1, 2, 3);
  r.radius = 2;
  r.occluder = occluder;
  return r;
}

TEST(RecordFormatTest, OccludersCrossTheWire) {
  const std::vector<IrradianceRecord> recs = {Record(0, Vec3(0.2f, 0, 0)), Record(1, Vec3())};
  v1::RecordBatch batch;
  PackRecords(recs, 5, &batch);
  ASSERT_EQ(batch.occluders_size(), 6);
  const absl::StatusOr<std::vector<IrradianceRecord>> back = DecodeRecords(batch);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->size(), 2u);
  EXPECT_EQ((*back)[0].occluder.x, 0.2f);
  EXPECT_EQ((*back)[1].occluder.x, 0.0f);
  EXPECT_EQ((*back)[0].origin, 5u);
  EXPECT_TRUE(IsValidRecord((*back)[0]));

  // A sender that does not send occluders: records without a plane.
  v1::RecordBatch old = batch;
  old.clear_occluders();
  const absl::StatusOr<std::vector<IrradianceRecord>> plain = DecodeRecords(old);
  ASSERT_TRUE(plain.ok());
  EXPECT_EQ((*plain)[0].occluder.x, 0.0f);
  // Appending to such a batch keeps it consistent (no occluders for any record).
  PackRecords(recs, 5, &old);
  EXPECT_EQ(old.occluders_size(), 0);
  EXPECT_TRUE(DecodeRecords(old).ok());

  // Occluders for some records only: refused with the reason.
  v1::RecordBatch bad = batch;
  bad.mutable_occluders()->RemoveLast();
  const absl::StatusOr<std::vector<IrradianceRecord>> refused = DecodeRecords(bad);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(refused.status().message()).find("occluder"), std::string::npos);

  // A non-finite occluder decodes, and validation rejects the record.
  v1::RecordBatch nan = batch;
  nan.set_occluders(1, NAN);
  const absl::StatusOr<std::vector<IrradianceRecord>> poisoned = DecodeRecords(nan);
  ASSERT_TRUE(poisoned.ok());
  EXPECT_FALSE(IsValidRecord((*poisoned)[0]));
  EXPECT_TRUE(IsValidRecord((*poisoned)[1]));
}

TEST(RecordFormatTest, ReceivedPlaneKeepsTheRecordFromBehindItsOccluder) {
  // Valid 0.2 units around at a = 0.1 (R = 2); its occluder plane at x = 0.1.
  v1::RecordBatch batch;
  PackRecords({Record(0, Vec3(0.1f, 0, 0))}, 5, &batch);
  const absl::StatusOr<std::vector<IrradianceRecord>> got = DecodeRecords(batch);
  ASSERT_TRUE(got.ok());
  CacheSettings cs;
  cs.bounds = Bounds3{Vec3(-5), Vec3(5)};
  IrradianceCache cache(cs);
  cache.Insert((*got)[0]);
  const Vec3 n(0, 1, 0);
  Vec3 e;
  EXPECT_TRUE(cache.Lookup(Vec3(0.05f, 0, 0), n, 0.1f, &e, nullptr));
  EXPECT_TRUE(cache.Lookup(Vec3(-0.15f, 0, 0), n, 0.1f, &e, nullptr));
  EXPECT_FALSE(cache.Lookup(Vec3(0.15f, 0, 0), n, 0.1f, &e, nullptr));  // behind the plane
  // The same record from a sender without occluders reaches there.
  batch.clear_occluders();
  const absl::StatusOr<std::vector<IrradianceRecord>> plain = DecodeRecords(batch);
  ASSERT_TRUE(plain.ok());
  IrradianceCache without(cs);
  without.Insert((*plain)[0]);
  EXPECT_TRUE(without.Lookup(Vec3(0.15f, 0, 0), n, 0.1f, &e, nullptr));
}

TEST(RecordFormatTest, SnapshotsKeepOccludersAndReadVersionOne) {
  Snapshot snap;
  snap.scene_hash = 42;
  snap.records = {Record(0, Vec3(0.2f, 0, 0)), Record(1, Vec3())};
  const std::string bytes = SerializeSnapshot(snap);
  const absl::StatusOr<Snapshot> back = ParseSnapshot(bytes, "v2");
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->records.size(), 2u);
  EXPECT_EQ(back->records[0].occluder.x, 0.2f);
  EXPECT_EQ(back->records[0].irradiance.z, 3.0f);

  // The same records as a version-1 file (44 bytes per record, no occluder).
  std::string v1(bytes.data(), 32);
  const uint32_t version = 1, record_bytes = 44;
  std::memcpy(&v1[8], &version, 4);
  std::memcpy(&v1[12], &record_bytes, 4);
  for (size_t i = 0; i < snap.records.size(); ++i) v1.append(bytes.data() + 32 + i * 56, 44);
  const uint64_t sum = SnapshotChecksum(v1.data(), v1.size());
  v1.append(reinterpret_cast<const char*>(&sum), 8);
  const absl::StatusOr<Snapshot> old = ParseSnapshot(v1, "v1");
  ASSERT_TRUE(old.ok()) << old.status();
  ASSERT_EQ(old->records.size(), 2u);
  EXPECT_EQ(old->records[0].occluder.x, 0.0f);
  EXPECT_EQ(old->records[1].position.x, 1.0f);

  // A non-finite occluder makes the file invalid, named.
  Snapshot poisoned = snap;
  poisoned.records[1].occluder = Vec3(0, INFINITY, 0);
  const absl::StatusOr<Snapshot> refused = ParseSnapshot(SerializeSnapshot(poisoned), "p.snap");
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(std::string(refused.status().message()).find("record 1 is invalid"), std::string::npos);
}

}  // namespace
}  // namespace irfarm
