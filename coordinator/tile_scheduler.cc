// TileScheduler: tiles, leases, deadlines and retries of one job (see tile_scheduler.h).
#include "coordinator/tile_scheduler.h"

#include <algorithm>
#include <cstdlib>
#include <limits>

namespace irfarm {

TileScheduler::TileScheduler(int width, int height, int tile_size, const TileRetryPolicy& policy)
    : policy_(policy) {
  policy_.failure_workers = std::max(1, policy_.failure_workers);
  policy_.max_attempts = std::max(1, policy_.max_attempts);
  tile_size = std::max(1, tile_size);
  tiles_x_ = (width + tile_size - 1) / tile_size;
  for (int y = 0; y < height; y += tile_size)
    for (int x = 0; x < width; x += tile_size)
      rects_.push_back(
          PixelRect{x, y, std::min(width, x + tile_size), std::min(height, y + tile_size)});
  num_tiles_ = int(rects_.size());
  state_.assign(rects_.size(), State::kPending);
  failures_.assign(rects_.size(), 0);
  failed_on_.resize(rects_.size());
  for (int i = 0; i < num_tiles(); ++i) pending_.push_back(i);
}

std::optional<TileLeaseInfo> TileScheduler::Lease(uint32_t worker, SteadyTime now,
                                                  std::chrono::milliseconds lease_time,
                                                  const std::vector<uint32_t>& others, int near) {
  auto chosen = pending_.end();
  if (near >= num_tiles()) near = -1;
  int best = std::numeric_limits<int>::max();  // squared grid distance of a far `chosen` to near
  for (auto it = pending_.begin(); it != pending_.end(); ++it) {
    const std::set<uint32_t>& failed = failed_on_[size_t(*it)];
    if (failed.count(worker) &&
        std::any_of(others.begin(), others.end(), [&](uint32_t o) { return !failed.count(o); }))
      continue;                                 // a worker it has not failed on will take it
    if (chosen == pending_.end()) chosen = it;  // the first eligible, if none is far
    bool far = true;
    for (const TileLeaseInfo& l : leases_) {
      const int dx = std::abs(*it % tiles_x_ - l.tile % tiles_x_);
      const int dy = std::abs(*it / tiles_x_ - l.tile / tiles_x_);
      if (std::max(dx, dy) < 2) far = false;
    }
    if (!far) continue;
    if (near < 0) {
      chosen = it;
      break;
    }
    const int dx = *it % tiles_x_ - near % tiles_x_, dy = *it / tiles_x_ - near / tiles_x_;
    if (dx * dx + dy * dy < best) {
      best = dx * dx + dy * dy;
      chosen = it;
    }
  }
  if (chosen == pending_.end()) return std::nullopt;
  TileLeaseInfo lease{*chosen, LeaseToken::Random(), worker, now, now + lease_time};
  pending_.erase(chosen);
  state_[size_t(lease.tile)] = State::kLeased;
  leases_.push_back(lease);
  return lease;
}

const TileLeaseInfo* TileScheduler::Current(int tile, const LeaseToken& token) const {
  for (const TileLeaseInfo& l : leases_)
    if (l.tile == tile && l.token == token) return &l;
  return nullptr;
}

absl::Status TileScheduler::Complete(int tile, const LeaseToken& token) {
  auto it = std::find_if(leases_.begin(), leases_.end(), [&](const TileLeaseInfo& l) {
    return l.tile == tile && l.token == token;
  });
  if (it == leases_.end())
    return absl::FailedPreconditionError("tile " + std::to_string(tile) +
                                         ": that lease is not current");
  leases_.erase(it);
  state_[size_t(tile)] = State::kDone;
  ++done_count_;
  return absl::OkStatus();
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

absl::Status TileScheduler::Requeue(int tile, const LeaseToken& token, const std::string& reason,
                                    bool count_failure) {
  auto it = std::find_if(leases_.begin(), leases_.end(), [&](const TileLeaseInfo& l) {
    return l.tile == tile && l.token == token;
  });
  if (it == leases_.end()) return absl::OkStatus();  // already completed or requeued
  const uint32_t worker = it->worker;
  leases_.erase(it);
  state_[size_t(tile)] = State::kPending;
  pending_.push_front(tile);
  if (!count_failure) return absl::OkStatus();
  std::set<uint32_t>& on = failed_on_[size_t(tile)];
  on.insert(worker);
  ++failures_[size_t(tile)];
  if (int(on.size()) >= policy_.failure_workers || failures_[size_t(tile)] >= policy_.max_attempts)
    return absl::AbortedError("tile " + std::to_string(tile) + " failed " +
                              std::to_string(failures_[size_t(tile)]) + " times on " +
                              std::to_string(on.size()) + " workers (last: " + reason + ")");
  return absl::OkStatus();
}

absl::Status TileScheduler::ReleaseWorker(uint32_t worker, const std::string& reason,
                                          bool count_failure) {
  absl::Status result;
  const std::vector<TileLeaseInfo> leases = leases_;
  for (const TileLeaseInfo& l : leases)
    if (l.worker == worker) result.Update(Requeue(l.tile, l.token, reason, count_failure));
  return result;
}

absl::Status TileScheduler::ExpireLeases(SteadyTime now) {
  absl::Status result;
  const std::vector<TileLeaseInfo> leases = leases_;
  for (const TileLeaseInfo& l : leases)
    if (l.deadline < now)
      result.Update(Requeue(l.tile, l.token,
                            "worker " + std::to_string(l.worker) + " missed the lease deadline"));
  return result;
}

void TileScheduler::Clear() {
  std::vector<TileLeaseInfo>().swap(leases_);
  std::deque<int>().swap(pending_);
  std::vector<int>().swap(failures_);
  std::vector<std::set<uint32_t>>().swap(failed_on_);
}

std::vector<uint32_t> TileScheduler::LeaseHolders() const {
  std::vector<uint32_t> w;
  for (const TileLeaseInfo& l : leases_) w.push_back(l.worker);
  return w;
}

}  // namespace irfarm
