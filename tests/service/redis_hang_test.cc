// A hung Redis (issue 10, part 4), with a real redis-server that is SIGSTOPped while a job runs,
// the coordinator's real services (JobManager on a RedisJobStore behind the gRPC JobService and
// WorkerService on a loopback port) and a real irfarm worker in this process. While Redis is
// stopped for the 30 s (kStopped; 60 call deadlines of 500 ms pass while the worker
// keeps rendering; the whole test took 45-87 s on the shared 2-core machine at load 6):
//   - GetJob and ListJobs of known jobs answer from memory in under 100 ms, measured around
//     each RPC, every 50 ms, while the worker keeps sending tile results the store cannot take:
//     90% of them under 100 ms, and every one under 400 ms. (One that waited for Redis under the
//     coordinator's lock would take the 500 ms call deadline or more; with the old code the
//     slowest took 960 ms. The 90% allows for a loaded machine: measured with the load average
//     at 11 on 2 cores, the slowest of 98 took 113 ms.)
//   - Submit fails with UNAVAILABLE in under 2 s; Cancel of a queued job answers from memory
//     (under 400 ms, the bound of the slowest read; it was 100 ms for this one call, the likeliest
//     of the checks CI's run of 2026-12-02 failed once: its log did not keep which);
//   - no tile counts as done (none could be stored); counted from when /proc shows Redis stopped
//     and 200 ms more, since kill() returns before the stop takes hold and a write Redis was
//     already handed may still be answered (a second candidate for CI's failure of 2026-12-02).
// After SIGCONT the job finishes, and nothing was lost: a second coordinator started on the same
// Redis sees the job SUCCEEDED with every tile and returns the same image, sees the cancelled job
// CANCELLED, and has at least the records the first one merged.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <hiredis/hiredis.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <fstream>
#include <string>
#include <thread>

#include "coordinator/job_manager.h"
#include "coordinator/job_service.h"
#include "coordinator/worker_service.h"
#include "irfarm/v1/jobs.grpc.pb.h"
#include "service/scene_bundle.h"
#include "tests/service/redis_server.h"
#include "worker/worker.h"

