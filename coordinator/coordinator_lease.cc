// CoordinatorLease: SET NX PX to acquire, compare-and-set renewal and release (see the header).
#include "coordinator/coordinator_lease.h"

#include <hiredis/hiredis.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <random>

namespace irfarm {
namespace {

// KEYS[1] the lease, ARGV[1] the owner id, ARGV[2] the ttl in ms: 1 when renewed, else 0.
constexpr char kRenewScript[] =
    "if redis.call('GET', KEYS[1]) == ARGV[1] then "
    "return redis.call('PEXPIRE', KEYS[1], ARGV[2]) else return 0 end";
// KEYS[1] the lease, ARGV[1] the owner id: 1 when deleted, else 0.
constexpr char kReleaseScript[] =
    "if redis.call('GET', KEYS[1]) == ARGV[1] then "
    "return redis.call('DEL', KEYS[1]) else return 0 end";

timeval ToTimeval(std::chrono::milliseconds t) {
  return timeval{time_t(t.count() / 1000), suseconds_t((t.count() % 1000) * 1000)};
}

}  // namespace

std::string NewOwnerId(const std::string& label) {
  std::random_device random;
  char hex[33];
  std::snprintf(hex, sizeof hex, "%08x%08x%08x%08x", random(), random(), random(), random());
  return std::string(hex) + " " + label;
}

absl::StatusOr<std::unique_ptr<CoordinatorLease>> CoordinatorLease::Create(
    const std::string& address, std::string owner, const LeaseOptions& options) {
  const size_t colon = address.rfind(':');
  int port = 0;
  if (colon != std::string::npos) port = std::atoi(address.c_str() + colon + 1);
  if (colon == std::string::npos || port <= 0 || port > 65535)
    return absl::InvalidArgumentError("--redis expects HOST:PORT, got '" + address + "'");
  if (owner.empty()) return absl::InvalidArgumentError("lease owner id is empty");
  if (options.ttl.count() <= 0 || options.renew_every >= options.ttl)
    return absl::InvalidArgumentError(
        "lease: renewal every " + std::to_string(options.renew_every.count()) +
        " ms must be shorter than its ttl " + std::to_string(options.ttl.count()) + " ms");
  return std::unique_ptr<CoordinatorLease>(
      new CoordinatorLease(address.substr(0, colon), port, std::move(owner), options));
}

CoordinatorLease::~CoordinatorLease() {
  StopRenewing();
  std::lock_guard<std::mutex> lock(mu_);
  Drop();
}

void CoordinatorLease::StopRenewing() {
  {
    std::lock_guard<std::mutex> lock(stop_mu_);
    stop_ = true;
  }
  stop_cv_.notify_all();
  if (renewer_.joinable() && renewer_.get_id() != std::this_thread::get_id()) renewer_.join();
}

void CoordinatorLease::Drop() {
  if (ctx_) redisFree(ctx_);
  ctx_ = nullptr;
}

absl::StatusOr<CoordinatorLease::Reply> CoordinatorLease::Command(
    const std::vector<std::string>& argv) {
  const std::string where = "redis " + host_ + ":" + std::to_string(port_);
  if (ctx_ == nullptr || ctx_->err != 0) {
    Drop();
    ctx_ = redisConnectWithTimeout(host_.c_str(), port_, ToTimeval(options_.timeout));
    if (ctx_ == nullptr || ctx_->err != 0) {
      const std::string why = ctx_ ? ctx_->errstr : "out of memory";
      Drop();
      return absl::UnavailableError(where + ": " + why);
    }
    redisSetTimeout(ctx_, ToTimeval(options_.timeout));
  }
  std::vector<const char*> args;
  std::vector<size_t> lengths;
  for (const std::string& a : argv) {
    args.push_back(a.data());
    lengths.push_back(a.size());
  }
  redisReply* raw = static_cast<redisReply*>(
      redisCommandArgv(ctx_, int(args.size()), args.data(), lengths.data()));
  if (raw == nullptr) {
    const std::string why = ctx_->errstr;
    Drop();
    return absl::UnavailableError(where + ": " + why);
  }
  Reply reply;
  absl::Status status = absl::OkStatus();
  switch (raw->type) {
    case REDIS_REPLY_INTEGER:
      reply.integer = raw->integer;
      break;
    case REDIS_REPLY_STRING:
    case REDIS_REPLY_STATUS:
      reply.text.assign(raw->str, raw->len);
      break;
    case REDIS_REPLY_NIL:
      reply.nil = true;
      break;
    case REDIS_REPLY_ERROR:
      status = absl::UnavailableError(where + ": " + std::string(raw->str, raw->len));
      break;
    default:
      status = absl::InternalError(where + ": unexpected reply type " + std::to_string(raw->type));
  }
  freeReplyObject(raw);
  if (!status.ok()) return status;
  return reply;
}

absl::StatusOr<bool> CoordinatorLease::TryAcquire(std::string* holder) {
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<Reply> set =
      Command({"SET", options_.key, owner_, "NX", "PX", std::to_string(options_.ttl.count())});
  if (!set.ok()) return set.status();
  if (!set->nil) {  // "OK": ours now
    held_ = true;
    return true;
  }
  if (holder != nullptr) {
    absl::StatusOr<Reply> get = Command({"GET", options_.key});
    *holder = get.ok() && !get->nil ? get->text : "(expired meanwhile)";
  }
  return false;
}

absl::Status CoordinatorLease::Renew() {
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<Reply> renew = Command(
      {"EVAL", kRenewScript, "1", options_.key, owner_, std::to_string(options_.ttl.count())});
  if (!renew.ok()) return renew.status();
  if (renew->integer == 1) return absl::OkStatus();
  absl::StatusOr<Reply> get = Command({"GET", options_.key});
  const std::string holder = !get.ok()  ? "unknown (" + std::string(get.status().message()) + ")"
                             : get->nil ? "nobody (it expired or was deleted)"
                                        : get->text;
  return absl::FailedPreconditionError("coordinator lease " + options_.key + " is held by " +
                                       holder);
}

absl::Status CoordinatorLease::Release() {
  StopRenewing();
  held_ = false;
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<Reply> del = Command({"EVAL", kReleaseScript, "1", options_.key, owner_});
  return del.ok() ? absl::OkStatus() : del.status();
}

void CoordinatorLease::Start(std::chrono::steady_clock::time_point acquired_at,
                             std::function<void(const std::string& why)> on_lost) {
  renewer_ = std::thread(
      [this, acquired_at, on_lost = std::move(on_lost)] { RenewLoop(acquired_at, on_lost); });
}

void CoordinatorLease::RenewLoop(std::chrono::steady_clock::time_point last_ok,
                                 std::function<void(const std::string&)> on_lost) {
  std::string why;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(stop_mu_);
      if (stop_cv_.wait_for(lock, options_.renew_every, [&] { return stop_; })) return;
    }
    const auto sent = std::chrono::steady_clock::now();
    const absl::Status st = Renew();
    if (st.ok()) {
      last_ok = sent;
      continue;
    }
    if (absl::IsFailedPrecondition(st)) {
      why = std::string(st.message());
      break;
    }
    // Redis did not answer: the lease still counts until ttl after the last renewal was sent.
    if (std::chrono::steady_clock::now() - last_ok >= options_.ttl) {
      why = "not renewed for " + std::to_string(options_.ttl.count()) + " ms (" +
            std::string(st.message()) + ")";
      break;
    }
    spdlog::warn("coordinator lease: renewal failed, retrying: {}", st.ToString());
  }
  held_ = false;
  on_lost(why);
}

}  // namespace irfarm
