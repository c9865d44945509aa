// Property tests of the coordinator's scheduling (issue 10): random sequences of operations from
// fixed seeds, with the invariants checked after every step.
//  - TileScheduler, against a model of its tiles (1000 sequences of lease / complete / fail /
//    silent release / worker gone / deadline expiry / stale and forged results): every tile is in
//    exactly one of pending, leased or done; a result counts only under the current lease, so
//    every tile is done at most once; done never goes back; a tile is leased to a worker it
//    failed on only when every other eligible worker failed it too; the job fails exactly when a
//    tile has failed on failure_workers distinct workers or max_attempts times; and when it has
//    not failed, an honest worker finishes every tile (nothing lost).
//  - JobManager (200 sequences, real scene, in-memory store): workers join, leave, take leases,
//    send good and bad results, fail tiles; clients submit and cancel; leases expire. Every
//    job's state only moves forward (QUEUED -> RUNNING -> final, and a final state never
//    changes), tiles_done never drops and reaches tiles_total exactly when the job SUCCEEDED,
//    each tile is accepted at most once, and an honest worker finishes every job still live.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>

#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"
#include "coordinator/lease_token.h"
#include "coordinator/tile_scheduler.h"
#include "service/job_settings.h"
#include "service/scene_bundle.h"

namespace irfarm {
namespace {

using std::chrono::milliseconds;

// What the scheduler should hold, tile by tile.
struct TileModel {
  enum State { kPending, kLeased, kDone } state = kPending;
  LeaseToken lease;
  uint32_t worker = 0;
  SteadyTime deadline;
  std::set<uint32_t> failed_on;
  int failures = 0;
};

TEST(SchedulingPropertyTest, TileSchedulerKeepsEveryTileAndCountsEachOnce) {
  int failed_jobs = 0, finished_jobs = 0;
  for (uint32_t seed = 1; seed <= 1000; ++seed) {
    std::mt19937 rng(seed);
    auto pick = [&](int n) { return int(rng() % uint32_t(n)); };
    const TileRetryPolicy policy{1 + pick(4), 2 + pick(12)};
    const int w = 1 + pick(80), h = 1 + pick(80), size = 4 + pick(30);
    TileScheduler s(w, h, size, policy);
    std::vector<TileModel> model(size_t(s.num_tiles()));
    const int workers = 1 + pick(5);
    SteadyTime now;
    bool failed = false;
    int done_before = 0;
    auto check = [&] {
      int pending = 0, done = 0;
      for (int t = 0; t < s.num_tiles(); ++t) {
        const TileModel& m = model[size_t(t)];
        pending += m.state == TileModel::kPending;
        done += m.state == TileModel::kDone;
        ASSERT_EQ(s.is_done(t), m.state == TileModel::kDone) << "seed " << seed << " tile " << t;
        if (m.state == TileModel::kLeased) {
          const TileLeaseInfo* l = s.Current(t, m.lease);
          ASSERT_NE(l, nullptr) << "seed " << seed << ": lease of tile " << t << " lost";
          ASSERT_EQ(l->worker, m.worker);
        }
      }
      ASSERT_EQ(s.num_done(), done) << "seed " << seed;
      ASSERT_GE(done, done_before) << "seed " << seed << ": done went back";
      done_before = done;
      ASSERT_EQ(s.has_pending(), pending > 0) << "seed " << seed;
      ASSERT_EQ(int(s.LeaseHolders().size()), s.num_tiles() - pending - done) << "seed " << seed;
    };
    // A requeue in the model; whether the policy says the job fails now.
    auto model_requeue = [&](int t, bool count) {
      TileModel& m = model[size_t(t)];
      m.state = TileModel::kPending;
      if (!count) return false;
      m.failed_on.insert(m.worker);
      ++m.failures;
      return int(m.failed_on.size()) >= policy.failure_workers || m.failures >= policy.max_attempts;
    };
    for (int step = 0; step < 200 && !failed; ++step) {
      const uint32_t worker = uint32_t(1 + pick(workers));
      std::vector<uint32_t> others;
      for (uint32_t o = 1; o <= uint32_t(workers); ++o)
        if (o != worker && pick(4) != 0) others.push_back(o);
      std::vector<int> leased;
      for (int t = 0; t < s.num_tiles(); ++t)
        if (model[size_t(t)].state == TileModel::kLeased) leased.push_back(t);
      const int op = pick(10);
      if (op <= 2) {  // lease
        const std::optional<TileLeaseInfo> l =
            s.Lease(worker, now, milliseconds(1 + pick(50)), others);
        if (l) {
          TileModel& m = model[size_t(l->tile)];
          ASSERT_EQ(m.state, TileModel::kPending)
              << "seed " << seed << ": leased a non-pending tile";
          if (m.failed_on.count(worker)) {
            for (uint32_t o : others)
              EXPECT_TRUE(m.failed_on.count(o))
                  << "seed " << seed << ": tile " << l->tile << " went back to worker " << worker
                  << " that failed it while worker " << o << " had not";
          }
          m = TileModel{TileModel::kLeased, l->token, worker, l->deadline, m.failed_on, m.failures};
        } else {
          for (int t = 0; t < s.num_tiles(); ++t) {
            const TileModel& m = model[size_t(t)];
            // Nothing for this worker: every pending tile failed on it and another can take it.
            if (m.state == TileModel::kPending) {
              EXPECT_TRUE(m.failed_on.count(worker) &&
                          std::any_of(others.begin(), others.end(),
                                      [&](uint32_t o) { return !m.failed_on.count(o); }))
                  << "seed " << seed << ": tile " << t << " stranded";
            }
          }
        }
      } else if (op <= 4 && !leased.empty()) {  // complete (honestly)
        const int t = leased[size_t(pick(int(leased.size())))];
        ASSERT_TRUE(s.Complete(t, model[size_t(t)].lease).ok()) << "seed " << seed;
        model[size_t(t)].state = TileModel::kDone;
        // The same result again, or under a forged lease: refused.
        EXPECT_FALSE(s.Complete(t, model[size_t(t)].lease).ok()) << "seed " << seed;
      } else if (op == 5) {  // a result for a random tile under a forged or stale lease token
        const int t = pick(s.num_tiles());
        // Forged: the tile's own token (or, for a tile not leased, the last one it had) with one
        // of its 128 bits flipped, or the all-zero token.
        std::string bytes = model[size_t(t)].lease.Bytes();
        const int bit = pick(129);
        if (bit < 128) bytes[size_t(bit / 8)] = char(bytes[size_t(bit / 8)] ^ (1 << (bit % 8)));
        const LeaseToken forged = bit < 128 ? *LeaseToken::FromBytes(bytes) : LeaseToken();
        EXPECT_FALSE(s.Complete(t, forged).ok()) << "seed " << seed;
      } else if (op == 6 && !leased.empty()) {  // the worker reports a failure
        const int t = leased[size_t(pick(int(leased.size())))];
        const absl::Status st = s.Requeue(t, model[size_t(t)].lease, "failed");
        failed = model_requeue(t, true);
        EXPECT_EQ(!st.ok(), failed) << "seed " << seed << " tile " << t;
      } else if (op == 7) {  // a worker goes silent (no failure) or its stream breaks (failure)
        const bool count = pick(2) == 0;
        const absl::Status st = s.ReleaseWorker(worker, "gone", count);
        bool any = false;
        for (int t : leased)
          if (model[size_t(t)].worker == worker) any = model_requeue(t, count) || any;
        EXPECT_EQ(!st.ok(), any) << "seed " << seed;
        failed = any;
      } else if (op == 8) {  // time passes; expired leases are requeued (a failure)
        now += milliseconds(pick(40));
        std::vector<int> expired;
        for (int t : leased)
          if (model[size_t(t)].deadline < now) expired.push_back(t);
        const absl::Status st = s.ExpireLeases(now);
        bool any = false;
        for (int t : expired) any = model_requeue(t, true) || any;
        EXPECT_EQ(!st.ok(), any) << "seed " << seed;
        failed = any;
      }
      check();
      if (::testing::Test::HasFatalFailure()) return;
    }
    if (failed) {
      ++failed_jobs;
      continue;
    }
    // An honest worker that no other worker can replace finishes whatever is left.
    for (int guard = 0; !s.all_done() && guard < 10 * s.num_tiles() + 10; ++guard) {
      for (int t = 0; t < s.num_tiles(); ++t)
        if (model[size_t(t)].state == TileModel::kLeased) {
          ASSERT_TRUE(s.Complete(t, model[size_t(t)].lease).ok());
          model[size_t(t)].state = TileModel::kDone;
        }
      const std::optional<TileLeaseInfo> l = s.Lease(1, now, milliseconds(1000));
      if (!l) continue;
      ASSERT_TRUE(s.Complete(l->tile, l->token).ok());
      model[size_t(l->tile)].state = TileModel::kDone;
    }
    ASSERT_TRUE(s.all_done()) << "seed " << seed << ": tiles lost";
    check();
    ++finished_jobs;
  }
  // Both outcomes were exercised.
  EXPECT_GT(failed_jobs, 50);
  EXPECT_GT(finished_jobs, 50);
}

TEST(SchedulingPropertyTest, JobStatesOnlyMoveForwardAndEveryTileCountsOnce) {
  v1::SubmitJobRequest request;
  *request.mutable_scene()->mutable_bundle() =
      *MakeBundle(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml");
  (*request.mutable_settings()->mutable_defines())["resx"] = "24";
  (*request.mutable_settings()->mutable_defines())["resy"] = "16";
  request.mutable_settings()->set_tile_size(8);  // 6 tiles of 8x8
  int succeeded = 0, failed = 0, cancelled = 0;
  for (uint32_t seed = 1; seed <= 200; ++seed) {
    std::mt19937 rng(seed);
    auto pick = [&](int n) { return int(rng() % uint32_t(n)); };
    InMemoryJobStore store;
    JobManagerOptions options;
    options.lease_time = milliseconds(pick(2) == 0 ? 1 : 60000);
    options.quarantine_time = milliseconds(0);
    std::unique_ptr<JobManager> m = std::move(*JobManager::Create(options, &store));
    std::map<std::string, v1::Job> last;                  // last view of each job
    std::map<std::pair<std::string, int>, int> accepted;  // tile results that counted
    struct Held {
      std::string job;
      int tile = 0;
      std::string lease;  // token bytes
      int floats = 0;
    };
    std::map<uint32_t, std::optional<Held>> workers;
    auto check = [&] {
      for (const v1::Job& j : m->ListJobs()) {
        auto it = last.find(j.id());
        if (it != last.end()) {
          const v1::Job& before = it->second;
          ASSERT_GE(int(j.state()), int(before.state())) << "seed " << seed << " " << j.id();
          if (before.state() >= v1::JOB_STATE_SUCCEEDED) {
            ASSERT_EQ(j.state(), before.state()) << "seed " << seed;
          }
          ASSERT_GE(j.tiles_done(), before.tiles_done()) << "seed " << seed;
        }
        ASSERT_LE(j.tiles_done(), j.tiles_total());
        ASSERT_EQ(j.tiles_done() == j.tiles_total(), j.state() == v1::JOB_STATE_SUCCEEDED)
            << "seed " << seed << " " << j.id() << " " << v1::JobState_Name(j.state());
        last[j.id()] = j;
      }
      for (const auto& [key, n] : accepted) ASSERT_LE(n, 1) << "tile counted twice";
    };
    auto poll = [&](uint32_t w) {
      for (const v1::CoordinatorMessage& msg : m->Poll(w, milliseconds(0)))
        if (msg.has_lease()) {
          const v1::TileLease& l = msg.lease();
          workers[w] = Held{l.job_id(), l.tile_index(), l.lease_token(),
                            (l.rect().x1() - l.rect().x0()) * (l.rect().y1() - l.rect().y0()) * 3};
        } else if (msg.has_job_closed() && workers[w] &&
                   workers[w]->job == msg.job_closed().job_id()) {
          workers[w].reset();
        }
    };
    auto result = [&](uint32_t w, const Held& held, int floats, float value) {
      v1::TileResult r;
      r.set_job_id(held.job);
      r.set_tile_index(held.tile);
      r.set_lease_token(held.lease);
      for (int i = 0; i < floats; ++i) r.add_pixels(value);
      const absl::Status st = m->CompleteTile(w, r);
      if (st.ok()) ++accepted[{held.job, held.tile}];
      return st;
    };
    for (int step = 0; step < 60; ++step) {
      const int op = pick(12);
      if (op == 0 || m->ListJobs().empty()) {
        ASSERT_TRUE(m->Submit(request).ok());
      } else if (op == 1 || workers.empty()) {
        workers[m->RegisterWorker("w" + std::to_string(pick(3)))] = std::nullopt;
      } else {
        auto it = workers.begin();
        std::advance(it, pick(int(workers.size())));
        const uint32_t w = it->first;
        if (op == 2) {
          m->WorkerGone(w, "stream broke");
          workers.erase(w);
        } else if (op <= 5) {
          if (!it->second) poll(w);
        } else if (op <= 8 && it->second) {  // a result: good, or wrong size, or NaN
          const Held held = *it->second;
          it->second.reset();
          const int kind = pick(4);
          (void)result(w, held, kind == 0 ? held.floats - 3 : held.floats,
                       kind == 1 ? std::nanf("") : 0.5f);
          // Replayed: never counts twice.
          (void)result(w, held, held.floats, 0.5f);
        } else if (op == 9 && it->second) {
          v1::TileFailed f;
          f.set_job_id(it->second->job);
          f.set_tile_index(it->second->tile);
          f.set_lease_token(it->second->lease);
          (void)m->FailTile(w, f);
          it->second.reset();
        } else if (op == 10) {
          const std::vector<v1::Job> jobs = m->ListJobs();
          (void)m->Cancel(jobs[size_t(pick(int(jobs.size())))].id());
        } else {
          m->ExpireLeases();
        }
      }
      check();
      if (::testing::Test::HasFatalFailure()) return;
    }
    // An honest worker finishes every job still live.
    for (auto& [w, held] : workers) m->WorkerGone(w, "end of sequence");
    const uint32_t honest = m->RegisterWorker("honest");
    std::optional<Held> h;
    for (int guard = 0; guard < 1000; ++guard) {
      for (const v1::CoordinatorMessage& msg : m->Poll(honest, milliseconds(0)))
        if (msg.has_lease())
          h = Held{msg.lease().job_id(), msg.lease().tile_index(), msg.lease().lease_token(),
                   (msg.lease().rect().x1() - msg.lease().rect().x0()) *
                       (msg.lease().rect().y1() - msg.lease().rect().y0()) * 3};
      if (!h) break;
      (void)result(honest, *h, h->floats, 0.5f);
      h.reset();
    }
    check();
    for (const v1::Job& j : m->ListJobs()) {
      ASSERT_GE(int(j.state()), int(v1::JOB_STATE_SUCCEEDED))
          << "seed " << seed << ": " << j.id() << " left " << v1::JobState_Name(j.state());
      succeeded += j.state() == v1::JOB_STATE_SUCCEEDED;
      failed += j.state() == v1::JOB_STATE_FAILED;
      cancelled += j.state() == v1::JOB_STATE_CANCELLED;
    }
  }
  std::printf("MEASURED 200 sequences: %d jobs succeeded, %d failed, %d cancelled\n", succeeded,
              failed, cancelled);
  EXPECT_GT(succeeded, 0);
  EXPECT_GT(failed, 0);
  EXPECT_GT(cancelled, 0);
}

// cornell-box at 16 x 8 in two 8 x 8 tiles.
v1::SubmitJobRequest TwoTileRequest() {
  v1::SubmitJobRequest request;
  *request.mutable_scene()->mutable_bundle() =
      *MakeBundle(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml");
  (*request.mutable_settings()->mutable_defines())["resx"] = "16";
  (*request.mutable_settings()->mutable_defines())["resy"] = "8";
  request.mutable_settings()->set_tile_size(8);
  return request;
}

// The lease a Poll of `w` brings now, if any.
std::optional<v1::TileLease> LeaseFor(JobManager* m, uint32_t w) {
  for (const v1::CoordinatorMessage& msg : m->Poll(w, milliseconds(0)))
    if (msg.has_lease()) return msg.lease();
  return std::nullopt;
}

// `w` sends the result of its 8 x 8 lease `l`.
absl::Status Complete8x8(JobManager* m, uint32_t w, const v1::TileLease& l) {
  v1::TileResult r;
  r.set_job_id(l.job_id());
  r.set_tile_index(l.tile_index());
  r.set_lease_token(l.lease_token());
  for (int i = 0; i < 8 * 8 * 3; ++i) r.add_pixels(0.5f);
  return m->CompleteTile(w, r);
}

// A tile that failed on one worker waits for the others (TryAssign gives it to a worker it
// failed on only when no other could take it), but not for one whose lease is overdue: that
// worker never reported (a hung render, or a worker that keeps its stream alive and does not
// report), gets no lease before it does, and so never takes the tile. The job stayed RUNNING for
// ever before, with an honest worker idle.
TEST(SchedulingTest, AWorkerWithAnOverdueLeaseDoesNotHoldBackATile) {
  v1::SubmitJobRequest request = TwoTileRequest();
  InMemoryJobStore store;
  JobManagerOptions options;
  options.lease_time = milliseconds(300);
  std::unique_ptr<JobManager> m = std::move(*JobManager::Create(options, &store));
  const absl::StatusOr<v1::Job> job = m->Submit(request);
  ASSERT_TRUE(job.ok()) << job.status();
  const uint32_t holder = m->RegisterWorker("holder"), honest = m->RegisterWorker("honest");
  auto lease = [&](uint32_t w) { return LeaseFor(m.get(), w); };
  auto complete = [&](uint32_t w, const v1::TileLease& l) { return Complete8x8(m.get(), w, l); };
  const std::optional<v1::TileLease> held = lease(holder);
  const std::optional<v1::TileLease> failing = lease(honest);
  ASSERT_TRUE(held && failing);
  v1::TileFailed f;
  f.set_job_id(failing->job_id());
  f.set_tile_index(failing->tile_index());
  f.set_lease_token(failing->lease_token());
  f.set_reason("out of memory");
  ASSERT_TRUE(m->FailTile(honest, f).ok());
  // The failed tile waits for the holder while its lease runs.
  EXPECT_FALSE(lease(honest));
  std::this_thread::sleep_for(milliseconds(400));
  m->Heard(holder);  // alive, not reporting
  m->ExpireLeases();
  // The holder's expired tile and the failed one both go to the honest worker (which first does
  // not matter; before, it got the expired one and then nothing).
  std::set<int> done;
  for (int k = 0; k < 2; ++k) {
    const std::optional<v1::TileLease> l = lease(honest);
    ASSERT_TRUE(l) << "lease " << k << ": a tile waits for a worker whose lease is overdue";
    ASSERT_TRUE(complete(honest, *l).ok());
    done.insert(l->tile_index());
  }
  EXPECT_EQ(done, (std::set<int>{held->tile_index(), failing->tile_index()}));
  EXPECT_EQ(m->GetJob(job->id())->state(), v1::JOB_STATE_SUCCEEDED);
}

// A worker holds at most kMaxWorkerJobs open jobs (it ignores the spec of one more and would fail
// its leases, each a counted failure): with 64 open on it, a new job of higher priority is not
// leased to it, a tile of a job it holds is; once one of its jobs closes, the new job is.
TEST(SchedulingTest, AWorkerIsLeasedNoTileOfAJobPastItsOpenJobs) {
  v1::SubmitJobRequest request = TwoTileRequest();
  InMemoryJobStore store;
  JobManagerOptions options;
  options.limits.max_live_jobs_per_client = 100;
  std::unique_ptr<JobManager> m = std::move(*JobManager::Create(options, &store));
  const uint32_t w = m->RegisterWorker("w");
  auto lease = [&] { return LeaseFor(m.get(), w); };
  auto complete = [&](const v1::TileLease& l) { return Complete8x8(m.get(), w, l); };
  // Each job in turn: higher priority than the last, one of its two tiles done, so it stays open.
  for (int i = 0; i < int(kMaxWorkerJobs); ++i) {
    request.set_priority(i);
    const absl::StatusOr<v1::Job> job = m->Submit(request);
    ASSERT_TRUE(job.ok()) << job.status();
    const std::optional<v1::TileLease> l = lease();
    ASSERT_TRUE(l);
    ASSERT_EQ(l->job_id(), job->id());
    ASSERT_TRUE(complete(*l).ok());
  }
  request.set_priority(int(kMaxWorkerJobs));
  const absl::StatusOr<v1::Job> extra = m->Submit(request);
  ASSERT_TRUE(extra.ok());
  const std::optional<v1::TileLease> held = lease();
  ASSERT_TRUE(held);
  EXPECT_NE(held->job_id(), extra->id()) << "a 65th open job on one worker";
  ASSERT_TRUE(complete(*held).ok());  // that job closes (both tiles done)
  const std::optional<v1::TileLease> next = lease();
  ASSERT_TRUE(next);
  EXPECT_EQ(next->job_id(), extra->id());
}

}  // namespace
}  // namespace irfarm
