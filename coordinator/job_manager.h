// JobManager: the coordinator's logic, with no gRPC in it (the services in job_service.h and
// worker_service.h only translate). It owns the jobs (each with a TileScheduler, a GlobalCache
// and its finished tiles), the connected workers and what must be sent to each of them, and
// writes everything that must survive through to a JobStore; Create() reads the store back and
// resumes every unfinished job. Thread-safe: one mutex guards all state.
//
// Worker protocol, as seen from here: RegisterWorker gives an id; Poll returns what to send the
// worker next: other workers' record batches (fan-out), JobClosed notices and, when the worker
// holds no lease, its next tile lease, preceded by the job's spec and the job's records so far
// the first time the worker works on that job (late join). A job starting after other jobs of
// the same scene (a batch of frames) is first seeded with their records (cache_seed.h). Records and
// tile results come in through AddRecords and CompleteTile; WorkerGone requeues the tiles of a
// worker whose stream broke.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "coordinator/global_cache.h"
#include "coordinator/job_store.h"
#include "coordinator/tile_scheduler.h"
#include "render/denoiser.h"
#include "irfarm/v1/jobs.pb.h"
#include "irfarm/v1/worker.pb.h"

namespace irfarm {

// `origin` stamped on records imported from a snapshot (worker ids count up from 1).
constexpr uint32_t kSnapshotOrigin = 0xffffffffu;

struct JobManagerOptions {
  size_t max_upload_bytes = size_t(64) << 20;  // SubmitJob requests above this are refused
  int max_tile_attempts = 3;                   // a tile failing this often fails its job
  std::chrono::milliseconds lease_time{120000};
  size_t sync_batch_records = 16384;  // records per batch when catching up a late joiner
};

class JobManager {
 public:
  static absl::StatusOr<std::unique_ptr<JobManager>> Create(const JobManagerOptions& options,
                                                            JobStore* store);

  // --- Job API. Errors: NOT_FOUND (unknown job), INVALID_ARGUMENT (bad scene: the loader's
  // "path:line: ..." message; a bundle path leaving the bundle; bad settings), RESOURCE_EXHAUSTED
  // (upload over max_upload_bytes), FAILED_PRECONDITION (snapshot of another scene; result of an
  // unfinished job), UNAVAILABLE (the store failed). A refused request changes nothing.
  absl::StatusOr<v1::Job> Submit(const v1::SubmitJobRequest& request);
  absl::StatusOr<v1::Job> GetJob(const std::string& id) const;
  std::vector<v1::Job> ListJobs() const;
  absl::StatusOr<v1::Job> Cancel(const std::string& id);
  // The finished image as EXR file bytes. A job with settings.denoise is denoised here (tiles
  // alone cannot be: the filter needs their neighbours): RGB = denoised, layer "noisy" = as
  // rendered, layers "albedo" and "normal" = the guides.
  absl::StatusOr<std::string> ResultExr(const std::string& id) const;
  // The job's merged records as snapshot file bytes (cache/snapshot.h).
  absl::StatusOr<std::string> ExportSnapshot(const std::string& id) const;
  // Waits until anything changes after `seen` (a value returned before) or the timeout passes;
  // returns the current change counter.
  uint64_t WaitForChange(uint64_t seen, std::chrono::milliseconds timeout) const;

  // --- Worker side.
  uint32_t RegisterWorker(const std::string& name);
  void WorkerGone(uint32_t worker, const std::string& reason);
  // The worker will finish its tile and leave: give it no new lease.
  void Drain(uint32_t worker);
  absl::Status AddRecords(uint32_t worker, const v1::JobRecords& records);
  absl::Status CompleteTile(uint32_t worker, const v1::TileResult& result);
  absl::Status FailTile(uint32_t worker, const v1::TileFailed& failed);
  std::vector<v1::CoordinatorMessage> Poll(uint32_t worker, std::chrono::milliseconds timeout);
  // Requeues tiles whose lease deadline passed (call periodically).
  void ExpireLeases();

 private:
  struct Job {
    v1::StoredJob stored;
    std::unique_ptr<TileScheduler> tiles;
    std::unique_ptr<GlobalCache> cache;
    // Finished tiles: float RGB bytes, followed for denoised jobs by the guides (albedo RGB and
    // normal XYZ per pixel, as in TileResult.guides).
    std::map<int, std::string> pixels;
    std::map<uint32_t, v1::WorkerJobStats> worker_stats;
    std::set<uint32_t> workers;  // have the spec (and get the job's records)
    SteadyTime started, finished;
    bool has_started = false;
  };
  struct Worker {
    std::string name;
    std::deque<v1::CoordinatorMessage> outbox;
    std::set<std::string> jobs;
    bool has_lease = false, draining = false;
    std::string lease_job;
    uint64_t lease_id = 0;
  };

  JobManager(const JobManagerOptions& options, JobStore* store)
      : options_(options), store_(store) {}
  absl::Status Resume();
  v1::Job View(const Job& job) const;
  bool IsFinal(const Job& job) const;
  void TryAssign(uint32_t worker_id, Worker& worker, std::vector<v1::CoordinatorMessage>* out);
  void FinishJob(Job& job, v1::JobState state, const std::string& error);
  // When `job` starts: merges the records of earlier jobs of the same sensor-free scene and
  // record settings (cache_seed.h) into its cache, so its workers get them on joining.
  void SeedCache(Job& job);
  void Changed();
  // The denoiser, loaded on first use (thread-safe); its error says why it is unavailable.
  absl::StatusOr<const Denoiser*> GetDenoiser() const;

  const JobManagerOptions options_;
  JobStore* const store_;
  mutable std::mutex mu_;
  mutable std::condition_variable changed_cv_;  // any change (WaitForChange, Poll)
  uint64_t version_ = 0;
  uint64_t next_sequence_ = 1;
  uint32_t next_worker_ = 1;
  std::map<std::string, std::unique_ptr<Job>> jobs_;
  std::map<uint32_t, Worker> workers_;
  mutable std::mutex denoiser_mu_;  // guards the two below; OIDN filters run one at a time
  mutable std::unique_ptr<Denoiser> denoiser_;
  mutable absl::Status denoiser_error_;
};

}  // namespace irfarm
