// RedisJobStore: a JobStore in Redis (hiredis), so a coordinator killed and restarted on the same
// Redis resumes every unfinished job without losing a finished tile or a merged record.
//
// Keys (PREFIX defaults to "irfarm:"):
//   PREFIX job_counter          INCR counter behind NextJobNumber
//   PREFIX jobs                 SET of job ids
//   PREFIX job:ID               STRING: serialized irfarm.v1.StoredJob, its scene left out
//                               (state, settings); jobs stored before the scene had a key of its
//                               own have it here, and are moved at LoadJobs
//   PREFIX job:ID:scene         STRING: serialized irfarm.v1.SceneSource (the upload), written
//                               only by a PutJob that carries a scene
//   PREFIX job:ID:tiles         HASH tile index -> the tile's bytes (float RGB pixels, guides,
//                               peaks)
//   PREFIX job:ID:records       LIST of serialized irfarm.v1.RecordBatch, one per merged batch
//   PREFIX deleted:ID           STRING, for a day after the job was deleted: PutJob refuses it
// What is atomic: every write is one Lua script (EVAL), which Redis runs whole with nothing in
// between: PutJob writes the job (and its scene) and adds it to the set together, or, for an
// unfinished job's state change whose scene is gone (flushed, evicted), nothing (IsSceneMissing);
// each PutTile is one HSET and each AppendRecords one RPUSH, so a tile is stored whole or not at
// all and a batch of records likewise; a tile or batch of a job not in the set, and a PutJob of a
// deleted job, write nothing and fail NOT_FOUND (a write that lands after the delete cannot
// recreate its keys). The coordinator marks a tile done only after its HSET succeeded, and fans
// records out only after their RPUSH succeeded, so whatever clients and workers were told is in
// Redis. Writes are not fsync'ed by us: durability across a Redis crash is Redis's own persistence
// setting (appendonly); a coordinator crash loses nothing that was acknowledged.
//
// When Redis is down or hung (SIGSTOP, a stalled network): every call gives up after its
// deadline (RedisOptions::timeout, 500 ms by default, for waiting for the connection plus as much
// again for Redis's answer) and returns UNAVAILABLE (the coordinator refuses submits, requeues a
// tile whose result it could not store, drops that record batch and retries job-state writes);
// the next call reconnects, so service resumes when Redis is back. A command that timed out may
// still run when a hung Redis resumes (an INCR leaves a gap in job numbers, an RPUSH stores a
// batch the coordinator dropped: both harmless). One connection, used under a mutex that callers
// wait for at most `timeout`. The start-up reads (Load*) get the longer load_timeout, and report
// and skip what they cannot read (a damaged job key, a damaged record batch) rather than keep
// the coordinator from starting.
//
// Fencing (several coordinators on one Redis, `irfarm-coordinator --ha`, coordinator_lease.h):
// with RedisOptions::fence_owner set, each write script first checks that the lease key holds
// that owner and otherwise writes nothing and fails (FAILED_PRECONDITION). Check and write are
// one script, so no write of a coordinator that lost its lease lands after a standby took over,
// not even one already on the wire when the lease expired, and no clock is trusted for it. Reads
// are not fenced: a standby does not serve before it holds the lease.
#pragma once

#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "coordinator/job_store.h"

struct redisContext;

namespace irfarm {

struct RedisOptions {
  std::string prefix = "irfarm:";
  // Deadline of one call: connecting, and each command's answer (and, separately, the wait for
  // the connection another call is using).
  std::chrono::milliseconds timeout{500};
  // The same for the start-up reads (LoadJobs/LoadTiles/LoadRecords), which may move hundreds
  // of MiB.
  std::chrono::milliseconds load_timeout{60000};
  // Fencing: when fence_owner is not empty, a write lands only while GET fence_key ==
  // fence_owner (the CoordinatorLease's key and owner id).
  std::string fence_key;
  std::string fence_owner;
};

class RedisJobStore : public JobStore {
 public:
  // host:port. Fails (UNAVAILABLE) when Redis does not answer PING.
  static absl::StatusOr<std::unique_ptr<RedisJobStore>> Connect(
      const std::string& address, const RedisOptions& options = RedisOptions());
  ~RedisJobStore() override;

  absl::StatusOr<uint64_t> NextJobNumber() override;
  absl::Status PutJob(const v1::StoredJob& job) override;
  absl::StatusOr<std::vector<v1::StoredJob>> LoadJobs() override;
  absl::Status PutTile(const std::string& job_id, int tile, const std::string& pixels) override;
  absl::StatusOr<std::map<int, std::string>> LoadTiles(const std::string& job_id) override;
  absl::Status AppendRecords(const std::string& job_id,
                             const std::vector<IrradianceRecord>& records) override;
  absl::StatusOr<std::vector<IrradianceRecord>> LoadRecords(const std::string& job_id) override;
  absl::Status DeleteJob(const std::string& job_id) override;

 private:
  RedisJobStore(std::string host, int port, const RedisOptions& options)
      : host_(std::move(host)), port_(port), options_(options), prefix_(options.prefix) {}
  // Takes mu_ within options_.timeout, or UNAVAILABLE (another call holds the connection).
  absl::StatusOr<std::unique_lock<std::mutex>> Lock();
  absl::Status EnsureConnected();  // mu_ held
  void Drop();                     // mu_ held: forget a broken connection
  // mu_ held, connected: sets the deadline of the commands that follow.
  void SetCommandTimeout(std::chrono::milliseconds t);
  // Takes mu_ and runs a write script: `body` (Lua) sees the job keys from KEYS[2] and its
  // arguments from ARGV[2] on, after the fence check on KEYS[1] / ARGV[1]. Returns the script's
  // integer result. UNAVAILABLE when Redis fails, FAILED_PRECONDITION when fenced, DATA_LOSS for
  // a key of the wrong type. `timeout` 0: options_.timeout.
  absl::StatusOr<long long> Write(const char* body, const std::vector<std::string>& keys,
                                  const std::vector<std::string>& args,
                                  std::chrono::milliseconds timeout = {});

  const std::string host_;
  const int port_;
  const RedisOptions options_;
  const std::string prefix_;
  std::mutex mu_;
  redisContext* ctx_ = nullptr;
};

}  // namespace irfarm
