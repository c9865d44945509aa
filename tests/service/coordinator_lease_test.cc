// CoordinatorLease and the store fencing behind `irfarm-coordinator --ha`, on a real
// redis-server (tests/service/redis_server.h): one holder at a time, expiry hands the lease to
// a waiting standby (not before its ttl), renewal is a compare-and-set that never extends
// another owner's lease, the renewal thread keeps it and reports its loss (another owner, or
// Redis silent for ttl), release hands it over at once, and a fenced RedisJobStore writes
// nothing while its owner does not hold the lease.
#include <gtest/gtest.h>
#include <hiredis/hiredis.h>
#include <signal.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "coordinator/coordinator_lease.h"
#include "coordinator/redis_job_store.h"
#include "tests/service/redis_server.h"

namespace irfarm {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

// One command on a fresh connection: its reply as text ("" for nil), or the integer as text.
std::string Raw(const RedisServer& redis, const std::vector<std::string>& argv) {
  redisContext* c = redisConnect("127.0.0.1", redis.port());
  std::vector<const char*> args;
  std::vector<size_t> lengths;
  for (const std::string& a : argv) {
    args.push_back(a.data());
    lengths.push_back(a.size());
  }
  auto* r =
      static_cast<redisReply*>(redisCommandArgv(c, int(args.size()), args.data(), lengths.data()));
  std::string out = "(no reply)";
  if (r != nullptr) {
    if (r->type == REDIS_REPLY_INTEGER)
      out = std::to_string(r->integer);
    else if (r->type == REDIS_REPLY_NIL)
      out = "";
    else
      out.assign(r->str, r->len);
    freeReplyObject(r);
  }
  redisFree(c);
  return out;
}

LeaseOptions Options(int ttl_ms, int renew_ms = 0) {
  LeaseOptions o;
  o.ttl = milliseconds(ttl_ms);
  o.renew_every = milliseconds(renew_ms > 0 ? renew_ms : ttl_ms / 3);
  return o;
}

std::unique_ptr<CoordinatorLease> MakeLease(const RedisServer& redis, const std::string& label,
                                            const LeaseOptions& o) {
  absl::StatusOr<std::unique_ptr<CoordinatorLease>> l =
      CoordinatorLease::Create(redis.address(), NewOwnerId(label), o);
  EXPECT_TRUE(l.ok()) << l.status();
  return l.ok() ? std::move(*l) : nullptr;
}

// Waits until the server answers (it was just started).
void WaitForRedis(const RedisServer& redis) {
  for (int i = 0; i < 100 && Raw(redis, {"PING"}) != "PONG"; ++i)
    std::this_thread::sleep_for(milliseconds(50));
  ASSERT_EQ(Raw(redis, {"PING"}), "PONG");
}

TEST(CoordinatorLeaseTest, BadOptionsAreRefused) {
  EXPECT_FALSE(CoordinatorLease::Create("no-port", "x", Options(3000)).ok());
  EXPECT_FALSE(CoordinatorLease::Create("127.0.0.1:1", "x", Options(3000, 3000)).ok());
  EXPECT_FALSE(CoordinatorLease::Create("127.0.0.1:1", "", Options(3000)).ok());
  // Redis not there: UNAVAILABLE, not a false "someone else holds it".
  auto lease =
      CoordinatorLease::Create("127.0.0.1:" + std::to_string(FreePort()), "x", Options(3000));
  ASSERT_TRUE(lease.ok());
  EXPECT_TRUE(absl::IsUnavailable((*lease)->TryAcquire().status()));
}

TEST(CoordinatorLeaseTest, OneHolderAtATimeAndExpiryHandsItOver) {
  RedisServer redis;
  WaitForRedis(redis);
  auto a = MakeLease(redis, "a", Options(600));
  auto b = MakeLease(redis, "b", Options(600));
  const auto acquired = Clock::now();
  ASSERT_TRUE(*a->TryAcquire());
  EXPECT_TRUE(a->held());
  std::string holder;
  EXPECT_FALSE(*b->TryAcquire(&holder));
  EXPECT_EQ(holder, a->owner());
  EXPECT_FALSE(b->held());
  // a never renews: b, polling, gets it once the ttl ran out, not before.
  bool got = false;
  while (!got && Clock::now() - acquired < std::chrono::seconds(5)) {
    got = *b->TryAcquire();
    if (!got) std::this_thread::sleep_for(milliseconds(20));
  }
  const auto waited = Clock::now() - acquired;
  ASSERT_TRUE(got);
  EXPECT_GE(waited, milliseconds(600));
  EXPECT_EQ(Raw(redis, {"GET", "irfarm:coordinator_lease"}), b->owner());
}

TEST(CoordinatorLeaseTest, RenewalIsACompareAndSetThatNeverExtendsAnotherOwnersLease) {
  RedisServer redis;
  WaitForRedis(redis);
  auto a = MakeLease(redis, "a", Options(300));
  auto b = MakeLease(redis, "b", Options(20000));
  ASSERT_TRUE(*a->TryAcquire());
  EXPECT_TRUE(a->Renew().ok());
  std::this_thread::sleep_for(milliseconds(450));  // a's lease expires
  ASSERT_TRUE(*b->TryAcquire());
  // a renewing now would set the key's ttl to 300 ms if it did not check the owner.
  const absl::Status st = a->Renew();
  EXPECT_TRUE(absl::IsFailedPrecondition(st)) << st;
  EXPECT_NE(st.message().find(b->owner()), std::string::npos) << st;
  EXPECT_EQ(Raw(redis, {"GET", "irfarm:coordinator_lease"}), b->owner());
  EXPECT_GT(std::stoll(Raw(redis, {"PTTL", "irfarm:coordinator_lease"})), 10000);
  // Nor does a's release delete it.
  EXPECT_TRUE(a->Release().ok());
  EXPECT_EQ(Raw(redis, {"GET", "irfarm:coordinator_lease"}), b->owner());
  // b's own release frees it at once.
  EXPECT_TRUE(b->Release().ok());
  EXPECT_EQ(Raw(redis, {"EXISTS", "irfarm:coordinator_lease"}), "0");
  EXPECT_TRUE(*a->TryAcquire());
}

TEST(CoordinatorLeaseTest, RenewalsKeepTheLeaseAndItsLossIsReported) {
  RedisServer redis;
  WaitForRedis(redis);
  auto a = MakeLease(redis, "a", Options(600, 150));
  auto b = MakeLease(redis, "b", Options(600));
  const auto sent = Clock::now();
  ASSERT_TRUE(*a->TryAcquire());
  std::atomic<int> lost{0};
  std::string why;
  a->Start(sent, [&](const std::string& w) {
    why = w;
    lost.fetch_add(1);
  });
  // Three lease times later a still holds it.
  for (int i = 0; i < 18; ++i) {
    EXPECT_FALSE(*b->TryAcquire());
    std::this_thread::sleep_for(milliseconds(100));
  }
  EXPECT_TRUE(a->held());
  EXPECT_EQ(lost.load(), 0);
  // Someone else's owner id in the key (an operator, a split brain): a notices at its next
  // renewal and reports it once.
  Raw(redis, {"SET", "irfarm:coordinator_lease", "intruder", "PX", "20000"});
  for (int i = 0; i < 100 && lost.load() == 0; ++i) std::this_thread::sleep_for(milliseconds(10));
  std::this_thread::sleep_for(milliseconds(400));
  EXPECT_EQ(lost.load(), 1);
  EXPECT_FALSE(a->held());
  EXPECT_NE(why.find("intruder"), std::string::npos) << why;
  EXPECT_EQ(Raw(redis, {"GET", "irfarm:coordinator_lease"}), "intruder");
}

TEST(CoordinatorLeaseTest, RedisSilentForTheLeaseTimeLosesIt) {
  RedisServer redis;
  WaitForRedis(redis);
  LeaseOptions o = Options(900, 150);
  o.timeout = milliseconds(100);
  auto a = MakeLease(redis, "a", o);
  const auto sent = Clock::now();
  ASSERT_TRUE(*a->TryAcquire());
  std::atomic<bool> lost{false};
  std::atomic<int64_t> lost_after_ms{0};
  std::string why;
  a->Start(sent, [&](const std::string& w) {
    why = w;
    lost_after_ms = std::chrono::duration_cast<milliseconds>(Clock::now() - sent).count();
    lost = true;
  });
  std::this_thread::sleep_for(milliseconds(300));
  kill(redis.pid(), SIGSTOP);  // hung: renewals time out
  const auto stopped = Clock::now();
  for (int i = 0; i < 300 && !lost; ++i) std::this_thread::sleep_for(milliseconds(10));
  kill(redis.pid(), SIGCONT);
  ASSERT_TRUE(lost.load());
  // Not before the lease time after the last renewal that got through, and not much after it.
  EXPECT_GE(lost_after_ms.load(), 900);
  EXPECT_LT(Clock::now() - stopped, std::chrono::milliseconds(2500));
  EXPECT_NE(why.find("not renewed"), std::string::npos) << why;
  EXPECT_FALSE(a->held());
}

// Fencing: every write of a store whose owner does not hold the lease is refused, and nothing
// lands; the reads still work.
TEST(CoordinatorLeaseTest, FencedStoreWritesOnlyWhileItsOwnerHoldsTheLease) {
  RedisServer redis;
  WaitForRedis(redis);
  auto a = MakeLease(redis, "a", Options(20000));
  RedisOptions ro;
  ro.fence_key = a->options().key;
  ro.fence_owner = a->owner();
  std::unique_ptr<RedisJobStore> store = redis.Connect(ro);
  ASSERT_TRUE(store);
  IrradianceRecord r;
  r.position = Vec3(1, 2, 3);
  r.normal = Vec3(0, 0, 1);
  r.irradiance = Vec3(0.5f);
  r.radius = 0.25f;
  v1::StoredJob job;
  job.mutable_job()->set_id("job-1");
  job.mutable_scene()->set_path("/scenes/a/scene.xml");

  // No lease yet: refused.
  EXPECT_TRUE(absl::IsFailedPrecondition(store->PutTile("job-1", 0, "abc")));
  ASSERT_TRUE(*a->TryAcquire());
  ASSERT_TRUE(store->PutJob(job).ok());
  ASSERT_TRUE(store->PutTile("job-1", 0, "abc").ok());
  ASSERT_TRUE(store->AppendRecords("job-1", {r, r}).ok());
  ASSERT_EQ(*store->NextJobNumber(), 1u);

  // Another coordinator holds it now (a's lease expired and a standby took it).
  Raw(redis, {"SET", "irfarm:coordinator_lease", "standby-b 127.0.0.1:2", "PX", "20000"});
  EXPECT_TRUE(absl::IsFailedPrecondition(store->PutTile("job-1", 1, "def")));
  EXPECT_TRUE(absl::IsFailedPrecondition(store->AppendRecords("job-1", {r})));
  job.mutable_job()->set_state(v1::JOB_STATE_SUCCEEDED);
  EXPECT_TRUE(absl::IsFailedPrecondition(store->PutJob(job)));
  EXPECT_TRUE(absl::IsFailedPrecondition(store->NextJobNumber().status()));
  EXPECT_TRUE(absl::IsFailedPrecondition(store->DeleteJob("job-1")));
  EXPECT_EQ(store->LoadTiles("job-1")->size(), 1u);
  EXPECT_EQ(store->LoadRecords("job-1")->size(), 2u);
  std::vector<v1::StoredJob> jobs = *store->LoadJobs();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_NE(jobs[0].job().state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(Raw(redis, {"GET", "irfarm:job_counter"}), "1");

  // A store without a fence owner (no --ha) writes regardless of the lease.
  std::unique_ptr<RedisJobStore> plain = redis.Connect();
  ASSERT_TRUE(plain);
  EXPECT_TRUE(plain->PutTile("job-1", 2, "ghi").ok());
  EXPECT_EQ(store->LoadTiles("job-1")->size(), 2u);
}

}  // namespace
}  // namespace irfarm
