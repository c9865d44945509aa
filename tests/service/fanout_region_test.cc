// Filtered record fan-out in the real JobManager (no gRPC): on the two-rooms scene (left room
// x in [-2.5, -0.5], right room x in [0.5, 2.5]), two workers each lease one tile and report the
// box of one room. A record published by one worker reaches the other only when it lies within
// max_accuracy * R of that worker's region; a worker whose region is reported after records were
// withheld from it gets them from the backlog; malformed regions are refused (violation, Rejected
// notice) and a second region for the same lease is ignored; with filter_fanout off every record
// goes to every worker.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "coordinator/fanout_region.h"
#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"
#include "service/record_codec.h"
#include "service/scene_bundle.h"

namespace irfarm {
namespace {

const std::string kScene = std::string(IRFARM_TEST_DATA) + "/scenes/two-rooms/scene.xml";

// A level-0 record on the floor at x (y = 0, z = 1), normal up, radius R.
IrradianceRecord FloorRecord(float x, float radius) {
  IrradianceRecord r;
  r.position = Vec3(x, 0, 1);
  r.normal = Vec3(0, 1, 0);
  r.irradiance = Vec3(0.5f);
  r.radius = radius;
  return r;
}

v1::TileRegion Region(const v1::TileLease& lease, float x0, float x1) {
  v1::TileRegion r;
  r.set_job_id(lease.job_id());
  r.set_lease_token(lease.lease_token());
  r.set_min_x(x0);
  r.set_max_x(x1);
  r.set_min_y(0);
  r.set_max_y(2);
  r.set_min_z(0);
  r.set_max_z(2);
  return r;
}

class FanoutRegionTest : public ::testing::Test {
 protected:
  // `outbox_bytes` bounds the record fan-out queued for one worker; 100 records per catch-up
  // batch, so that a small bound still lets some batches through.
  void Start(bool filter, size_t outbox_bytes = size_t(64) << 20, int tile_size = 48) {
    JobManagerOptions options;
    options.filter_fanout = filter;
    options.limits.max_outbox_bytes = outbox_bytes;
    options.sync_batch_records = 100;
    manager_ = std::move(*JobManager::Create(options, &store_));
    v1::SubmitJobRequest req;
    *req.mutable_scene()->mutable_bundle() = *MakeBundle(kScene);
    (*req.mutable_settings()->mutable_defines())["resx"] = "96";
    (*req.mutable_settings()->mutable_defines())["resy"] = "48";
    req.mutable_settings()->set_tile_size(tile_size);
    req.mutable_settings()->set_share_records(true);
    ASSERT_TRUE(manager_->Submit(req).ok());
    a_ = manager_->RegisterWorker("a", "", 1, true);
    b_ = manager_->RegisterWorker("b", "", 1, true);
    lease_a_ = LeaseOf(a_);
    lease_b_ = LeaseOf(b_);
  }
  v1::TileLease LeaseOf(uint32_t worker) {
    for (const v1::CoordinatorMessage& m : manager_->Poll(worker, std::chrono::milliseconds(0)))
      if (m.has_lease()) return m.lease();
    ADD_FAILURE() << "no lease for worker " << worker;
    return v1::TileLease();
  }
  // Positions (x) of the records queued for `worker`; counts Rejected notices.
  std::vector<float> Received(uint32_t worker, int* rejected = nullptr) {
    std::vector<float> xs;
    for (const v1::CoordinatorMessage& m : manager_->Poll(worker, std::chrono::milliseconds(0))) {
      if (m.has_rejected() && rejected) ++*rejected;
      if (!m.has_records()) continue;
      const absl::StatusOr<std::vector<IrradianceRecord>> records =
          DecodeRecords(m.records().batch());
      EXPECT_TRUE(records.ok());
      if (!records.ok()) continue;
      for (const IrradianceRecord& r : *records) xs.push_back(r.position.x);
    }
    std::sort(xs.begin(), xs.end());
    return xs;
  }
  absl::Status Publish(uint32_t worker, const v1::TileLease& lease,
                       const std::vector<IrradianceRecord>& records) {
    v1::JobRecords m;
    m.set_job_id(lease.job_id());
    PackRecords(records, worker, m.mutable_batch());
    return manager_->AddRecords(worker, m);
  }
  v1::WorkerJobStats Stats(uint32_t worker) {
    const absl::StatusOr<v1::Job> job = manager_->GetJob(lease_a_.job_id());
    EXPECT_TRUE(job.ok());
    if (!job.ok()) return v1::WorkerJobStats();
    for (const v1::WorkerJobStats& s : job->workers())
      if (s.worker_id() == worker) return s;
    return v1::WorkerJobStats();
  }

