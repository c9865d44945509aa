// One test suite run against both JobStore implementations: InMemoryJobStore, and RedisJobStore
// on a real redis-server started here on a free 127.0.0.1 port with a temp dir (and stopped).
#include <gtest/gtest.h>
#include <hiredis/hiredis.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <thread>
#include <vector>

#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"
#include "coordinator/redis_job_store.h"
#include "coordinator/store_writer.h"
#include "service/record_codec.h"
#include "service/scene_bundle.h"
#include "tests/service/redis_server.h"

namespace irfarm {
namespace {

// cornell-box at 32 x 32, as a client submits it.
v1::SubmitJobRequest CornellRequest() {
  v1::SubmitJobRequest req;
  *req.mutable_scene()->mutable_bundle() =
      *MakeBundle(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml");
  (*req.mutable_settings()->mutable_defines())["resx"] = "32";
  (*req.mutable_settings()->mutable_defines())["resy"] = "32";
  return req;
}

class JobStoreTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "memory") {
      store_ = std::make_unique<InMemoryJobStore>();
      return;
    }
    redis_ = std::make_unique<RedisServer>();
    for (int i = 0; i < 100 && !store_; ++i) {
      absl::StatusOr<std::unique_ptr<RedisJobStore>> s = RedisJobStore::Connect(redis_->address());
      if (s.ok()) {
        store_ = std::move(*s);
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    }
    ASSERT_TRUE(store_) << "redis-server did not start";
  }
  std::unique_ptr<RedisServer> redis_;
  std::unique_ptr<JobStore> store_;
};

TEST_P(JobStoreTest, JobNumbersCountUp) {
  EXPECT_EQ(*store_->NextJobNumber(), 1u);
  EXPECT_EQ(*store_->NextJobNumber(), 2u);
}

TEST_P(JobStoreTest, JobsRoundTripAndReplace) {
  v1::StoredJob job;
  job.mutable_job()->set_id("job-1");
  job.mutable_job()->set_state(v1::JOB_STATE_QUEUED);
  job.mutable_scene()->set_path("/x/scene.xml");
  ASSERT_TRUE(store_->PutJob(job).ok());
  job.mutable_job()->set_state(v1::JOB_STATE_RUNNING);
  ASSERT_TRUE(store_->PutJob(job).ok());
  std::vector<v1::StoredJob> jobs = *store_->LoadJobs();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job().state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(jobs[0].scene().path(), "/x/scene.xml");
}

// A state change (the job without its scene, StateOnly) keeps the scene stored with the submit;
// a finished job's emptied bundle replaces it.
TEST_P(JobStoreTest, AStateChangeKeepsTheStoredScene) {
  v1::StoredJob job;
  job.mutable_job()->set_id("job-1");
  job.mutable_job()->set_state(v1::JOB_STATE_QUEUED);
  v1::BundleFile* f = job.mutable_scene()->mutable_bundle()->add_files();
  f->set_path("scene.xml");
  f->set_content(std::string(1 << 20, 'x'));
  // An unfinished job's state change before any scene was stored writes nothing.
  const absl::Status early = store_->PutJob(StateOnly(job));
  EXPECT_TRUE(IsSceneMissing(early)) << early;
  EXPECT_TRUE(store_->LoadJobs()->empty());
  // A finished job's state needs none.
  v1::StoredJob finished;
  finished.mutable_job()->set_id("job-2");
  finished.mutable_job()->set_state(v1::JOB_STATE_CANCELLED);
  ASSERT_TRUE(store_->PutJob(finished).ok());
  ASSERT_TRUE(store_->DeleteJob("job-2").ok());
  ASSERT_TRUE(store_->PutJob(job).ok());
  v1::StoredJob state = StateOnly(job);
  EXPECT_FALSE(state.has_scene());
  ASSERT_EQ(job.scene().bundle().files_size(), 1);  // the job keeps its scene
  EXPECT_EQ(job.scene().bundle().files(0).content().size(), size_t(1) << 20);
  state.mutable_job()->set_state(v1::JOB_STATE_RUNNING);
  ASSERT_TRUE(store_->PutJob(state).ok());
  std::vector<v1::StoredJob> jobs = *store_->LoadJobs();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job().state(), v1::JOB_STATE_RUNNING);
  ASSERT_EQ(jobs[0].scene().bundle().files_size(), 1);
  EXPECT_EQ(jobs[0].scene().bundle().files(0).content(), std::string(1 << 20, 'x'));
  job.mutable_job()->set_state(v1::JOB_STATE_SUCCEEDED);
  job.mutable_scene()->mutable_bundle()->mutable_files(0)->clear_content();
  ASSERT_TRUE(store_->PutJob(job).ok());
  jobs = *store_->LoadJobs();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job().state(), v1::JOB_STATE_SUCCEEDED);
  ASSERT_EQ(jobs[0].scene().bundle().files_size(), 1);
  EXPECT_TRUE(jobs[0].scene().bundle().files(0).content().empty());
}

