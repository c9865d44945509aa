// Job retention (issue 11, part 6) against a real redis-server: finished jobs past --job-ttl, or
// beyond --max-finished-jobs, are gone from the coordinator's memory and from Redis (job, tiles,
// records, set membership) while live jobs stay; DeleteJob removes a finished job of its owner
// only; and a restart on a Redis holding 1,000 expired jobs (each with tiles and records) deletes
// them unread and starts in under a second, loading only the live job.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "coordinator/job_manager.h"
#include "coordinator/redis_job_store.h"
#include "service/scene_bundle.h"
#include "tests/service/redis_server.h"

namespace irfarm {
namespace {

const std::string kScene = std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml";

v1::SubmitJobRequest SmallJob() {
  v1::SubmitJobRequest req;
  *req.mutable_scene()->mutable_bundle() = *MakeBundle(kScene);
  (*req.mutable_settings()->mutable_defines())["resx"] = "32";
  (*req.mutable_settings()->mutable_defines())["resy"] = "32";
  req.mutable_settings()->set_tile_size(16);  // 4 tiles
  return req;
}

std::vector<IrradianceRecord> SomeRecords(int n) {
  std::vector<IrradianceRecord> out(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    out[size_t(i)].position = Vec3(0.01f * float(i), 0.5f, 0.0f);
    out[size_t(i)].normal = Vec3(0, 1, 0);
    out[size_t(i)].irradiance = Vec3(1, 1, 1);
    out[size_t(i)].radius = 0.1f;
  }
  return out;
}

std::vector<v1::StoredJob> StoredJobs(JobStore* store) {
  absl::StatusOr<std::vector<v1::StoredJob>> jobs = store->LoadJobs();
  EXPECT_TRUE(jobs.ok()) << jobs.status();
  return jobs.ok() ? std::move(*jobs) : std::vector<v1::StoredJob>();
}

// True when the store holds anything of job `id`: in the job set, its tiles or its records.
bool InStore(JobStore* store, const std::string& id) {
  const std::vector<v1::StoredJob> jobs = StoredJobs(store);
  for (const v1::StoredJob& j : jobs)
    if (j.job().id() == id) return true;
  return !store->LoadTiles(id)->empty() || !store->LoadRecords(id)->empty();
}

class RetentionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    store_ = redis_.Connect();
    ASSERT_TRUE(store_) << "redis-server did not start";
  }
  std::unique_ptr<JobManager> Manager(std::chrono::milliseconds ttl, int max_finished) {
    JobManagerOptions o;
    o.job_ttl = ttl;
    o.max_finished_jobs = max_finished;
    return std::move(*JobManager::Create(o, store_.get()));
  }
  // Submits a job and gives it tiles and records in the store, as a rendered job has.
  std::string SubmitWithData(JobManager* m, const Caller& caller = Caller()) {
    absl::StatusOr<v1::Job> job = m->Submit(SmallJob(), caller);
    EXPECT_TRUE(job.ok()) << job.status();
    EXPECT_TRUE(store_->PutTile(job->id(), 0, std::string(16 * 16 * 3 * 4, '\0')).ok());
    EXPECT_TRUE(store_->AppendRecords(job->id(), SomeRecords(10)).ok());
    return job->id();
  }

  RedisServer redis_;
  std::unique_ptr<RedisJobStore> store_;
};

TEST_F(RetentionTest, JobsPastTheirTtlAreGoneFromMemoryAndRedis) {
  std::unique_ptr<JobManager> m = Manager(std::chrono::milliseconds(400), 0);
  const std::string done = SubmitWithData(m.get()), live = SubmitWithData(m.get());
  ASSERT_TRUE(m->Cancel(done).ok());
  EXPECT_EQ(m->ExpireJobs(), 0);  // finished just now: within its TTL
  EXPECT_TRUE(m->GetJob(done).ok());
  EXPECT_TRUE(InStore(store_.get(), done));
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_EQ(m->ExpireJobs(), 1);
  EXPECT_TRUE(absl::IsNotFound(m->GetJob(done).status()));
  EXPECT_FALSE(InStore(store_.get(), done)) << "job, tiles or records left in Redis";
  // The live job stays however old it is, with its data.
  EXPECT_TRUE(m->GetJob(live).ok());
  EXPECT_TRUE(InStore(store_.get(), live));
  EXPECT_EQ(store_->LoadTiles(live)->size(), 1u);
  // A restart sees the same.
  m.reset();
  std::unique_ptr<JobManager> again = Manager(std::chrono::milliseconds(400), 0);
  ASSERT_EQ(again->ListJobs().size(), 1u);
  EXPECT_EQ(again->ListJobs()[0].id(), live);
}

