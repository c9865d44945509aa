// CoordinatorLease: which of several coordinators on one Redis is the active one (`--ha`). The
// active coordinator holds a lease: the Redis key PREFIX "coordinator_lease", whose value is its
// owner id (random, unique per process, followed by its listen address for the logs) and which
// expires after `ttl` unless renewed. A standby polls TryAcquire until the key is free, then
// loads the jobs and serves; the active renews every `renew_every` (well within ttl), with a
// compare-and-set (a Lua script: PEXPIRE only while GET == owner), so a coordinator that lost
// the lease never extends someone else's.
//
// Timing: with the defaults (ttl 3 s, renew every 1 s, poll every 250 ms) a standby takes over
// at most ttl + poll = 3.25 s after the active one stops renewing (killed, hung, cut off).
// The active counts the lease as lost when Redis names another owner (or none: the key expired
// or was deleted), or when no renewal succeeded for ttl, measured from the moment the last
// successful renewal was sent (Redis starts its ttl later, when it runs the command, so the
// local view ends first). The lease alone does not fence writes already on their way; the job
// store checks the owner atomically in every write (RedisOptions::fence_owner), so a coordinator
// that lost the lease cannot write even before it notices.
//
// Uses a Redis connection of its own (RedisJobStore's may be busy with a long start-up load,
// which must not delay a renewal). Each command gives up after `timeout` (UNAVAILABLE) and the
// next one reconnects. Thread-safe: Start runs the renewals on a thread of its own.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

struct redisContext;

namespace irfarm {

struct LeaseOptions {
  std::string key = "irfarm:coordinator_lease";
  std::chrono::milliseconds ttl{3000};
  std::chrono::milliseconds renew_every{1000};  // < ttl / 2, so one lost renewal is survived
  std::chrono::milliseconds timeout{500};       // deadline of one Redis command
};

class CoordinatorLease {
 public:
  // `address` is Redis's host:port; `owner` must be unique among the coordinators (NewOwnerId).
  // INVALID_ARGUMENT for a bad address or renew_every >= ttl; does not connect yet.
  static absl::StatusOr<std::unique_ptr<CoordinatorLease>> Create(const std::string& address,
                                                                  std::string owner,
                                                                  const LeaseOptions& options);
  // Stops the renewals (does not release: see Release).
  ~CoordinatorLease();
  CoordinatorLease(const CoordinatorLease&) = delete;
  CoordinatorLease& operator=(const CoordinatorLease&) = delete;

  // One attempt to take the lease (SET NX PX): true when this coordinator holds it now, false
  // when another does (its owner id in *holder when given); UNAVAILABLE when Redis did not
  // answer.
  absl::StatusOr<bool> TryAcquire(std::string* holder = nullptr);
  // Extends the lease by ttl if this coordinator still holds it (compare-and-set, atomic on the
  // Redis server). FAILED_PRECONDITION naming the holder when it does not; UNAVAILABLE when Redis
  // did not answer.
  absl::Status Renew();
  // Stops the renewals and deletes the lease if this coordinator holds it (compare-and-delete),
  // so that a standby takes over at once after a graceful shutdown instead of after ttl. Not
  // from `on_lost`.
  absl::Status Release();

  // After a successful TryAcquire: renews every renew_every on a thread of its own until the
  // lease is lost (then calls `on_lost` once, with the reason, from that thread, and stops) or
  // this object is destroyed. `acquired_at` is when the TryAcquire that succeeded was sent.
  void Start(std::chrono::steady_clock::time_point acquired_at,
             std::function<void(const std::string& why)> on_lost);
  // True from a successful TryAcquire until the lease is lost.
  bool held() const { return held_.load(); }
  const std::string& owner() const { return owner_; }
  const LeaseOptions& options() const { return options_; }

 private:
  CoordinatorLease(std::string host, int port, std::string owner, const LeaseOptions& options)
      : host_(std::move(host)), port_(port), owner_(std::move(owner)), options_(options) {}
  // mu_ held: connects if needed and runs one command (argv), returning its reply's type and
  // value: an integer, a string (bulk or status) or nil.
  struct Reply {
    bool nil = false;
    long long integer = 0;
    std::string text;
  };
  absl::StatusOr<Reply> Command(const std::vector<std::string>& argv);
  void Drop();  // mu_ held
  void StopRenewing();
  void RenewLoop(std::chrono::steady_clock::time_point last_ok,
                 std::function<void(const std::string&)> on_lost);

  const std::string host_;
  const int port_;
  const std::string owner_;
  const LeaseOptions options_;
  std::mutex mu_;  // the connection
  redisContext* ctx_ = nullptr;
  std::atomic<bool> held_{false};
  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  bool stop_ = false;
  std::thread renewer_;
};

// A fresh owner id: 128 random bits (hex) and `label` (e.g. the listen address), for the logs.
std::string NewOwnerId(const std::string& label);

}  // namespace irfarm
