// RedisJobStore: a JobStore in Redis (hiredis), so a coordinator killed and restarted on the same
// Redis resumes every unfinished job without losing a finished tile or a merged record.
//
// Keys (PREFIX defaults to "irfarm:"):
//   PREFIX job_counter          INCR counter behind NextJobNumber
//   PREFIX jobs                 SET of job ids
//   PREFIX job:ID               STRING: serialized irfarm.v1.StoredJob (state, scene, settings)
//   PREFIX job:ID:tiles         HASH tile index -> the tile's float RGB pixels (bytes)
//   PREFIX job:ID:records       LIST of serialized irfarm.v1.RecordBatch, one per merged batch
// What is atomic: PutJob writes the job and adds it to the set in one MULTI/EXEC; each PutTile is
// one HSET and each AppendRecords one RPUSH, so a tile is stored whole or not at all and a batch
// of records likewise. The coordinator marks a tile done only after its HSET succeeded, and fans
// records out only after their RPUSH succeeded, so whatever clients and workers were told is
// in Redis. Writes are not fsync'ed by us: durability across a Redis crash is Redis's own
// persistence setting (appendonly); a coordinator crash loses nothing that was acknowledged.
// When Redis is down: every call returns UNAVAILABLE (the coordinator refuses submits, requeues
// a tile whose result it could not store, and drops that record batch); the next call tries to
// reconnect (2 s connect timeout), so service resumes when Redis is back. One connection, used
// under a mutex (calls are short; the coordinator is not Redis-bound).
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include "coordinator/job_store.h"

struct redisContext;

namespace irfarm {

class RedisJobStore : public JobStore {
 public:
  // host:port. Fails (UNAVAILABLE) when Redis does not answer PING.
  static absl::StatusOr<std::unique_ptr<RedisJobStore>> Connect(
      const std::string& address, const std::string& prefix = "irfarm:");
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
  RedisJobStore(std::string host, int port, std::string prefix)
      : host_(std::move(host)), port_(port), prefix_(std::move(prefix)) {}
  absl::Status EnsureConnected();  // mu_ held
  void Drop();                     // mu_ held: forget a broken connection

  const std::string host_;
  const int port_;
  const std::string prefix_;
  std::mutex mu_;
  redisContext* ctx_ = nullptr;
};

}  // namespace irfarm
