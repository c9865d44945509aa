// JobManager: the coordinator's logic, with no gRPC in it (the services in job_service.h and
// worker_service.h only translate). It owns the jobs (each with a TileScheduler, a GlobalCache
// and its finished tiles), the connected workers and what must be sent to each of them, and
// writes everything that must survive through to a JobStore; Create() reads the store back and
// resumes every unfinished job. Thread-safe: one mutex guards all state, and it is never held
// while the store is called (a hung Redis must not stall what is answered from memory: GetJob,
// ListJobs, leases): a tile result or record batch is checked under the lock, written to the
// store without it, and counted under it again if its lease or job is still current; job-state
// changes go through a StoreWriter (store_writer.h).
//
// Worker protocol, as seen from here: RegisterWorker gives an id; Poll returns what to send the
// worker next: other workers' record batches (fan-out), JobClosed notices, Rejected notices and,
// when the worker holds no lease, its next tile lease, preceded by the job's spec and the job's
// records so far the first time the worker works on that job (late join). A job starting after
// other jobs of the same scene (a batch of frames) is first seeded with their records
// (cache_seed.h). Records and tile results come in through AddRecords and CompleteTile;
// WorkerGone requeues the tiles of a worker whose stream broke.
//
// Filtered fan-out (options.filter_fanout, for workers that registered with reports_regions): a
// worker gets only the records that reach the region its leased tiles see (fanout_region.h),
// the union of the TileRegion boxes it sent for the job; at late join it gets none (its region
// is empty), and whenever its region grows it gets the job's records that reach the grown region
// but not the old one (the backlog of records withheld from it). Per worker and job the records
// delivered, withheld and sent from the backlog are counted (WorkerJobStats, Prometheus, and a
// log line when the job ends). A record batch looks up its receivers in a grid over the
// filtered workers' regions (fanout_index.h): its cost grows with the workers it reaches, not
// with the job's workers; the withheld counts are settled lazily (Job::Tally), Prometheus's
// withheld counters by ExpireLeases (they lag by at most one of its periods).
//
// Nothing a worker sends is trusted (issue 10): a tile result or TileFailed counts only from the
// session holding that (random) lease; pixels must be finite and non-negative and stats sane;
// records are merged only for a job the worker holds a lease of, while the job runs, and only
// within the scene's RecordBounds. Every invalid message is counted, answered with a Rejected
// message and, past max_violations, ends the session (Expelled). A tile that failed is leased to
// other workers first; a worker failing quarantine_after tiles in a row gets no leases for
// quarantine_time; a worker silent for 3 heartbeat periods loses its leases (not counted as a
// failure of the tile) until it is heard from again.
//
// Jobs belong to the client that submitted them (Caller): a non-admin caller sees and acts on
// its own jobs only; others' jobs are NOT_FOUND to it. JobLimits bound what one request may ask.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "coordinator/coordinator_metrics.h"
#include "coordinator/fanout_index.h"
#include "coordinator/global_cache.h"
#include "coordinator/job_store.h"
#include "coordinator/lease_token.h"
#include "coordinator/store_writer.h"
#include "coordinator/tile_scheduler.h"
#include "irfarm/v1/jobs.pb.h"
#include "irfarm/v1/worker.pb.h"
#include "render/camera.h"
#include "render/denoiser.h"
#include "render/image.h"
#include "render/record_bounds.h"

