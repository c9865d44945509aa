// TileScheduler: the tiles of one job and who renders them. The image is cut into square tiles
// (many more than workers, so a slow or lost worker costs little); a worker leases one tile at a
// time until a deadline, under a random, unguessable lease token (128 bits from the kernel's
// CSPRNG, lease_token.h) bound to that worker: a result is accepted only from the lease's holder. A
// tile whose worker fails it, dies or misses its deadline goes back to the front of the queue, but
// is leased to a worker it has not failed on first; the job fails only when the tile failed on
// `failure_workers` distinct workers, or `max_attempts` times in all (a single worker left).
// Not thread-safe: JobManager serialises access.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "coordinator/lease_token.h"
#include "render/renderer.h"

namespace irfarm {

using SteadyTime = std::chrono::steady_clock::time_point;

struct TileLeaseInfo {
  int tile = -1;
  LeaseToken token;
  uint32_t worker = 0;
  SteadyTime start, deadline;
};

struct TileRetryPolicy {
  int failure_workers = 3;  // a tile failing on this many distinct workers fails the job
  int max_attempts = 10;    // ... or failing this many times in all
};

class TileScheduler {
 public:
  TileScheduler(int width, int height, int tile_size, const TileRetryPolicy& policy);

  int num_tiles() const { return num_tiles_; }
  int num_done() const { return done_count_; }
  bool all_done() const { return done_count_ == num_tiles(); }
  bool has_pending() const { return !pending_.empty(); }
  const PixelRect& rect(int tile) const { return rects_[size_t(tile)]; }
  bool is_done(int tile) const { return state_[size_t(tile)] == State::kDone; }

  // Leases a pending tile to `worker`, preferring one at least two tiles away from every tile
  // leased now (so concurrent workers compute fewer overlapping records). A tile that failed on
  // `worker` is skipped while one of `others` (the other workers that could take a lease) has
  // not failed it. With `near` (the worker's previous tile of this job, -1: none), the far tile
  // nearest to it is taken instead of the first (ties: queue order), so each worker's tiles stay
  // together and see one part of the scene: what makes filtered record fan-out pay
  // (fanout_region.h). nullopt when no tile is pending for this worker.
  std::optional<TileLeaseInfo> Lease(uint32_t worker, SteadyTime now,
                                     std::chrono::milliseconds lease_time,
                                     const std::vector<uint32_t>& others = {}, int near = -1);

  // The current lease of `tile` with `token`, or nullptr (expired and re-leased, done, never, or
  // a wrong token).
  const TileLeaseInfo* Current(int tile, const LeaseToken& token) const;
  // The tile's result arrived under `token`. FAILED_PRECONDITION when that lease is no longer
  // current: the result is then ignored.
  absl::Status Complete(int tile, const LeaseToken& token);
  // Marks a tile done without a lease (restoring finished tiles from a store).
  void MarkDone(int tile);

  // Puts the tile of a lease back in the queue. With `count_failure` the attempt counts against
  // the tile (the worker failed it, died or missed the deadline); a worker that only went silent
  // does not count. Returns an error (the job must fail) when the tile has now failed on
  // failure_workers distinct workers or max_attempts times.
  absl::Status Requeue(int tile, const LeaseToken& token, const std::string& reason,
                       bool count_failure = true);
  // Requeues every tile leased to `worker`.
  absl::Status ReleaseWorker(uint32_t worker, const std::string& reason, bool count_failure);
  // Requeues every lease whose deadline is before `now`.
  absl::Status ExpireLeases(SteadyTime now);
  // Drops every lease and pending tile and the per-tile bookkeeping (cancelled, failed or
  // finished job); rect() stays valid for a finished image.
  void Clear();
  // Workers holding a lease now.
  std::vector<uint32_t> LeaseHolders() const;

 private:
  enum class State : uint8_t { kPending, kLeased, kDone };
  int tiles_x_ = 0, num_tiles_ = 0;
  std::vector<PixelRect> rects_;
  std::vector<State> state_;
  std::vector<int> failures_;
  std::vector<std::set<uint32_t>> failed_on_;  // workers each tile failed on
  std::vector<TileLeaseInfo> leases_;          // current leases
  std::deque<int> pending_;
  int done_count_ = 0;
  TileRetryPolicy policy_;
};

}  // namespace irfarm
