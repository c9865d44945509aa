// StoreWriter: the job store writes that need not hold anything up, done by a thread of their
// own: job-state changes (a job starting, finishing, being cancelled; JobManager::FinishJob and
// friends run under the coordinator's lock, which must never wait on Redis) and the records a
// job was seeded with. Writes run in the order queued; one that fails (Redis down or hung) is
// retried every `retry` until it succeeds (one refused NOT_FOUND is dropped: the job was
// deleted, JobStore::DeleteJob), so once the store answers again it ends up with the
// latest state of every job. A PutJob replaces a PutJob of the same job still queued behind
// nothing else of that job (keeping that one's scene when it has none: JobStore::PutJob), so a
// store that is down for long holds one state per job here, not one per change. What is lost if the
// coordinator dies before a queued write lands is only a job state: the job resumes after a restart
// and is finished again (its tiles are written synchronously, before they count). Thread-safe.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "coordinator/job_store.h"

namespace irfarm {

class StoreWriter {
 public:
  // The scene of a job the coordinator holds (nullopt: none, or the job is gone), for a state
  // change the store refuses because it lost the job's scene (IsSceneMissing): the writer then
  // writes the state with this scene. Called on the writer's thread, without the writer's lock.
  using SceneOf = std::function<std::optional<v1::SceneSource>(const std::string& job_id)>;
  static constexpr std::chrono::milliseconds kDefaultRetry{500};
  explicit StoreWriter(JobStore* store, std::chrono::milliseconds retry = kDefaultRetry,
                       SceneOf scene_of = nullptr);
  // Writes what is queued until the first failure, then stops.
  ~StoreWriter();
  StoreWriter(const StoreWriter&) = delete;
  StoreWriter& operator=(const StoreWriter&) = delete;

  void PutJob(const v1::StoredJob& job);
  void AppendRecords(const std::string& job_id, std::vector<IrradianceRecord> records);
  // Deletes the job once the store answers: for a job whose submit was refused because its
  // PutJob failed, which may yet land (sent before Redis hung); the delete's tombstone keeps
  // out one that lands later still.
  void DeleteJob(const std::string& job_id);
  // Waits until nothing is queued or being written, or `timeout` passed; true when empty.
  bool Flush(std::chrono::milliseconds timeout);
  // Writes queued or in progress.
  size_t pending() const;
  // Attempts that failed (each retry counts).
  uint64_t failures() const;

 private:
  struct Op {
    std::string job_id;
    std::optional<v1::StoredJob> job;       // PutJob
    std::vector<IrradianceRecord> records;  // AppendRecords
    bool remove = false;                    // DeleteJob
  };
  void Run();
  absl::Status Write(const Op& op);

  JobStore* const store_;
  const std::chrono::milliseconds retry_;
  const SceneOf scene_of_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Op> queue_;
  bool busy_ = false;  // an op taken from the queue is being written
  bool stop_ = false;
  uint64_t failures_ = 0;
  std::thread thread_;
};

}  // namespace irfarm