namespace irfarm {

// `origin` stamped on records imported from a snapshot (worker ids count up from 1).
constexpr uint32_t kSnapshotOrigin = 0xffffffffu;

// What one request may ask for; each has a coordinator flag (coordinator/main.cc). Requests over
// a limit get INVALID_ARGUMENT (a single request asking too much) or RESOURCE_EXHAUSTED (too
// many live jobs, too large an upload).
struct JobLimits {
  int max_film_side = 32768;                   // pixels along either axis
  int64_t max_film_pixels = int64_t(1) << 26;  // 67 M pixels (8192 x 8192)
  int max_tiles = 1 << 16;                     // tiles per job
  int64_t max_samples = int64_t(1) << 36;      // spp x pixels (6.9e10: 8192^2 at 1024 spp)
  int max_record_rays = 1 << 16;               // hemisphere rays per irradiance record
  size_t max_name_bytes = 1024;                // job name, worker name
  int max_defines = 256;                       // -D overrides per job
  size_t max_define_bytes = 4096;              // name + value of one -D
  int max_batch_records = 1 << 16;             // records per worker message
  // Records one job's cache holds, from all its workers (64 bytes each in memory, and each is in
  // the store and sent to the other workers): 2^24 is about 1 GiB, some 30x the records of a
  // default render of an 8192 x 8192 image. A worker sending past it is refused (Rejected).
  int64_t max_job_records = int64_t(1) << 24;
  // Queued + running jobs of one client, counting its submits still in progress.
  int max_live_jobs_per_client = 64;
  size_t max_outbox_bytes = size_t(64) << 20;  // record fan-out queued for one worker
  // ... and for all workers together: sessions that do not read (each up to max_outbox_bytes)
  // must not add up to the coordinator's memory; past it fan-out is dropped for everyone.
  size_t max_total_outbox_bytes = size_t(1) << 30;
  // A tile's result (its pixels, and the denoiser's guides) must fit in this many bytes: the
  // coordinator's message size limit less 1 MiB for the rest of the message (irfarm-coordinator
  // sets both from --max-upload-mib). A job whose tiles could never be delivered is refused.
  size_t max_tile_result_bytes = size_t(64) << 20;
  // GetResult and ExportCache calls in progress at once (each holds a whole image or snapshot,
  // and its file, in memory); past it RESOURCE_EXHAUSTED, to be retried.
  int max_downloads = 4;
  // WatchJob streams open at once (each holds a server thread until its job ends); past it
  // RESOURCE_EXHAUSTED (GetJob answers the same, polled).
  int max_watches = 64;
  // A job's priority (higher runs first, across all clients' jobs) is in [0, kMaxPriority].
  static constexpr int kMaxPriority = 100;
};

struct JobManagerOptions {
  size_t max_upload_bytes = size_t(64) << 20;  // SubmitJob requests above this are refused
  TileRetryPolicy tile_retry;                  // when a failing tile fails its job
  std::chrono::milliseconds lease_time{120000};
  // Workers send a heartbeat this often; one silent for 3 periods loses its leases.
  std::chrono::milliseconds heartbeat{1000};
  int quarantine_after = 3;  // failed tiles in a row
  std::chrono::milliseconds quarantine_time{30000};
  int max_violations = 16;  // invalid messages before the coordinator ends a worker's session
  size_t sync_batch_records = 16384;  // records per batch when catching up a late joiner
  // Send a worker that reports regions only the records that reach them (false: every record to
  // every worker of the job, `irfarm-coordinator --fanout=all`).
  bool filter_fanout = true;
  // Fan-out batching: records for a worker that is rendering a tile wait up to this long after
  // the first of them was queued, so that the batches of many senders leave as one message (one
  // write instead of one per sender; bench/scale_sim.cc measured the difference). Adds at most
  // this much to a record's delivery latency; 0 sends each batch as soon as the worker's stream
  // takes it.
  std::chrono::milliseconds fanout_linger{10};
  JobLimits limits;
  // Scenes given by path (SceneSource.path, read from the coordinator's file system): allowed
  // under this directory; with none, only for admin callers (which, without authentication, is
  // everyone: the loopback development setup). Others get PERMISSION_DENIED, whether the file
  // exists or not.
  std::string scene_path_root;
  // Retention: a finished job (succeeded, failed or cancelled) is removed, from memory and from
  // the store with its tiles and records, job_ttl after it finished (0: no TTL), and when more
  // than max_finished_jobs finished jobs are held, the oldest finished go first (0: no limit).
  // Checked by ExpireJobs() and at start-up, where expired jobs are deleted without being loaded.
  std::chrono::milliseconds job_ttl{std::chrono::hours(24 * 7)};
  int max_finished_jobs = 1000;
};

// Who calls the job API: the name of its client token, and whether it may see every job.
// Without authentication every caller is Caller{} (anonymous admin).
struct Caller {
  std::string name;
  bool admin = true;
};

class JobManager {
 public:
  // Metrics go to `registry` (the process's, served on --metrics), or with none to a registry
  // of the manager's own (metrics_registry()).
  static absl::StatusOr<std::unique_ptr<JobManager>> Create(const JobManagerOptions& options,
                                                            JobStore* store,
                                                            MetricsRegistry* registry = nullptr);
  // Takes its collector out of the registry (which may outlive it: a Create that failed).
  ~JobManager();

