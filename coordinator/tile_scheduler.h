// TileScheduler: the tiles of one job and who renders them. The image is cut into square tiles
// (many more than workers, so a slow or lost worker costs little); a worker leases one tile at a
// time until a deadline. A tile whose worker dies or misses its deadline goes back to the front
// of the queue; after max_attempts failed attempts the job fails with the reason. Not
// thread-safe: JobManager serialises access.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "render/renderer.h"

namespace irfarm {

using SteadyTime = std::chrono::steady_clock::time_point;

struct TileLeaseInfo {
  int tile = -1;
  uint64_t lease_id = 0;
  uint32_t worker = 0;
  SteadyTime deadline;
};

class TileScheduler {
 public:
  TileScheduler(int width, int height, int tile_size, int max_attempts);

  int num_tiles() const { return int(rects_.size()); }
  int num_done() const { return done_count_; }
  bool all_done() const { return done_count_ == num_tiles(); }
  bool has_pending() const { return !pending_.empty(); }
  const PixelRect& rect(int tile) const { return rects_[size_t(tile)]; }
  bool is_done(int tile) const { return state_[size_t(tile)] == State::kDone; }

  // Leases a pending tile to `worker`, preferring one at least two tiles away from every tile
  // leased now (so concurrent workers compute fewer overlapping records). nullopt when none is
  // pending. Lease ids are unique per scheduler.
  std::optional<TileLeaseInfo> Lease(uint32_t worker, SteadyTime now,
                                     std::chrono::milliseconds lease_time);

  // The tile's result arrived under `lease_id`. FAILED_PRECONDITION when that lease is no longer
  // current (expired and re-leased, or the tile is done): the result is then ignored.
  absl::Status Complete(int tile, uint64_t lease_id);
  // True while `lease_id` is the tile's current lease.
  bool IsCurrent(int tile, uint64_t lease_id) const;
  // Marks a tile done without a lease (restoring finished tiles from a store).
  void MarkDone(int tile);

  // Puts the tile of a lease back in the queue, counting a failed attempt. Returns an error
  // (the job must fail) when the tile has now failed max_attempts times.
  absl::Status Requeue(int tile, uint64_t lease_id, const std::string& reason);
  // Requeues every tile leased to `worker` (its stream broke).
  absl::Status ReleaseWorker(uint32_t worker, const std::string& reason);
  // Requeues every lease whose deadline is before `now`.
  absl::Status ExpireLeases(SteadyTime now);
  // Drops every lease and pending tile (cancelled or failed job).
  void Clear();
  // Workers holding a lease now.
  std::vector<uint32_t> LeaseHolders() const;

 private:
  enum class State { kPending, kLeased, kDone };
  int tiles_x_ = 0;
  std::vector<PixelRect> rects_;
  std::vector<State> state_;
  std::vector<int> failures_;
  std::vector<TileLeaseInfo> leases_;  // current leases
  std::deque<int> pending_;
  int done_count_ = 0;
  int max_attempts_;
  uint64_t next_lease_id_ = 1;
};

}  // namespace irfarm