namespace irfarm {
namespace {

using Clock = std::chrono::steady_clock;
constexpr std::chrono::seconds kStopped{30};
constexpr std::chrono::milliseconds kRedisTimeout{500};

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

// cornell-box at 64 x 64 in 64 tiles.
v1::SubmitJobRequest Request(int priority) {
  v1::SubmitJobRequest req;
  *req.mutable_scene()->mutable_bundle() =
      *MakeBundle(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml");
  (*req.mutable_settings()->mutable_defines())["resx"] = "64";
  (*req.mutable_settings()->mutable_defines())["resy"] = "64";
  req.mutable_settings()->set_tile_size(8);  // 64 tiles
  req.mutable_settings()->set_share_records(true);
  req.mutable_settings()->set_seed(1);
  req.set_priority(priority);
  return req;
}

class RedisHangTest : public ::testing::Test {
 protected:
  void SetUp() override {
    store_ = redis_.Connect(RedisOptions{"irfarm:", kRedisTimeout});
    ASSERT_TRUE(store_) << "redis-server did not start";
    manager_ = std::move(*JobManager::Create(JobManagerOptions(), store_.get()));
    jobs_ = std::make_unique<JobServiceImpl>(manager_.get());
    workers_ = std::make_unique<WorkerServiceImpl>(manager_.get());
    grpc::ServerBuilder b;
    b.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    b.RegisterService(jobs_.get());
    b.RegisterService(workers_.get());
    server_ = b.BuildAndStart();
    ASSERT_GT(port_, 0);
    stub_ = v1::JobService::NewStub(grpc::CreateChannel("127.0.0.1:" + std::to_string(port_),
                                                        grpc::InsecureChannelCredentials()));
  }
  void TearDown() override {
    redis_.Resume();  // whatever happened, let the teardown writes finish
    if (worker_) {
      worker_->Stop();
      worker_thread_.join();
    }
    if (server_) server_->Shutdown(std::chrono::system_clock::now());
  }
  void StartWorker() {
    WorkerOptions o;
    o.coordinator = "127.0.0.1:" + std::to_string(port_);
    o.name = "w";
    o.threads = 2;
    worker_ = std::make_unique<Worker>(o);
    worker_thread_ = std::thread([this] { worker_->Run(); });
  }
  grpc::Status Submit(const v1::SubmitJobRequest& req, std::string* id = nullptr) {
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
    v1::SubmitJobResponse r;
    grpc::Status st = stub_->SubmitJob(&c, req, &r);
    if (id) *id = r.job().id();
    return st;
  }
  grpc::Status Get(const std::string& id, v1::Job* job) {
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
    v1::GetJobRequest req;
    req.set_job_id(id);
    v1::GetJobResponse r;
    grpc::Status st = stub_->GetJob(&c, req, &r);
    *job = r.job();
    return st;
  }

  RedisServer redis_;
  std::unique_ptr<RedisJobStore> store_;
  std::unique_ptr<JobManager> manager_;
  std::unique_ptr<JobServiceImpl> jobs_;
  std::unique_ptr<WorkerServiceImpl> workers_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  std::unique_ptr<v1::JobService::Stub> stub_;
  std::unique_ptr<Worker> worker_;
  std::thread worker_thread_;
};

TEST_F(RedisHangTest, ReadsAnswerFromMemorySubmitFailsFastAndNothingIsLost) {
  std::string a, b;
  ASSERT_TRUE(Submit(Request(2), &a).ok());
  ASSERT_TRUE(Submit(Request(1), &b).ok());  // lower priority: stays queued behind a
  StartWorker();
  v1::Job job;
  const Clock::time_point wait_end = Clock::now() + std::chrono::seconds(60);
  do {
    ASSERT_TRUE(Get(a, &job).ok());
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  } while (job.tiles_done() < 1 && Clock::now() < wait_end);
  ASSERT_GE(job.tiles_done(), 1u) << "the job never started";

  const Clock::time_point stopped = Clock::now();
  // kill() returns before the stop takes hold: Redis may still answer a write it was handed, and
  // that tile would then count after at_stop below. So: until /proc says it is stopped, then
  // long enough for a reply already sent to be taken in.
  ASSERT_TRUE(redis_.Hang()) << "redis-server did not stop";
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  v1::Job at_stop;
  ASSERT_TRUE(Get(a, &at_stop).ok());
  ASSERT_LT(at_stop.tiles_done(), at_stop.tiles_total()) << "finished before Redis was stopped";

  // Submits while stopped: UNAVAILABLE, each within 2 s.
  double worst_submit_ms = 0;
  for (int i = 0; i < 3; ++i) {
    const Clock::time_point t0 = Clock::now();
    const grpc::Status st = Submit(Request(0));
    const double ms = Ms(Clock::now() - t0);
    worst_submit_ms = std::max(worst_submit_ms, ms);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAVAILABLE) << st.error_message();
  }
  // Cancel of the queued job: answered from memory, written once Redis is back. One call, so it
  // gets the bound of the slowest read (one that waited for Redis would take the 500 ms deadline).
  double cancel_ms = 0;
  {
    const Clock::time_point t0 = Clock::now();
    grpc::ClientContext c;
    v1::CancelJobRequest req;
    req.set_job_id(b);
    v1::CancelJobResponse r;
    EXPECT_TRUE(stub_->CancelJob(&c, req, &r).ok());
    cancel_ms = Ms(Clock::now() - t0);
  }
  // Reads, every 50 ms, for the rest of the stop.
  std::vector<double> get_ms, list_ms;
  while (Clock::now() - stopped < kStopped) {
    Clock::time_point t0 = Clock::now();
    ASSERT_TRUE(Get(a, &job).ok());
    get_ms.push_back(Ms(Clock::now() - t0));
    EXPECT_EQ(job.tiles_done(), at_stop.tiles_done()) << "a tile counted that was not stored";
    t0 = Clock::now();
    grpc::ClientContext c;
    v1::ListJobsResponse list;
    ASSERT_TRUE(stub_->ListJobs(&c, v1::ListJobsRequest(), &list).ok());
    list_ms.push_back(Ms(Clock::now() - t0));
    EXPECT_EQ(list.jobs_size(), 2);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const v1::GetClusterResponse cluster = manager_->Cluster();
  redis_.Resume();
  std::sort(get_ms.begin(), get_ms.end());
  std::sort(list_ms.begin(), list_ms.end());
  ASSERT_GE(get_ms.size(), 20u);
  auto p90 = [](const std::vector<double>& v) { return v[v.size() * 9 / 10]; };
  std::printf(
      "MEASURED Redis stopped %.1f s: %zu GetJob, median %.1f ms, 90%% %.1f ms, slowest %.1f ms; "
      "ListJobs 90%% %.1f ms, slowest %.1f ms; slowest failed Submit %.0f ms; Cancel %.1f ms; "
      "tiles done at stop %u/%u\n",
      Ms(Clock::now() - stopped) / 1000, get_ms.size(), get_ms[get_ms.size() / 2], p90(get_ms),
      get_ms.back(), p90(list_ms), list_ms.back(), worst_submit_ms, cancel_ms, at_stop.tiles_done(),
      at_stop.tiles_total());
  EXPECT_LT(p90(get_ms), 100.0);
  EXPECT_LT(get_ms.back(), 400.0);
  EXPECT_LT(p90(list_ms), 100.0);
  EXPECT_LT(list_ms.back(), 400.0);
  EXPECT_LT(worst_submit_ms, 2000.0);
  EXPECT_LT(cancel_ms, 400.0);
  ASSERT_EQ(cluster.workers_size(), 1);
  EXPECT_FALSE(cluster.workers(0).silent()) << "the worker's stream stalled behind the store";

  // Back: the job finishes, and a new submit works.
  const Clock::time_point finish_end = Clock::now() + std::chrono::seconds(90);
  do {
    ASSERT_TRUE(Get(a, &job).ok());
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  } while (job.state() < v1::JOB_STATE_SUCCEEDED && Clock::now() < finish_end);
  ASSERT_EQ(job.state(), v1::JOB_STATE_SUCCEEDED) << job.error();
  EXPECT_EQ(job.tiles_done(), job.tiles_total());
  std::string c;
  EXPECT_TRUE(Submit(Request(0), &c).ok());
  ASSERT_TRUE(manager_->FlushStore(std::chrono::seconds(10)));
  absl::StatusOr<std::string> image = manager_->ResultExr(a);
  ASSERT_TRUE(image.ok()) << image.status();

  // Nothing lost: a second coordinator on the same Redis.
  std::unique_ptr<RedisJobStore> store2 = redis_.Connect();
  ASSERT_TRUE(store2);
  absl::StatusOr<std::unique_ptr<JobManager>> again =
      JobManager::Create(JobManagerOptions(), store2.get());
  ASSERT_TRUE(again.ok()) << again.status();
  absl::StatusOr<v1::Job> a2 = (*again)->GetJob(a);
  ASSERT_TRUE(a2.ok()) << a2.status();
  EXPECT_EQ(a2->state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(a2->tiles_done(), job.tiles_total());
  EXPECT_GE(a2->records_merged(), job.records_merged());
  absl::StatusOr<std::string> image2 = (*again)->ResultExr(a);
  ASSERT_TRUE(image2.ok()) << image2.status();
  EXPECT_TRUE(*image2 == *image) << "the restored image differs";
  absl::StatusOr<v1::Job> b2 = (*again)->GetJob(b);
  ASSERT_TRUE(b2.ok()) << b2.status();
  EXPECT_EQ(b2->state(), v1::JOB_STATE_CANCELLED);
  EXPECT_EQ((*again)->ListJobs().size(), 3u);
}

// A store on Redis that hangs Redis (SIGSTOP) just before the first PutJob is handed to it: that
// write times out, but stays in Redis's socket and runs when Redis resumes.
class HangAtFirstPutJob final : public JobStore {
 public:
  HangAtFirstPutJob(JobStore* inner, const RedisServer* redis) : inner_(inner), redis_(redis) {}
  absl::StatusOr<uint64_t> NextJobNumber() override { return inner_->NextJobNumber(); }
  absl::Status PutJob(const v1::StoredJob& job) override {
    if (!hung_.exchange(true) && !redis_->Hang())
      return absl::InternalError("redis-server did not stop");
    return inner_->PutJob(job);
  }
  absl::StatusOr<std::vector<v1::StoredJob>> LoadJobs() override { return inner_->LoadJobs(); }
  absl::Status PutTile(const std::string& id, int tile, const std::string& pixels) override {
    return inner_->PutTile(id, tile, pixels);
  }
  absl::StatusOr<std::map<int, std::string>> LoadTiles(const std::string& id) override {
    return inner_->LoadTiles(id);
  }
  absl::Status AppendRecords(const std::string& id,
                             const std::vector<IrradianceRecord>& records) override {
    return inner_->AppendRecords(id, records);
  }
  absl::StatusOr<std::vector<IrradianceRecord>> LoadRecords(const std::string& id) override {
    return inner_->LoadRecords(id);
  }
  absl::Status DeleteJob(const std::string& id) override { return inner_->DeleteJob(id); }
  bool hung() const { return hung_; }

 private:
  JobStore* const inner_;
  const RedisServer* const redis_;
  std::atomic<bool> hung_{false};
};

// A submit refused because its job's write timed out (Redis hung, not down) is not resumed after
// a restart when that write lands later: the coordinator deletes the job once Redis answers
// again, and the delete's tombstone refuses a write that lands later still. Before, the job the
// client was told had failed came back at the next start and rendered.
TEST(RedisLateWriteTest, ARefusedSubmitIsNotResumedWhenItsWriteLandsLater) {
  RedisServer redis;
  std::unique_ptr<RedisJobStore> inner = redis.Connect(RedisOptions{"irfarm:", kRedisTimeout});
  ASSERT_TRUE(inner) << "redis-server did not start";
  HangAtFirstPutJob store(inner.get(), &redis);
  std::unique_ptr<JobManager> manager = std::move(*JobManager::Create(JobManagerOptions(), &store));
  const absl::StatusOr<v1::Job> job = manager->Submit(Request(0));
  redis.Resume();
  ASSERT_TRUE(store.hung());
  EXPECT_EQ(job.status().code(), absl::StatusCode::kUnavailable) << job.status();
  EXPECT_TRUE(manager->ListJobs().empty());
  ASSERT_TRUE(manager->FlushStore(std::chrono::seconds(10))) << "the delete never landed";
  std::unique_ptr<RedisJobStore> store2 = redis.Connect();
  ASSERT_TRUE(store2);
  EXPECT_TRUE(store2->LoadJobs()->empty()) << "the refused job is in the store";
  absl::StatusOr<std::unique_ptr<JobManager>> again =
      JobManager::Create(JobManagerOptions(), store2.get());
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_TRUE((*again)->ListJobs().empty()) << "the refused job resumed";
}

// Redis's job counter went back (evicted under a maxmemory policy, or reset by hand) while the
// tombstone of a job deleted within the day is there: the next submit draws that job's id, whose
// tombstone refuses the write, and takes the next id instead (it failed UNAVAILABLE "was deleted").
TEST(RedisLateWriteTest, ASubmitSkipsTheIdOfAJobDeletedToday) {
  RedisServer redis;
  std::unique_ptr<RedisJobStore> store = redis.Connect(RedisOptions{"irfarm:", kRedisTimeout});
  ASSERT_TRUE(store) << "redis-server did not start";
  std::unique_ptr<JobManager> manager =
      std::move(*JobManager::Create(JobManagerOptions(), store.get()));
  const absl::StatusOr<v1::Job> first = manager->Submit(Request(0));
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_TRUE(manager->Cancel(first->id()).ok());
  ASSERT_TRUE(manager->FlushStore(std::chrono::seconds(10)));
  ASSERT_TRUE(manager->Delete(first->id()).ok());
  redisContext* c = redisConnect("127.0.0.1", redis.port());
  ASSERT_TRUE(c != nullptr && c->err == 0);
  freeReplyObject(redisCommand(c, "SET irfarm:job_counter 0"));
  redisFree(c);
  const absl::StatusOr<v1::Job> next = manager->Submit(Request(0));
  ASSERT_TRUE(next.ok()) << next.status();
  EXPECT_NE(next->id(), first->id());
  std::printf("MEASURED deleted %s; after the counter was reset the submit took %s\n",
              first->id().c_str(), next->id().c_str());
}

}  // namespace
}  // namespace irfarm