  // --- Job API. Errors: NOT_FOUND (unknown job), INVALID_ARGUMENT (bad scene: the loader's
  // "path:line: ..." message; a bundle path leaving the bundle; bad settings), RESOURCE_EXHAUSTED
  // (upload over max_upload_bytes), FAILED_PRECONDITION (snapshot of another scene; result of an
  // unfinished job), UNAVAILABLE (the store failed). A refused request changes nothing.
  absl::StatusOr<v1::Job> Submit(const v1::SubmitJobRequest& request,
                                 const Caller& caller = Caller());
  absl::StatusOr<v1::Job> GetJob(const std::string& id, const Caller& caller = Caller()) const;
  std::vector<v1::Job> ListJobs(const Caller& caller = Caller()) const;
  absl::StatusOr<v1::Job> Cancel(const std::string& id, const Caller& caller = Caller());
  // Removes a finished job from memory and the store (FAILED_PRECONDITION while it is queued or
  // running: cancel it first).
  absl::Status Delete(const std::string& id, const Caller& caller = Caller());
  // The finished image as EXR file bytes. A job with settings.denoise is denoised here (tiles
  // alone cannot be: the filter needs their neighbours): RGB = denoised, layer "noisy" = as
  // rendered, layers "albedo" and "normal" = the guides.
  absl::StatusOr<std::string> ResultExr(const std::string& id,
                                        const Caller& caller = Caller()) const;
  // The job's image so far (the dashboard): finished tiles' pixels, black elsewhere, at most
  // kMaxPreviewSide pixels on the longer side (each the mean of the finished pixels of its
  // block). For queued, running and succeeded jobs (a failed or cancelled job's pixels are
  // released: FAILED_PRECONDITION).
  absl::StatusOr<Image> Preview(const std::string& id, const Caller& caller = Caller()) const;
  static constexpr int kMaxPreviewSide = 1024;  // Preview's longer side at most, in pixels
  // The job's record map so far (the dashboard; record_map.h): where its level-0 records were
  // computed, coloured by the worker session that sent them. FAILED_PRECONDITION for a job stored
  // before jobs kept their camera.
  absl::StatusOr<Image> RecordMap(const std::string& id, const Caller& caller = Caller()) const;
  // Changes the priority of a queued or running job (FAILED_PRECONDITION once it ended).
  absl::StatusOr<v1::Job> SetPriority(const std::string& id, int priority,
                                      const Caller& caller = Caller());
  // The job's merged records as snapshot file bytes (cache/snapshot.h).
  absl::StatusOr<std::string> ExportSnapshot(const std::string& id,
                                             const Caller& caller = Caller()) const;
  // Connected workers and the worker-side counters (auth_failures is the caller's to fill).
  // Workers and counters. A caller other than an admin sees no worker's address, and a worker's
  // lease only when it is of one of the caller's own jobs (another client's job ids stay hidden).
  v1::GetClusterResponse Cluster(const Caller& caller = Caller{}) const;
  // Waits until anything changes after `seen` (a value returned before) or the timeout passes;
  // returns the current change counter.
  uint64_t WaitForChange(uint64_t seen, std::chrono::milliseconds timeout) const;