  uint64_t BatchesDropped(uint32_t worker) {
    const v1::GetClusterResponse cluster = manager_->Cluster();
    for (const v1::WorkerInfo& w : cluster.workers())
      if (w.id() == worker) return w.batches_dropped();
    ADD_FAILURE() << "no worker " << worker;
    return 0;
  }
  // `n` left-room floor records (x in [-2.4, -0.6]), published by B in batches of 100.
  void PublishLeftRoom(int n) {
    for (int b = 0; b < n; b += 100) {
      std::vector<IrradianceRecord> batch;
      for (int i = b; i < std::min(n, b + 100); ++i)
        batch.push_back(FloorRecord(-2.4f + 1.8f * float(i) / float(n), 1));
      ASSERT_TRUE(Publish(b_, lease_b_, batch).ok());
    }
  }

  InMemoryJobStore store_;
  std::unique_ptr<JobManager> manager_;
  uint32_t a_ = 0, b_ = 0;
  v1::TileLease lease_a_, lease_b_;
};

// Records at the right room's floor (x = 1.5), at its inner wall's foot (x = 0.6, R = 1: reach
// 0.1 at a = 0.1, so it misses a box ending at x = -0.5) and one reaching across the divider
// (x = 0.6, R = 12: reach 1.2 > 1.1).
std::vector<IrradianceRecord> RightRoomRecords() {
  return {FloorRecord(1.5f, 1), FloorRecord(0.6f, 1), FloorRecord(0.6f, 12)};
}

TEST_F(FanoutRegionTest, SendsOnlyRecordsReachingTheRegion) {
  Start(true);
  ASSERT_TRUE(manager_->AddTileRegion(a_, Region(lease_a_, -2.5f, -0.5f)).ok());
  ASSERT_TRUE(manager_->AddTileRegion(b_, Region(lease_b_, 0.5f, 2.5f)).ok());
  Received(a_);
  ASSERT_TRUE(Publish(b_, lease_b_, RightRoomRecords()).ok());
  EXPECT_EQ(Received(a_), std::vector<float>({0.6f}));  // only the one reaching across
  EXPECT_EQ(Stats(a_).records_delivered(), 1u);
  EXPECT_EQ(Stats(a_).records_withheld(), 2u);
  // Records of A's room go to A's job cache; B gets none of them (it is in the other room).
  ASSERT_TRUE(Publish(a_, lease_a_, {FloorRecord(-1.5f, 1)}).ok());
  EXPECT_TRUE(Received(b_).empty());
}

TEST_F(FanoutRegionTest, RegionGrowthSendsTheBacklog) {
  Start(true);
  ASSERT_TRUE(manager_->AddTileRegion(b_, Region(lease_b_, 0.5f, 2.5f)).ok());
  Received(a_);
  // A has reported no region yet: everything is withheld from it.
  ASSERT_TRUE(Publish(b_, lease_b_, RightRoomRecords()).ok());
  EXPECT_TRUE(Received(a_).empty());
  EXPECT_EQ(Stats(a_).records_withheld(), 3u);
  // Its region (the left room) brings the one record that reaches it ...
  ASSERT_TRUE(manager_->AddTileRegion(a_, Region(lease_a_, -2.5f, -0.5f)).ok());
  EXPECT_EQ(Received(a_), std::vector<float>({0.6f}));
  EXPECT_EQ(Stats(a_).records_backlog(), 1u);
  // ... and a second region for the same lease is ignored (no backlog, not a violation).
  EXPECT_TRUE(
      absl::IsFailedPrecondition(manager_->AddTileRegion(a_, Region(lease_a_, -2.5f, 2.5f))));
  EXPECT_TRUE(Received(a_).empty());
}

// Every accepted region is answered by a RegionReady after the records that reach it (the
// backlog here), so that a warm-started job's worker can wait for them before the tile; filtered
// or not, and for a region that did not grow.
TEST_F(FanoutRegionTest, RegionReadyFollowsTheRegionsRecords) {
  for (const bool filter : {true, false}) {
    Start(filter);
    Received(a_);
    ASSERT_TRUE(Publish(b_, lease_b_, RightRoomRecords()).ok());
    if (filter) {
      EXPECT_TRUE(Received(a_).empty());
    }
    ASSERT_TRUE(manager_->AddTileRegion(a_, Region(lease_a_, -2.5f, -0.5f)).ok());
    const std::vector<v1::CoordinatorMessage> out =
        manager_->Poll(a_, std::chrono::milliseconds(0));
    ASSERT_FALSE(out.empty()) << "filter " << filter;
    const v1::CoordinatorMessage& last = out.back();
    ASSERT_TRUE(last.has_region_ready()) << "filter " << filter;
    EXPECT_EQ(last.region_ready().job_id(), lease_a_.job_id());
    EXPECT_EQ(last.region_ready().lease_token(), lease_a_.lease_token());
    size_t records = 0, ready = 0;
    for (const v1::CoordinatorMessage& m : out) {
      if (m.has_records()) records += size_t(m.records().batch().origins_size());
      ready += m.has_region_ready();
    }
    EXPECT_EQ(ready, 1u);
    if (filter) {
      EXPECT_EQ(records, 1u);  // the backlog: the record reaching across the divider
    }
  }
}

TEST_F(FanoutRegionTest, MalformedRegionsAreRefused) {
  Start(true);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  v1::TileRegion bad = Region(lease_a_, -2.5f, -0.5f);
  bad.set_min_y(nan);
  v1::TileRegion inverted = Region(lease_a_, 1.0f, -1.0f);
  v1::TileRegion outside = Region(lease_a_, 100.0f, 200.0f);
  v1::TileRegion not_held = Region(lease_a_, -2.5f, -0.5f);
  std::string flipped = lease_a_.lease_token();
  flipped[0] = char(flipped[0] ^ 1);
  not_held.set_lease_token(flipped);
  Received(a_);
  for (const v1::TileRegion& r : {bad, inverted, outside, not_held})
    EXPECT_TRUE(absl::IsPermissionDenied(manager_->AddTileRegion(a_, r)));
  int rejected = 0;
  Received(a_, &rejected);
  EXPECT_EQ(rejected, 4);
  // A huge box is clipped to the scene: the worker then gets the whole job (no more).
  v1::TileRegion huge = Region(lease_a_, -1e30f, 1e30f);
  EXPECT_TRUE(manager_->AddTileRegion(a_, huge).ok());
  ASSERT_TRUE(Publish(b_, lease_b_, RightRoomRecords()).ok());
  EXPECT_EQ(Received(a_).size(), 3u);
}

TEST_F(FanoutRegionTest, UnfilteredSendsEverything) {
  Start(false);
  ASSERT_TRUE(manager_->AddTileRegion(a_, Region(lease_a_, -2.5f, -0.5f)).ok());
  Received(a_);
  ASSERT_TRUE(Publish(b_, lease_b_, RightRoomRecords()).ok());
  EXPECT_EQ(Received(a_).size(), 3u);
  EXPECT_EQ(Stats(a_).records_withheld(), 0u);
  EXPECT_EQ(Stats(a_).records_delivered(), 3u);
}

// The backlog a region brings is fan-out, and bounded like it: 3000 withheld records (168 kB)
// against a 16 KiB outbox bound; A gets what fits and the rest is dropped and counted.
TEST_F(FanoutRegionTest, TheBacklogStaysWithinTheOutboxBound) {
  const size_t kBound = 16 << 10;
  Start(true, kBound);
  Received(a_);
  PublishLeftRoom(3000);
  EXPECT_TRUE(Received(a_).empty());
  EXPECT_EQ(BatchesDropped(a_), 0u);
  ASSERT_TRUE(manager_->AddTileRegion(a_, Region(lease_a_, -2.5f, -0.5f)).ok());
  size_t bytes = 0, records = 0;
  for (const v1::CoordinatorMessage& m : manager_->Poll(a_, std::chrono::milliseconds(0))) {
    if (!m.has_records()) continue;
    bytes += BatchBytes(m.records().batch());
    records += size_t(m.records().batch().origins_size());
  }
  std::printf("MEASURED backlog: %zu records, %zu bytes queued against a bound of %zu\n", records,
              bytes, kBound);
  EXPECT_GT(records, 0u);
  EXPECT_LE(bytes, kBound);
  EXPECT_GT(BatchesDropped(a_), 0u);
}

// A worker that joins a job late gets the job's records so far with its first lease (unfiltered
// fan-out): that copy is bounded too, or a worker that does not read would hold every record of
// the job in its stream's writer. C joins after 3000 records against a 16 KiB bound.
TEST_F(FanoutRegionTest, ALateJoinersCopyStaysWithinTheOutboxBound) {
  const size_t kBound = 16 << 10;
  Start(false, kBound, 24);  // 8 tiles: one left for C
  PublishLeftRoom(3000);
  const uint32_t c = manager_->RegisterWorker("c", "", 1, true);
  size_t bytes = 0, records = 0;
  bool leased = false;
  for (const v1::CoordinatorMessage& m : manager_->Poll(c, std::chrono::milliseconds(0))) {
    leased |= m.has_lease();
    if (!m.has_records()) continue;
    bytes += BatchBytes(m.records().batch());
    records += size_t(m.records().batch().origins_size());
  }
  std::printf("MEASURED late join: %zu records, %zu bytes sent against a bound of %zu\n", records,
              bytes, kBound);
  EXPECT_TRUE(leased);
  EXPECT_GT(records, 0u);
  EXPECT_LE(bytes, kBound);
  EXPECT_GT(BatchesDropped(c), 0u);
}

TEST(RecordReachesBoxTest, DistanceAgainstReach) {
  Bounds3 box;
  box.lo = Vec3(0, 0, 0);
  box.hi = Vec3(1, 1, 1);
  IrradianceRecord r = FloorRecord(2.0f, 10);  // 1 unit from the box; reach 0.1 * 10 = 1
  r.position = Vec3(2, 0.5f, 0.5f);
  EXPECT_TRUE(RecordReachesBox(r, box, 0.1f));
  EXPECT_FALSE(RecordReachesBox(r, box, 0.09f));
  EXPECT_FALSE(RecordReachesBox(r, Bounds3(), 1.0f));  // empty region: nothing
  r.level = 1;                                         // secondary records always pass
  EXPECT_TRUE(RecordReachesBox(r, Bounds3(), 0.01f));
}

}  // namespace
}  // namespace irfarm