TEST_P(JobStoreTest, TilesAndRecordsRoundTrip) {
  v1::StoredJob job;
  job.mutable_job()->set_id("job-1");
  job.mutable_scene()->set_path("/scenes/a/scene.xml");
  ASSERT_TRUE(store_->PutJob(job).ok());
  ASSERT_TRUE(store_->PutTile("job-1", 3, std::string("\0\1\2", 3)).ok());
  ASSERT_TRUE(store_->PutTile("job-1", 5, "abc").ok());
  std::map<int, std::string> tiles = *store_->LoadTiles("job-1");
  ASSERT_EQ(tiles.size(), 2u);
  EXPECT_EQ(tiles[3], std::string("\0\1\2", 3));
  EXPECT_TRUE(store_->LoadTiles("job-2")->empty());
  IrradianceRecord r;
  r.position = Vec3(1, 2, 3);
  r.normal = Vec3(0, 0, 1);
  r.irradiance = Vec3(0.5f);
  r.radius = 0.25f;
  r.origin = 7;
  ASSERT_TRUE(store_->AppendRecords("job-1", {r, r}).ok());
  r.origin = 8;
  ASSERT_TRUE(store_->AppendRecords("job-1", {r}).ok());
  std::vector<IrradianceRecord> recs = *store_->LoadRecords("job-1");
  ASSERT_EQ(recs.size(), 3u);
  EXPECT_EQ(recs[0].origin, 7u);
  EXPECT_EQ(recs[2].origin, 8u);
  EXPECT_EQ(recs[1].position.y, 2.0f);
}

// A tile or record batch that arrives after its job was deleted (a worker's result stored while a
// client deleted the cancelled job; a write that timed out while Redis hung and lands later) is
// refused NOT_FOUND and leaves nothing behind: it recreated the job's tile hash and record list
// before, which nothing ever read or deleted again. In Redis a deleted job cannot be put back
// either (its tombstone).
TEST_P(JobStoreTest, WritesForAJobNotStoredAreRefused) {
  IrradianceRecord r;
  r.normal = Vec3(0, 0, 1);
  r.irradiance = Vec3(0.5f);
  r.radius = 0.25f;
  EXPECT_TRUE(absl::IsNotFound(store_->PutTile("job-9", 0, "abc")));
  EXPECT_TRUE(absl::IsNotFound(store_->AppendRecords("job-9", {r})));
  v1::StoredJob job;
  job.mutable_job()->set_id("job-9");
  job.mutable_scene()->set_path("/scenes/a/scene.xml");
  ASSERT_TRUE(store_->PutJob(job).ok());
  ASSERT_TRUE(store_->PutTile("job-9", 0, "abc").ok());
  ASSERT_TRUE(store_->AppendRecords("job-9", {r}).ok());
  ASSERT_TRUE(store_->DeleteJob("job-9").ok());
  EXPECT_TRUE(absl::IsNotFound(store_->PutTile("job-9", 1, "def")));
  EXPECT_TRUE(absl::IsNotFound(store_->AppendRecords("job-9", {r, r})));
  EXPECT_TRUE(store_->LoadTiles("job-9")->empty());
  EXPECT_TRUE(store_->LoadRecords("job-9")->empty());
  if (GetParam() != "redis") return;
  job.mutable_job()->set_state(v1::JOB_STATE_CANCELLED);
  const absl::Status late = store_->PutJob(job);
  EXPECT_TRUE(absl::IsNotFound(late)) << late;
  EXPECT_NE(late.message().find("job-9 was deleted"), std::string::npos) << late;
  EXPECT_TRUE(store_->LoadJobs()->empty());
  // What is left in Redis is the tombstone, for a day.
  redisContext* c = redisConnect("127.0.0.1", redis_->port());
  ASSERT_TRUE(c != nullptr && c->err == 0);
  auto* keys = static_cast<redisReply*>(redisCommand(c, "KEYS *"));
  ASSERT_TRUE(keys != nullptr);
  ASSERT_EQ(keys->elements, 1u);
  EXPECT_EQ(std::string(keys->element[0]->str), "irfarm:deleted:job-9");
  freeReplyObject(keys);
  auto* ttl = static_cast<redisReply*>(redisCommand(c, "TTL irfarm:deleted:job-9"));
  ASSERT_TRUE(ttl != nullptr);
  EXPECT_GT(ttl->integer, 86000);
  EXPECT_LE(ttl->integer, 86400);
  freeReplyObject(ttl);
  redisFree(c);
}