  // --- Worker side. The message handlers return OK, FAILED_PRECONDITION for a harmless stale
  // message (a result for a lease this worker lost, records for a job that just ended),
  // UNAVAILABLE when the store failed, or PERMISSION_DENIED / INVALID_ARGUMENT for an invalid
  // message (counted against the worker and answered with a Rejected message).
  // `token`: the name of the worker token it presented (Authenticator::Worker; "" without
  // tokens). Its failure history (WorkerHealth) is kept under token and name together, so a
  // worker cannot take the name of a worker with another token to have that one quarantined.
  // Workers sharing one token are told apart by their names alone, as before.
  uint32_t RegisterWorker(const std::string& name, const std::string& peer = "", int threads = 0,
                          bool reports_regions = false, const std::string& token = "");
  void WorkerGone(uint32_t worker, const std::string& reason);
  // The worker will finish its tile and leave: give it no new lease.
  void Drain(uint32_t worker);
  // Any message from the worker (heartbeats included) proves it alive.
  void Heard(uint32_t worker);
  absl::Status AddRecords(uint32_t worker, const v1::JobRecords& records);
  absl::Status CompleteTile(uint32_t worker, const v1::TileResult& result);
  absl::Status FailTile(uint32_t worker, const v1::TileFailed& failed);
  // Grows the worker's region of the job (filtered fan-out) and queues the backlog of records
  // that now reach it. One region per lease; INVALID_ARGUMENT / PERMISSION_DENIED (counted as a
  // violation) for a malformed box or a lease the worker never held, FAILED_PRECONDITION for a
  // stale or repeated one (ignored).
  absl::Status AddTileRegion(uint32_t worker, const v1::TileRegion& region);
  // True when the worker sent more than max_violations invalid messages: end its session.
  bool Expelled(uint32_t worker) const;
  std::vector<v1::CoordinatorMessage> Poll(uint32_t worker, std::chrono::milliseconds timeout);
  // Requeues tiles whose lease deadline passed and the leases of workers silent for 3 heartbeat
  // periods (call periodically, well within a heartbeat period).
  void ExpireLeases();
  // Removes finished jobs past options().job_ttl or beyond options().max_finished_jobs (call
  // periodically); returns how many were removed.
  int ExpireJobs();
  const JobManagerOptions& options() const { return options_; }
  MetricsRegistry* metrics_registry() const { return registry_; }
  // Waits until the job-state writes queued so far reached the store (or `timeout` passed).
  bool FlushStore(std::chrono::milliseconds timeout) { return writer_->Flush(timeout); }

