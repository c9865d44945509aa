// JobContext: what a worker keeps per job while it renders the job's tiles: the scene (the bundle
// written to a private temp dir, loaded and built once), the render settings and the local
// IrradianceCache that holds the worker's own records (origin 0) and those received from other
// workers (origin = the sender's id). Knows which of its own records it has not published yet.
#pragma once

#include <algorithm>
#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "cache/irradiance_cache.h"
#include "irfarm/v1/worker.pb.h"
#include "render/record_bounds.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace irfarm {

// `origin` for received records that carry none (never 0: 0 means "computed here").
constexpr uint32_t kUnknownRemoteOrigin = 0xfffffffeu;
// Records a job's local cache takes from the coordinator: the coordinator's own limit per job
// (JobLimits::max_job_records); past it received records are dropped (and counted).
constexpr size_t kMaxRemoteRecords = size_t(1) << 24;

class JobContext {
 public:
  // The longest job id a worker takes ([A-Za-z0-9_.-]; it names the job's temp dir).
  static constexpr size_t kMaxIdLength = 64;
  // Writes the bundle (if any) to a temp dir, loads and builds the scene. The job id must be
  // [A-Za-z0-9_.-]{1,64} (it names the temp dir).
  static absl::StatusOr<std::unique_ptr<JobContext>> Create(const v1::JobSpec& spec, int threads);
  ~JobContext();

  const std::string& job_id() const { return job_id_; }
  const Scene& scene() const { return *scene_; }
  const RenderSettings& settings() const { return settings_; }
  IrradianceCache* cache() const { return cache_.get(); }
  // Warm-started (JobSpec.warm_cache): its tiles wait for their regions' records (RegionReady).
  bool warm() const { return warm_; }
  // The job's tile edge (JobTileSize): no lease covers more than this square.
  int tile_size() const { return tile_size_; }

  // Inserts other workers' records (validated; at most kMaxRemoteRecords in all); returns how
  // many were inserted.
  size_t InsertRemote(const std::vector<IrradianceRecord>& records);
  // Own camera records (origin 0, level 0) computed since the last call, oldest first, at most
  // `max` of them (the rest wait for the next call).
  std::vector<IrradianceRecord> TakeNewOwnRecords(size_t max);
  // Records received since the last call (for the next tile's stats).
  uint64_t TakeReceivedCount() { return received_since_.exchange(0); }
  // Records from the coordinator dropped by InsertRemote (outside the scene's RecordBounds, or
  // past kMaxRemoteRecords).
  uint64_t rejected() const { return rejected_.load(); }

  // Adaptive sampling's budget (RenderSettings::budget_carry): what this worker's earlier tiles
  // left unspent (tiles of walls stop at the sampling goal), offered whole to its next tile,
  // which gives back what it did not use (RenderStats::budget_left).
  double TakeBudgetCarry() { return budget_carry_.exchange(0); }
  void AddBudgetCarry(double work) {
    double now = budget_carry_.load();
    while (!budget_carry_.compare_exchange_weak(now, now + std::max(0.0, work))) {
    }
  }

 private:
  JobContext() = default;
  std::string job_id_, dir_;
  bool warm_ = false;
  int tile_size_ = 0;
  size_t remote_ = 0;  // records InsertRemote inserted (one reader thread calls it)
  std::unique_ptr<Scene> scene_;
  // The job's caustic photon map, built once for all of its tiles (settings_.irrcache.caustics
  // points here); null where the job uses none.
  std::unique_ptr<CausticMap> caustics_;
  RenderSettings settings_;
  std::unique_ptr<IrradianceCache> cache_;
  std::mutex publish_mu_;
  // TakeNewOwnRecords: the cache's mark of the newest record it has looked at
  // (IrradianceCache::ForEachNewer), and the own records seen but not yet taken, oldest first.
  uint64_t seen_mark_ = 0;
  std::deque<IrradianceRecord> unpublished_;
  std::atomic<uint64_t> received_since_{0};
  std::atomic<uint64_t> rejected_{0};
  RecordBounds record_bounds_;
  std::atomic<double> budget_carry_{0};
};

}  // namespace irfarm