INSTANTIATE_TEST_SUITE_P(Stores, JobStoreTest, ::testing::Values("memory", "redis"));

// The store writer drops a queued write the store refuses NOT_FOUND (its job was deleted) after
// one try; it retried it at the head of its queue forever before, holding up every later write.
TEST(StoreWriterTest, AWriteForADeletedJobIsDroppedNotRetried) {
  InMemoryJobStore store;
  StoreWriter writer(&store, std::chrono::milliseconds(20));
  IrradianceRecord r;
  r.normal = Vec3(0, 0, 1);
  r.radius = 0.25f;
  v1::StoredJob job;
  job.mutable_job()->set_id("job-2");
  job.mutable_scene()->set_path("/scenes/a/scene.xml");
  writer.AppendRecords("job-1", {r});  // never stored
  writer.PutJob(job);
  writer.AppendRecords("job-2", {r, r});
  ASSERT_TRUE(writer.Flush(std::chrono::seconds(5))) << "the refused write is retried";
  EXPECT_EQ(store.LoadRecords("job-2")->size(), 2u);
}

// While Redis hangs the writer holds its queue; a state change queued behind the submit-like
// write of the same job replaces it (one state per job) but keeps that write's scene, which lands
// once Redis answers.
TEST(StoreWriterTest, AStateChangeReplacingAQueuedWriteKeepsItsScene) {
  RedisServer redis;
  RedisOptions options;
  options.timeout = std::chrono::milliseconds(200);
  absl::StatusOr<std::unique_ptr<RedisJobStore>> store;
  for (int i = 0; i < 100 && !(store.ok() && *store); ++i) {
    store = RedisJobStore::Connect(redis.address(), options);
    if (!store.ok()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_TRUE(store.ok()) << store.status();
  StoreWriter writer(store->get(), std::chrono::milliseconds(20));
  ASSERT_TRUE(redis.Hang());
  v1::StoredJob other;
  other.mutable_job()->set_id("job-1");
  other.mutable_scene()->set_path("/scenes/a/scene.xml");
  writer.PutJob(other);  // taken by the writer, stuck until Redis answers
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  v1::StoredJob job;
  job.mutable_job()->set_id("job-2");
  job.mutable_job()->set_state(v1::JOB_STATE_QUEUED);
  job.mutable_scene()->set_path("/scenes/a/scene.xml");
  writer.PutJob(job);
  v1::StoredJob running = StateOnly(job);
  running.mutable_job()->set_state(v1::JOB_STATE_RUNNING);
  writer.PutJob(running);
  EXPECT_EQ(writer.pending(), 2u);  // job-1's write, and one of job-2
  redis.Resume();
  ASSERT_TRUE(writer.Flush(std::chrono::seconds(10)));
  std::vector<v1::StoredJob> jobs = *(*store)->LoadJobs();
  ASSERT_EQ(jobs.size(), 2u);
  const v1::StoredJob& j2 = jobs[0].job().id() == "job-2" ? jobs[0] : jobs[1];
  EXPECT_EQ(j2.job().state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(j2.scene().path(), "/scenes/a/scene.xml");
}

TEST(RedisJobStoreTest, RedisDownIsUnavailable) {
  absl::StatusOr<std::unique_ptr<RedisJobStore>> s =
      RedisJobStore::Connect("127.0.0.1:" + std::to_string(FreePort()));
  EXPECT_EQ(s.status().code(), absl::StatusCode::kUnavailable);
}

// A worker's records count (are merged and fanned out) only once the store holds them: with
// Redis gone, a batch is refused UNAVAILABLE and the job's merged count does not move, so memory
// and store never disagree (issue 10, part 4).
TEST(RedisRecordsTest, RecordsAreMergedOnlyOnceStored) {
  auto redis = std::make_unique<RedisServer>();
  std::unique_ptr<RedisJobStore> store;
  for (int i = 0; i < 100 && !store; ++i) {
    absl::StatusOr<std::unique_ptr<RedisJobStore>> s = RedisJobStore::Connect(redis->address());
    if (s.ok()) {
      store = std::move(*s);
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  ASSERT_TRUE(store) << "redis-server did not start";
  std::unique_ptr<JobManager> manager =
      std::move(*JobManager::Create(JobManagerOptions(), store.get()));
  absl::StatusOr<v1::Job> job = manager->Submit(CornellRequest());
  ASSERT_TRUE(job.ok()) << job.status();
  const uint32_t worker = manager->RegisterWorker("w");
  bool leased = false;
  for (const v1::CoordinatorMessage& m : manager->Poll(worker, std::chrono::seconds(1)))
    leased = leased || m.has_lease();
  ASSERT_TRUE(leased);
  v1::JobRecords batch;
  batch.set_job_id(job->id());
  IrradianceRecord r;
  r.normal = Vec3(0, 1, 0);
  r.irradiance = Vec3(0.5f);
  r.radius = 0.1f;
  PackRecords({r, r}, worker, batch.mutable_batch());
  ASSERT_TRUE(manager->AddRecords(worker, batch).ok());
  EXPECT_EQ(manager->GetJob(job->id())->records_merged(), 2u);
  redis.reset();  // SIGKILL
  EXPECT_EQ(manager->AddRecords(worker, batch).code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(manager->GetJob(job->id())->records_merged(), 2u);
}

}  // namespace
}  // namespace irfarm

namespace irfarm {
namespace {

// Runs one raw command on a fresh connection to `address` (the damage a test does by hand, or a
// look at what is stored); returns the reply's string or integer as text ("" for nil).
std::string RawRedis(const RedisServer& redis, const std::vector<std::string>& argv) {
  redisContext* c = redisConnect("127.0.0.1", std::stoi(redis.address().substr(10)));
  EXPECT_TRUE(c != nullptr && c->err == 0);
  if (c == nullptr || c->err != 0) return "";
  std::vector<const char*> args;
  std::vector<size_t> lens;
  for (const std::string& a : argv) {
    args.push_back(a.data());
    lens.push_back(a.size());
  }
  redisReply* r =
      static_cast<redisReply*>(redisCommandArgv(c, int(args.size()), args.data(), lens.data()));
  EXPECT_NE(r, nullptr);
  std::string out;
  if (r != nullptr && (r->type == REDIS_REPLY_STRING || r->type == REDIS_REPLY_STATUS))
    out.assign(r->str, r->len);
  if (r != nullptr && r->type == REDIS_REPLY_INTEGER) out = std::to_string(r->integer);
  if (r != nullptr) freeReplyObject(r);
  redisFree(c);
  return out;
}

// Stores `job` as a coordinator before the scene had a key of its own did (the scene, if any,
// inside the job's key), listed in the job set.
void StoreRawJob(const RedisServer& redis, const v1::StoredJob& job) {
  RawRedis(redis, {"SET", "irfarm:job:" + job.job().id(), job.SerializeAsString()});
  RawRedis(redis, {"SADD", "irfarm:jobs", job.job().id()});
}

// Bytes Redis has read from its clients so far (INFO stats: total_net_input_bytes).
long long RedisInputBytes(const RedisServer& redis) {
  const std::string info = RawRedis(redis, {"INFO", "stats"});
  const std::string key = "total_net_input_bytes:";
  const size_t at = info.find(key);
  EXPECT_NE(at, std::string::npos);
  return at == std::string::npos ? -1 : std::stoll(info.substr(at + key.size()));
}

// A real redis-server and a store on it, for the tests of where a job's scene is kept.
class RedisSceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    store_ = redis_.Connect();
    ASSERT_TRUE(store_) << "redis-server did not start";
  }
  // A stored job with a scene given by path.
  static v1::StoredJob Job(const std::string& id, v1::JobState state, const std::string& path) {
    v1::StoredJob job;
    job.mutable_job()->set_id(id);
    job.mutable_job()->set_state(state);
    job.mutable_scene()->set_path(path);
    return job;
  }
  // A coordinator on the store, and a worker of it taking a tile (the job starts).
  std::unique_ptr<JobManager> Manager() {
    return std::move(*JobManager::Create(JobManagerOptions(), store_.get()));
  }
  static bool LeaseOne(JobManager& manager) {
    const uint32_t worker = manager.RegisterWorker("w");
    bool leased = false;
    for (const v1::CoordinatorMessage& m : manager.Poll(worker, std::chrono::seconds(1)))
      leased = leased || m.has_lease();
    return leased;
  }
  RedisServer redis_;
  std::unique_ptr<RedisJobStore> store_;
};

// A job whose upload is large (a 4 MiB file beside cornell-box): starting it and changing its
// priority write its state, not the upload again (before, each state change sent Redis the whole
// bundle and copied it under the coordinator's lock); a coordinator started later on the same
// Redis resumes it with the upload as submitted.
TEST_F(RedisSceneTest, StateChangesDoNotWriteTheUploadAgain) {
  v1::SubmitJobRequest req = CornellRequest();
  std::string big(size_t(4) << 20, '\0');
  for (size_t i = 0; i < big.size(); ++i) big[i] = char((i * 2654435761u) >> 24);
  v1::BundleFile* extra = req.mutable_scene()->mutable_bundle()->add_files();
  extra->set_path("textures/big.bin");
  extra->set_content(big);
  std::string id;
  {
    std::unique_ptr<JobManager> manager = Manager();
    absl::StatusOr<v1::Job> job = manager->Submit(req);
    ASSERT_TRUE(job.ok()) << job.status();
    id = job->id();
    const long long before = RedisInputBytes(redis_);
    ASSERT_TRUE(LeaseOne(*manager));
    ASSERT_TRUE(manager->SetPriority(id, 7).ok());
    ASSERT_TRUE(manager->FlushStore(std::chrono::seconds(5)));
    EXPECT_EQ(manager->GetJob(id)->state(), v1::JOB_STATE_RUNNING);
    const long long sent = RedisInputBytes(redis_) - before;
    std::printf("MEASURED start + priority change sent Redis %lld bytes (upload %zu)\n", sent,
                big.size());
    EXPECT_GT(sent, 0);
    EXPECT_LT(sent, 256 << 10);  // two state writes, not two 4 MiB uploads
    EXPECT_LT(std::stoll(RawRedis(redis_, {"STRLEN", "irfarm:job:" + id})), 64 << 10);
    EXPECT_GT(std::stoll(RawRedis(redis_, {"STRLEN", "irfarm:job:" + id + ":scene"})),
              (4 << 20) - 1);
  }
  absl::StatusOr<std::unique_ptr<JobManager>> again =
      JobManager::Create(JobManagerOptions(), store_.get());
  ASSERT_TRUE(again.ok()) << again.status();
  absl::StatusOr<v1::Job> job = (*again)->GetJob(id);
  ASSERT_TRUE(job.ok()) << job.status();
  EXPECT_EQ(job->state(), v1::JOB_STATE_QUEUED);  // resumed: queued until a worker takes a tile
  EXPECT_EQ(job->priority(), 7);
  std::vector<v1::StoredJob> stored = *store_->LoadJobs();
  ASSERT_EQ(stored.size(), 1u);
  const v1::SceneBundle& bundle = stored[0].scene().bundle();
  ASSERT_EQ(bundle.files_size(), req.scene().bundle().files_size());
  for (int k = 0; k < bundle.files_size(); ++k) {
    EXPECT_EQ(bundle.files(k).path(), req.scene().bundle().files(k).path());
    EXPECT_EQ(bundle.files(k).content(), req.scene().bundle().files(k).content());
  }
}

// Redis loses its data (FLUSHALL) while a job is queued: the state change of its start, which
// carries no scene, is refused by the store (it would bring the job back without one, and a
// coordinator started later would drop it), and the writer writes the state again with the scene
// the coordinator holds. A later coordinator resumes the job with its whole upload.
TEST_F(RedisSceneTest, AStateChangeAfterRedisLostItsDataWritesTheSceneAgain) {
  // The store alone: nothing is written, and the caller is told why.
  v1::StoredJob bare = Job("job-9", v1::JOB_STATE_QUEUED, "/scenes/a/scene.xml");
  ASSERT_TRUE(store_->PutJob(bare).ok());
  RawRedis(redis_, {"FLUSHALL"});
  const absl::Status refused = store_->PutJob(StateOnly(bare));
  EXPECT_TRUE(IsSceneMissing(refused)) << refused;
  EXPECT_TRUE(store_->LoadJobs()->empty());
  // Through the coordinator.
  const v1::SubmitJobRequest req = CornellRequest();
  std::string id;
  {
    std::unique_ptr<JobManager> manager = Manager();
    absl::StatusOr<v1::Job> job = manager->Submit(req);
    ASSERT_TRUE(job.ok()) << job.status();
    id = job->id();
    RawRedis(redis_, {"FLUSHALL"});
    ASSERT_TRUE(LeaseOne(*manager));
    ASSERT_TRUE(manager->FlushStore(std::chrono::seconds(5)));
    EXPECT_EQ(RawRedis(redis_, {"EXISTS", "irfarm:job:" + id + ":scene"}), "1");
    // Only the scene's key evicted (the job still in the set): the next state change writes it.
    RawRedis(redis_, {"DEL", "irfarm:job:" + id + ":scene"});
    ASSERT_TRUE(manager->SetPriority(id, 3).ok());
    ASSERT_TRUE(manager->FlushStore(std::chrono::seconds(5)));
    EXPECT_EQ(RawRedis(redis_, {"EXISTS", "irfarm:job:" + id + ":scene"}), "1");
  }
  absl::StatusOr<std::unique_ptr<JobManager>> again =
      JobManager::Create(JobManagerOptions(), store_.get());
  ASSERT_TRUE(again.ok()) << again.status();
  ASSERT_TRUE((*again)->GetJob(id).ok()) << "the job was not resumed";
  std::vector<v1::StoredJob> stored = *store_->LoadJobs();
  ASSERT_EQ(stored.size(), 1u);
  EXPECT_EQ(stored[0].scene().SerializeAsString(), req.scene().SerializeAsString());
}

// A finished job's state needs no scene: a coordinator that finds a succeeded job's tiles and its
// scene lost (both evicted) fails it at start-up, and the FAILED state is written (a state change
// refused for want of a scene would leave it SUCCEEDED, failed again at every start).
TEST_F(RedisSceneTest, AFinishedJobsStateIsWrittenWithoutAScene) {
  v1::StoredJob done = Job("job-3", v1::JOB_STATE_SUCCEEDED, "");
  done.clear_scene();
  done.mutable_job()->set_width(32);
  done.mutable_job()->set_height(32);
  StoreRawJob(redis_, done);  // no tiles, no scene key
  {
    std::unique_ptr<JobManager> manager = Manager();
    absl::StatusOr<v1::Job> job = manager->GetJob("job-3");
    ASSERT_TRUE(job.ok()) << job.status();
    EXPECT_EQ(job->state(), v1::JOB_STATE_FAILED);
    ASSERT_TRUE(manager->FlushStore(std::chrono::seconds(5)));
  }
  v1::StoredJob in_key;
  ASSERT_TRUE(in_key.ParseFromString(RawRedis(redis_, {"GET", "irfarm:job:job-3"})));
  EXPECT_EQ(in_key.job().state(), v1::JOB_STATE_FAILED);
}

// A job stored before the scene had a key of its own (the scene inside the job's key) loads with
// its scene, is moved to the two keys, and keeps its scene through a later state change.
TEST_F(RedisSceneTest, AJobStoredWithItsSceneInsideIsMoved) {
  const v1::StoredJob old = Job("job-5", v1::JOB_STATE_QUEUED, "/scenes/room/scene.xml");
  StoreRawJob(redis_, old);
  std::vector<v1::StoredJob> jobs = *store_->LoadJobs();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].scene().path(), "/scenes/room/scene.xml");
  v1::StoredJob in_key;
  ASSERT_TRUE(in_key.ParseFromString(RawRedis(redis_, {"GET", "irfarm:job:job-5"})));
  EXPECT_FALSE(in_key.has_scene());
  EXPECT_EQ(in_key.job().id(), "job-5");
  v1::SceneSource scene;
  ASSERT_TRUE(scene.ParseFromString(RawRedis(redis_, {"GET", "irfarm:job:job-5:scene"})));
  EXPECT_EQ(scene.path(), "/scenes/room/scene.xml");
  v1::StoredJob running = StateOnly(jobs[0]);
  running.mutable_job()->set_state(v1::JOB_STATE_RUNNING);
  ASSERT_TRUE(store_->PutJob(running).ok());
  jobs = *store_->LoadJobs();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job().state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(jobs[0].scene().path(), "/scenes/room/scene.xml");
  // Deleting the job removes the scene's key too.
  ASSERT_TRUE(store_->DeleteJob("job-5").ok());
  EXPECT_EQ(RawRedis(redis_, {"EXISTS", "irfarm:job:job-5:scene"}), "0");
}

// A store-consistency check at start-up (issue 10, part 4): damaged keys (a job that does not
// parse, a job id listed without its key, a record batch that does not parse, a tile hash of
// the wrong type) are reported and skipped; the coordinator starts and resumes the rest.
TEST(RedisStartupTest, DamagedKeysAreSkippedAndTheRestResumes) {
  RedisServer redis;
  std::unique_ptr<RedisJobStore> store = redis.Connect();
  ASSERT_TRUE(store) << "redis-server did not start";
  std::string good;
  {
    std::unique_ptr<JobManager> manager =
        std::move(*JobManager::Create(JobManagerOptions(), store.get()));
    const v1::SubmitJobRequest req = CornellRequest();
    for (int i = 0; i < 2; ++i) {
      absl::StatusOr<v1::Job> job = manager->Submit(req);
      ASSERT_TRUE(job.ok()) << job.status();
      good = job->id();
    }
  }
  IrradianceRecord r;
  r.normal = Vec3(0, 1, 0);
  r.irradiance = Vec3(0.5f);
  r.radius = 0.1f;
  ASSERT_TRUE(store->AppendRecords(good, {r, r}).ok());
  RawRedis(redis, {"SET", "irfarm:job:job-1", "not a protobuf \xff\xff\xff"});
  RawRedis(redis, {"SADD", "irfarm:jobs", "job-77"});  // listed, no key
  RawRedis(redis, {"RPUSH", "irfarm:job:" + good + ":records", "\xff\xff garbage"});
  RawRedis(redis, {"SET", "irfarm:job:" + good + ":tiles", "a string, not a hash"});
  // Jobs that parse but ask what no submit may (the store is as untrusted as a client): a
  // 2^20 x 2^20 film (2.7e8 tiles: tens of GB at start-up), 1-pixel tiles, cache bounds that
  // are not a box. Each is skipped with a log line; start-up takes no longer than with none.
  const auto stored_job = [&](const std::string& id, const std::function<void(v1::StoredJob*)>& f) {
    v1::StoredJob s;
    s.mutable_job()->set_id(id);
    s.mutable_job()->set_state(v1::JOB_STATE_QUEUED);
    s.mutable_job()->set_width(32);
    s.mutable_job()->set_height(32);
    s.mutable_scene()->set_path(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml");
    f(&s);
    StoreRawJob(redis, s);
  };
  stored_job("job-80", [](v1::StoredJob* s) {
    s->mutable_job()->set_width(1 << 20);
    s->mutable_job()->set_height(1 << 20);
  });
  stored_job("job-81",
             [](v1::StoredJob* s) { s->mutable_job()->mutable_settings()->set_tile_size(1); });
  stored_job("job-82", [](v1::StoredJob* s) {
    for (float f : {0.0f, 0.0f, 0.0f, std::nanf(""), 1.0f, 1.0f}) s->add_cache_bounds(f);
  });
  // A finished tile of the good job with a NaN pixel: rendered again, not shown.
  const std::string clean_id = "job-83";
  stored_job(clean_id, [](v1::StoredJob*) {});
  std::vector<float> pixels(16 * 16 * 3, 0.5f);
  pixels[7] = std::nanf("");
  RawRedis(redis, {"HSET", "irfarm:job:" + clean_id + ":tiles", "0",
                   std::string(reinterpret_cast<const char*>(pixels.data()),
                               pixels.size() * sizeof(float))});
  // A job stored before tiles carried the firefly filter's peaks, whose one 2000^2 tile fits the
  // 64 MiB result limit without them (48 MB) and not with them (96 MB): resumed with the filter
  // off (its workers then send no peaks), not dropped.
  const std::string big_tile_id = "job-84";
  stored_job(big_tile_id, [](v1::StoredJob* s) {
    s->mutable_job()->set_width(2000);
    s->mutable_job()->set_height(2000);
    s->mutable_job()->mutable_settings()->set_tile_size(2000);
  });
  // An unfinished job whose scene is lost (its key gone): not resumed (nothing to render).
  stored_job("job-85", [](v1::StoredJob* s) { s->clear_scene(); });
  const auto t0 = std::chrono::steady_clock::now();
  absl::StatusOr<std::unique_ptr<JobManager>> again =
      JobManager::Create(JobManagerOptions(), store.get());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_LT(seconds, 5.0);
  std::vector<v1::Job> jobs = (*again)->ListJobs();
  std::sort(jobs.begin(), jobs.end(),
            [](const v1::Job& a, const v1::Job& b) { return a.id() < b.id(); });
  ASSERT_EQ(jobs.size(), 3u);
  EXPECT_EQ(jobs[0].id(), good);
  EXPECT_EQ(jobs[0].records_merged(), 2u);
  EXPECT_FALSE(jobs[0].settings().no_firefly_filter());
  EXPECT_EQ(jobs[1].id(), clean_id);
  EXPECT_EQ(jobs[1].tiles_done(), 0);
  EXPECT_EQ(jobs[2].id(), big_tile_id);
  EXPECT_TRUE(jobs[2].settings().no_firefly_filter());
}

// Delete says why it failed: with Redis gone, the cancelled job's final state is still queued for
// the store, and the client hears that (UNAVAILABLE, "store writes are still pending"), not only
// "cannot delete job" (a review's finding: no reason, whatever the cause).
TEST(RedisStartupTest, DeleteSaysWhyTheStoreRefused) {
  auto redis = std::make_unique<RedisServer>();
  std::unique_ptr<RedisJobStore> store = redis->Connect();
  ASSERT_TRUE(store) << "redis-server did not start";
  std::unique_ptr<JobManager> manager =
      std::move(*JobManager::Create(JobManagerOptions(), store.get()));
  absl::StatusOr<v1::Job> job = manager->Submit(CornellRequest());
  ASSERT_TRUE(job.ok()) << job.status();
  redis.reset();  // SIGKILL
  ASSERT_TRUE(manager->Cancel(job->id(), Caller()).ok());
  const absl::Status st = manager->Delete(job->id(), Caller());
  EXPECT_TRUE(absl::IsUnavailable(st)) << st;
  EXPECT_NE(st.message().find("store writes are still pending"), std::string::npos) << st;
  EXPECT_TRUE(manager->GetJob(job->id()).ok()) << "a job the store still has left memory";
}

// A retention round stops at the first job the store cannot delete: with Redis gone and five
// cancelled jobs past their time, each delete waits 2 s on the writes still queued, and lease
// expiry runs on the same thread after it (10 s a round before; a review's finding).
TEST(RedisStartupTest, ARetentionRoundStopsAtAStuckStore) {
  auto redis = std::make_unique<RedisServer>();
  std::unique_ptr<RedisJobStore> store = redis->Connect();
  ASSERT_TRUE(store) << "redis-server did not start";
  JobManagerOptions options;
  options.max_finished_jobs = 0;
  options.job_ttl = std::chrono::milliseconds(1);
  std::unique_ptr<JobManager> manager = std::move(*JobManager::Create(options, store.get()));
  std::vector<std::string> ids;
  for (int i = 0; i < 5; ++i) {
    absl::StatusOr<v1::Job> job = manager->Submit(CornellRequest());
    ASSERT_TRUE(job.ok()) << job.status();
    ids.push_back(job->id());
  }
  redis.reset();  // SIGKILL
  for (const std::string& id : ids) ASSERT_TRUE(manager->Cancel(id, Caller()).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(manager->ExpireJobs(), 0);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("MEASURED a retention round with a dead store took %.2f s\n", seconds);
  EXPECT_LT(seconds, 4.0);                    // one 2 s wait, not five
  EXPECT_EQ(manager->ListJobs().size(), 5u);  // kept until the store has deleted them
}

// A finished job whose tiles are gone from the store after a restart (evicted by a Redis
// maxmemory policy, or damaged) fails with the count, instead of serving an image with black
// tiles as SUCCEEDED (a review's finding: GetResult answered OK with 1 of 4 tiles black).
TEST(RedisStartupTest, ASucceededJobMissingTilesFailsWithTheCount) {
  RedisServer redis;
  std::unique_ptr<RedisJobStore> store = redis.Connect();
  ASSERT_TRUE(store) << "redis-server did not start";
  v1::StoredJob s;
  s.mutable_job()->set_id("job-5");
  s.mutable_job()->set_state(v1::JOB_STATE_SUCCEEDED);
  s.mutable_job()->set_width(32);
  s.mutable_job()->set_height(32);
  s.mutable_job()->mutable_settings()->set_tile_size(16);  // 4 tiles
  StoreRawJob(redis, s);
  const std::vector<float> pixels(16 * 16 * 3, 0.5f);
  for (const char* tile : {"0", "1", "2"})  // of 4: tile 3 is lost
    RawRedis(redis, {"HSET", "irfarm:job:job-5:tiles", tile,
                     std::string(reinterpret_cast<const char*>(pixels.data()),
                                 pixels.size() * sizeof(float))});
  absl::StatusOr<std::unique_ptr<JobManager>> manager =
      JobManager::Create(JobManagerOptions(), store.get());
  ASSERT_TRUE(manager.ok()) << manager.status();
  const absl::StatusOr<v1::Job> job = (*manager)->GetJob("job-5");
  ASSERT_TRUE(job.ok()) << job.status();
  EXPECT_EQ(job->state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(job->error().find("1 of 4 finished tiles were lost from the store"), std::string::npos)
      << job->error();
  EXPECT_FALSE((*manager)->ResultExr("job-5").ok());
}

}  // namespace
}  // namespace irfarm