 private:
  struct Job {
    v1::StoredJob stored;
    std::unique_ptr<TileScheduler> tiles;
    std::unique_ptr<GlobalCache> cache;
    // Finished tiles: float RGB bytes, followed for denoised jobs by the guides (albedo RGB and
    // normal XYZ per pixel, as in TileResult.guides), then for jobs with the firefly filter by
    // the peaks (RGB per pixel, TileResult.peaks) where the worker sent them. The preview shows
    // the pixels unfiltered; the result spreads the fireflies. Shared and never changed once
    // stored, so that a result or a preview takes them under mu_ and assembles the image without
    // it.
    std::map<int, std::shared_ptr<const std::string>> pixels;
    std::map<uint32_t, v1::WorkerJobStats> worker_stats;
    std::set<uint32_t> workers;  // have the spec (and get the job's records)
    // Filtered fan-out: per worker, the union of its TileRegion boxes (empty: none yet) and the
    // lease its last accepted region came with (one region per lease).
    struct Region {
      Bounds3 box;
      LeaseToken lease;
    };
    std::map<uint32_t, Region> regions;
    // The fan-out receivers of the job: the filtered workers' regions in a grid (fanout_index.h)
    // and the workers that get every record. Rebuilt at the next record batch after a region
    // grew or a worker joined or left (index_stale), so a batch costs the workers it reaches,
    // not all of them.
    FanoutIndex index;
    std::vector<uint32_t> unfiltered;
    bool index_stale = true;
    // Withheld records are counted lazily, for the same reason: per filtered worker of the job,
    // the records offered since its tally was settled are offered_total - total_mark minus its
    // own (it is not sent its own) and those it was sent or dropped for (handled); the rest were
    // withheld. Settled (CountFanout) when it leaves the job, when the job ends and by
    // ExpireLeases; View adds the unsettled part.
    struct Tally {
      uint64_t total_mark = 0, own = 0, handled = 0;
    };
    uint64_t offered_total = 0;
    std::map<uint32_t, Tally> tallies;
    std::vector<std::pair<uint32_t, uint32_t>> deliveries;  // scratch: (slot, record index)
    std::vector<uint32_t> slots;                            // scratch
    std::unique_ptr<Camera> camera;  // for RecordMap (null: stored without one)
    SteadyTime started, finished;
    bool has_started = false;
  };
  // What a worker's Poll waits on: bumped and notified when something was queued for it, or
  // anything changed that may give it a lease. Shared, so that a Poll in progress keeps it while
  // WorkerGone erases the worker.
  struct Wake {
    std::condition_variable cv;
    uint64_t seq = 0;
  };
  struct Worker {
    std::string name, peer;
    std::string health_key;  // "token/name" (RegisterWorker): where its failures are counted
    std::shared_ptr<Wake> wake = std::make_shared<Wake>();
    // Messages to send; consecutive record batches of one job are appended to one message (up
    // to sync_batch_records records).
    std::deque<v1::CoordinatorMessage> outbox;
    SteadyTime records_queued_at;  // when records were queued into an empty outbox
    std::set<std::string> jobs;
    bool has_lease = false, draining = false;
    std::string lease_job;
    LeaseToken lease;
    int lease_tile = -1;
    // The lease's deadline: past it, a worker still holding it (never reported; a hung render,
    // or a worker that does not report at all) is not counted on to take a tile (TryAssign).
    SteadyTime lease_deadline;
    int threads = 0;  // as registered (0: all its cores)
    // The last kPastLeases leases it was given (token, job id): a late message about one of
    // them is stale, not invalid.
    std::deque<std::pair<LeaseToken, std::string>> past_leases;
    SteadyTime last_heard;
    bool silent = false;  // no message for 3 heartbeat periods: leases taken, gets none
    uint32_t violations = 0;
    size_t outbox_bytes = 0;  // record payload queued in outbox
    // Record payload the last Poll handed to the session's writer (moved from the outbox, and a
    // late joiner's copy): held there, maybe blocked on a worker that does not read, until the
    // writer polls again. Counted in the bounds with outbox_bytes.
    size_t in_flight_bytes = 0;
    uint64_t batches_dropped = 0;  // fan-out batches not queued: outbox over max_outbox_bytes
    bool reports_regions = false;  // sends TileRegion messages (registered so)
    // Records of other workers (and imported ones) sent to it, and withheld by the filter, over
    // all its jobs (the Prometheus per-worker counters).
    uint64_t records_delivered = 0, records_withheld = 0;
  };
  // Failure history of a worker token and name (Worker::health_key; survives reconnects, so a
  // broken worker that reconnects stays quarantined).
  struct WorkerHealth {
    int consecutive_failures = 0;
    SteadyTime quarantined_until;
  };
  static constexpr size_t kPastLeases = 64;

