// TileScheduler: tiles, leases, deadlines and retries of one job (see tile_scheduler.h).
#include "coordinator/tile_scheduler.h"

#include <algorithm>
#include <cstdlib>

namespace irfarm {

TileScheduler::TileScheduler(int width, int height, int tile_size, int max_attempts)
    : max_attempts_(std::max(1, max_attempts)) {
  tile_size = std::max(1, tile_size);
  tiles_x_ = (width + tile_size - 1) / tile_size;
  for (int y = 0; y < height; y += tile_size)
    for (int x = 0; x < width; x += tile_size)
      rects_.push_back(
          PixelRect{x, y, std::min(width, x + tile_size), std::min(height, y + tile_size)});
  state_.assign(rects_.size(), State::kPending);
  failures_.assign(rects_.size(), 0);
  for (int i = 0; i < num_tiles(); ++i) pending_.push_back(i);
}

std::optional<TileLeaseInfo> TileScheduler::Lease(uint32_t worker, SteadyTime now,
                                                  std::chrono::milliseconds lease_time) {
  if (pending_.empty()) return std::nullopt;
  auto chosen = pending_.begin();
  for (auto it = pending_.begin(); it != pending_.end(); ++it) {
    bool far = true;
    for (const TileLeaseInfo& l : leases_) {
      const int dx = std::abs(*it % tiles_x_ - l.tile % tiles_x_);
      const int dy = std::abs(*it / tiles_x_ - l.tile / tiles_x_);
      if (std::max(dx, dy) < 2) far = false;
    }
    if (far) {
      chosen = it;
      break;
    }
  }
  TileLeaseInfo lease{*chosen, next_lease_id_++, worker, now + lease_time};
  pending_.erase(chosen);
  state_[size_t(lease.tile)] = State::kLeased;
  leases_.push_back(lease);
  return lease;
}

absl::Status TileScheduler::Complete(int tile, uint64_t lease_id) {
  auto it = std::find_if(leases_.begin(), leases_.end(), [&](const TileLeaseInfo& l) {
    return l.tile == tile && l.lease_id == lease_id;
  });
  if (it == leases_.end())
    return absl::FailedPreconditionError("tile " + std::to_string(tile) + " lease " +
                                         std::to_string(lease_id) + " is not current");
  leases_.erase(it);
  state_[size_t(tile)] = State::kDone;
  ++done_count_;
  return absl::OkStatus();
}

bool TileScheduler::IsCurrent(int tile, uint64_t lease_id) const {
  return std::any_of(leases_.begin(), leases_.end(), [&](const TileLeaseInfo& l) {
    return l.tile == tile && l.lease_id == lease_id;
  });
}

void TileScheduler::MarkDone(int tile) {
  if (tile < 0 || tile >= num_tiles() || state_[size_t(tile)] == State::kDone) return;
  pending_.erase(std::remove(pending_.begin(), pending_.end(), tile), pending_.end());
  leases_.erase(std::remove_if(leases_.begin(), leases_.end(),
                               [&](const TileLeaseInfo& l) { return l.tile == tile; }),
                leases_.end());
  state_[size_t(tile)] = State::kDone;
  ++done_count_;
}

absl::Status TileScheduler::Requeue(int tile, uint64_t lease_id, const std::string& reason) {
  auto it = std::find_if(leases_.begin(), leases_.end(), [&](const TileLeaseInfo& l) {
    return l.tile == tile && l.lease_id == lease_id;
  });
  if (it == leases_.end()) return absl::OkStatus();  // already completed or requeued
  leases_.erase(it);
  state_[size_t(tile)] = State::kPending;
  pending_.push_front(tile);
  if (++failures_[size_t(tile)] >= max_attempts_)
    return absl::AbortedError("tile " + std::to_string(tile) + " failed " +
                              std::to_string(failures_[size_t(tile)]) + " times (last: " + reason +
                              ")");
  return absl::OkStatus();
}

absl::Status TileScheduler::ReleaseWorker(uint32_t worker, const std::string& reason) {
  absl::Status result;
  const std::vector<TileLeaseInfo> leases = leases_;
  for (const TileLeaseInfo& l : leases)
    if (l.worker == worker) result.Update(Requeue(l.tile, l.lease_id, reason));
  return result;
}

absl::Status TileScheduler::ExpireLeases(SteadyTime now) {
  absl::Status result;
  const std::vector<TileLeaseInfo> leases = leases_;
  for (const TileLeaseInfo& l : leases)
    if (l.deadline < now)
      result.Update(Requeue(l.tile, l.lease_id,
                            "worker " + std::to_string(l.worker) + " missed the lease deadline"));
  return result;
}

void TileScheduler::Clear() {
  leases_.clear();
  pending_.clear();
}

std::vector<uint32_t> TileScheduler::LeaseHolders() const {
  std::vector<uint32_t> w;
  for (const TileLeaseInfo& l : leases_) w.push_back(l.worker);
  return w;
}

}  // namespace irfarm