TEST_F(RetentionTest, OnlyTheNewestFinishedJobsAreKept) {
  std::unique_ptr<JobManager> m = Manager(std::chrono::milliseconds(0), 2);
  std::vector<std::string> ids;
  for (int i = 0; i < 4; ++i) ids.push_back(SubmitWithData(m.get()));
  for (int i = 0; i < 3; ++i) {  // finish 0, 1, 2 in this order; 3 stays queued
    ASSERT_TRUE(m->Cancel(ids[size_t(i)]).ok());
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // distinct finish times (ms)
  }
  EXPECT_EQ(m->ExpireJobs(), 1);
  EXPECT_TRUE(absl::IsNotFound(m->GetJob(ids[0]).status())) << "the oldest finished job stays";
  EXPECT_FALSE(InStore(store_.get(), ids[0]));
  for (int i = 1; i < 4; ++i) EXPECT_TRUE(m->GetJob(ids[size_t(i)]).ok()) << ids[size_t(i)];
}

TEST_F(RetentionTest, DeleteRemovesAFinishedJobOfItsOwnerOnly) {
  std::unique_ptr<JobManager> m = Manager(std::chrono::milliseconds(0), 0);
  const Caller alice{"alice", false}, bob{"bob", false};
  const std::string id = SubmitWithData(m.get(), alice);
  EXPECT_TRUE(absl::IsFailedPrecondition(m->Delete(id, alice))) << "a queued job was deleted";
  ASSERT_TRUE(m->Cancel(id, alice).ok());
  EXPECT_TRUE(absl::IsNotFound(m->Delete(id, bob))) << "another client deleted it";
  EXPECT_TRUE(InStore(store_.get(), id));
  EXPECT_TRUE(m->Delete(id, alice).ok());
  EXPECT_TRUE(absl::IsNotFound(m->GetJob(id, alice).status()));
  EXPECT_FALSE(InStore(store_.get(), id));
  EXPECT_TRUE(absl::IsNotFound(m->Delete(id, alice)));
}

TEST_F(RetentionTest, RestartWithAThousandExpiredJobsStartsInUnderASecond) {
  constexpr int kExpired = 1000;
  std::string live;
  v1::StoredJob model;
  {
    std::unique_ptr<JobManager> m = Manager(std::chrono::milliseconds(0), 0);
    live = SubmitWithData(m.get());
    for (const v1::StoredJob& j : StoredJobs(store_.get()))
      if (j.job().id() == live) model = j;
  }
  // 1,000 jobs that finished two days ago, each with its 4 tiles (3 KB each) and 100 records:
  // what a farm's Redis holds after a few days of frames.
  const int64_t two_days_ago =
      std::chrono::duration_cast<std::chrono::milliseconds>(
          (std::chrono::system_clock::now() - std::chrono::hours(48)).time_since_epoch())
          .count();
  const std::string tile(16 * 16 * 3 * 4, '\0');
  const std::vector<IrradianceRecord> records = SomeRecords(100);
  for (int i = 0; i < kExpired; ++i) {
    v1::StoredJob s = model;
    const std::string id = "old-" + std::to_string(i);
    s.mutable_job()->set_id(id);
    s.mutable_scene()->set_path("/scenes/a/scene.xml");
    s.mutable_job()->set_state(v1::JOB_STATE_SUCCEEDED);
    s.set_finished_unix_ms(two_days_ago);
    ASSERT_TRUE(store_->PutJob(s).ok());
    for (int t = 0; t < 4; ++t) ASSERT_TRUE(store_->PutTile(id, t, tile).ok());
    ASSERT_TRUE(store_->AppendRecords(id, records).ok());
  }
  ASSERT_EQ(StoredJobs(store_.get()).size(), size_t(kExpired + 1));

  // For comparison, a restart without retention reads every job with its tiles and records.
  auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(Manager(std::chrono::milliseconds(0), 0)->ListJobs().size(), size_t(kExpired + 1));
  std::printf("MEASURED restart loading all %d + 1 jobs (no retention): %.3f s\n", kExpired,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  start = std::chrono::steady_clock::now();
  std::unique_ptr<JobManager> m = Manager(std::chrono::hours(24), 1000);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("MEASURED restart with %d expired jobs in Redis (deleted unread): %.3f s\n", kExpired,
              seconds);
  EXPECT_LT(seconds, 1.0);
  ASSERT_EQ(m->ListJobs().size(), 1u);
  EXPECT_EQ(m->ListJobs()[0].id(), live);
  EXPECT_EQ(StoredJobs(store_.get()).size(), 1u);
  for (int i : {0, 499, 999}) EXPECT_FALSE(InStore(store_.get(), "old-" + std::to_string(i)));
}

}  // namespace
}  // namespace irfarm