  JobManager(const JobManagerOptions& options, JobStore* store, MetricsRegistry* registry);
  // Scrape-time metrics: jobs by state, per-job progress, workers, cache hit ratio.
  void CollectMetrics(MetricsWriter& w) const;
  absl::Status Resume();
  // A job id from the store's counter that no job held here has (nor one being submitted),
  // reserved in reserved_ids_ until the caller inserts or drops it. Takes mu_ only between
  // store calls.
  absl::StatusOr<std::string> ReserveJobId();
  v1::Job View(const Job& job) const;
  bool IsFinal(const Job& job) const;
  // The job `id` if `caller` may see it, else NOT_FOUND (the same answer as for no such job).
  absl::StatusOr<Job*> Find(const std::string& id, const Caller& caller) const;
  // A job's finished tiles, taken under mu_ (their bytes shared, not copied), for assembling an
  // image without it: GetResult and the dashboard's preview of a large job no longer hold every
  // worker message and lease while they build the image. FAILED_PRECONDITION for a failed or
  // cancelled job, and with `succeeded_only` for one not finished.
  struct FinishedTiles {
    int width = 0, height = 0;
    bool denoise = false;
    bool firefly_filter = false;  // the tiles carry peaks (those stored with them)
    std::vector<std::pair<PixelRect, std::shared_ptr<const std::string>>> tiles;
  };
  absl::StatusOr<FinishedTiles> TilesOf(const std::string& id, const Caller& caller,
                                        bool succeeded_only) const;
  // PERMISSION_DENIED unless `caller` may load the coordinator-side scene file `path`.
  absl::Status CheckScenePath(const std::string& path, const Caller& caller) const;
  // Counts an invalid message of `worker`, queues a Rejected notice (with `code`); returns
  // that status with `reason`.
  absl::Status Violation(uint32_t worker_id, Worker& worker, const std::string& reason,
                         absl::StatusCode code = absl::StatusCode::kPermissionDenied);
  // The lease token of a worker's message about a lease (`what`: "tile result", ...), or a
  // violation (INVALID_ARGUMENT) when `bytes` is not LeaseToken::kBytes long.
  absl::StatusOr<LeaseToken> TokenOf(uint32_t worker_id, Worker& worker, const std::string& bytes,
                                     const std::string& what);
  // A result or failure under `token` for a tile that is not (or no longer) this worker's:
  // harmless when the worker held that lease before (it expired), else a violation.
  absl::Status NotHolder(uint32_t worker_id, Worker* worker, const LeaseToken& token,
                         const std::string& what);
  void ReleaseLease(Worker& worker, const LeaseToken& token);
  // A worker's report about its lease of a tile (`what`: "tile result", "tile failure"), under
  // mu_: the worker, the job and the lease the report names, the lease released whether or not
  // the report counts. NOT_FOUND for an unknown worker; a violation (INVALID_ARGUMENT) for a
  // malformed token, and for the token of its current lease with another job or tile (the lease
  // is then kept); NotHolder's answer when the tile is not (or no longer) under this worker's
  // lease.
  struct HeldLease {
    Worker* worker = nullptr;
    Job* job = nullptr;
    const TileLeaseInfo* lease = nullptr;
    LeaseToken token;
  };
  absl::StatusOr<HeldLease> ReleaseHeldLease(uint32_t worker_id, const std::string& token_bytes,
                                             const std::string& job_id, int tile,
                                             const std::string& what);
  void TileFailedOn(const Worker& worker);
  bool Quarantined(const Worker& worker, SteadyTime now) const;
  // The workers other than `worker_id` that could take a lease now.
  std::vector<uint32_t> OtherEligibleWorkers(uint32_t worker_id, SteadyTime now) const;
  void TryAssign(uint32_t worker_id, Worker& worker, std::vector<v1::CoordinatorMessage>* out);
  void FinishJob(Job& job, v1::JobState state, const std::string& error);
  // Removes job `id` from the store, then from memory (mu_ NOT held); the store's error (its
  // code, the reason) when it failed.
  absl::Status RemoveJob(const std::string& id);
  // When `job` starts: merges the records of earlier jobs of the same sensor-free scene and
  // record settings (cache_seed.h) into its cache, so its workers get them on joining.
  void SeedCache(Job& job);
  // Something changed that any worker's Poll or WaitForChange may act on: wakes them all.
  void Changed();
  // Something changed for `worker` alone (its outbox, its lease) or, with null, for job views
  // only (record counts): wakes the WaitForChange callers and that worker's Poll, not the other
  // workers' Polls.
  void Touched(Worker* worker);
  static void WakeWorker(Worker& worker) {
    ++worker.wake->seq;
    worker.wake->cv.notify_one();
  }
  // Queues `records` (origins set) for `worker` in job `job_id`, appended to the last message of
  // its outbox when that is a records message of the job with room left; returns the payload
  // bytes added. Wakes the worker when its outbox was empty (later appends ride along).
  size_t QueueRecords(Worker& worker, const std::string& job_id,
                      const std::vector<IrradianceRecord>& records);
  // Whether fan-out to `worker` is filtered by its regions.
  bool Filtered(const Worker& worker) const {
    return options_.filter_fanout && worker.reports_regions;
  }
  // Rebuilds job.index and job.unfiltered from job.workers and job.regions.
  void RebuildIndex(Job& job);
  // Queues a fan-out batch of `records` (sent by another worker) for `other`, or drops it when
  // its outbox is over max_outbox_bytes; counts it. Returns the records delivered or dropped.
  size_t Deliver(Job& job, uint32_t other, const std::vector<IrradianceRecord>& records);
  // Fan-out bytes `w`'s outbox may still take: its outbox and in-flight bytes within
  // max_outbox_bytes, and everyone's within max_total_outbox_bytes. mu_ held.
  size_t OutboxRoom(const Worker& w) const;
  // The scene of job `id` (nullopt: not held, or none), for the writer's state changes that the
  // store refuses because it lost the scene (StoreWriter::SceneOf). Takes mu_; copies the scene
  // under it (only after the store lost data).
  std::optional<v1::SceneSource> SceneOf(const std::string& id) const;
  // A tile or record write the store refused NOT_FOUND (JobStore: it holds no such job): when the
  // job still runs here, the store lost it (FLUSHALL, eviction), so the job is written again and
  // `retry` run once; else NOT_FOUND. mu_ not held.
  absl::Status RestoreLostJob(const std::string& job_id,
                              const std::function<absl::Status()>& retry);
  // `bytes` of `w`'s queued fan-out left its outbox (sent, dropped, or the worker gone). mu_ held.
  void TakeOutboxBytes(Worker& w, size_t bytes);
  // What the last Poll handed `w`'s writer is written (or the worker is gone). mu_ held.
  void ReleaseInFlight(Worker& w);
  // Records withheld from `worker_id` in `job` since its tally was settled (Job::Tally).
  static uint64_t Unsettled(const Job& job, const Job::Tally& t) {
    return job.offered_total - t.total_mark - t.own - t.handled;
  }
  // Counts what was withheld from each filtered worker of `job` (or only `worker_id`, with
  // `erase` its tally removed: it left the job) since the last settlement.
  void SettleWithheld(Job& job);
  void SettleWithheld(Job& job, uint32_t worker_id, bool erase);
  // Counts records delivered to / withheld from `worker_id` for `job` (backlog: delivered ones
  // that had been withheld).
  void CountFanout(Job& job, uint32_t worker_id, Worker& worker, size_t delivered, size_t withheld,
                   size_t backlog);
  // The denoiser, loaded on first use (thread-safe); its error says why it is unavailable.
  absl::StatusOr<const Denoiser*> GetDenoiser() const;

  const JobManagerOptions options_;
  JobStore* const store_;
  std::unique_ptr<MetricsRegistry> own_registry_;  // when Create was given none
  MetricsRegistry* registry_;
  uint64_t collector_ = 0;  // registry_'s handle of CollectMetrics
  CoordinatorMetrics metrics_;
  std::unique_ptr<StoreWriter> writer_;  // job-state writes, off the lock
  mutable std::mutex mu_;
  mutable std::condition_variable changed_cv_;  // any change (WaitForChange, Poll)
  uint64_t version_ = 0;
  size_t total_outbox_bytes_ = 0;  // sum of the workers' outbox_bytes and in_flight_bytes
  uint64_t next_sequence_ = 1;
  uint32_t next_worker_ = 1;
  std::map<std::string, std::unique_ptr<Job>> jobs_;
  std::set<std::string> reserved_ids_;  // jobs being submitted (stored, not yet in jobs_)
  // Submits in progress per client (past the live-job check, not yet in jobs_): they count
  // against max_live_jobs_per_client, so parallel submits cannot pass the check together.
  std::map<std::string, int> submitting_;
  std::map<uint32_t, Worker> workers_;
  std::map<std::string, WorkerHealth> health_;  // by worker name
  uint64_t violations_total_ = 0, expelled_total_ = 0;
  mutable std::mutex denoiser_mu_;  // guards the two below; OIDN filters run one at a time
  mutable std::unique_ptr<Denoiser> denoiser_;
  mutable absl::Status denoiser_error_;
};

}  // namespace irfarm
