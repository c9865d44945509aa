// RedisJobStore: JobStore on hiredis (keys, atomicity and failure behaviour in the header).
#include "coordinator/redis_job_store.h"

#include <algorithm>
#include <chrono>
#include <thread>

#include <hiredis/hiredis.h>
#include <spdlog/spdlog.h>

#include "service/record_codec.h"

namespace irfarm {
namespace {

// Owns a reply; null when the command failed at the connection level.
struct ReplyDeleter {
  void operator()(redisReply* r) const {
    if (r) freeReplyObject(r);
  }
};
using Reply = std::unique_ptr<redisReply, ReplyDeleter>;

timeval ToTimeval(std::chrono::milliseconds t) {
  return timeval{time_t(t.count() / 1000), suseconds_t((t.count() % 1000) * 1000)};
}

// The write scripts (RedisJobStore::Write puts the fence check in front): KEYS[1] / ARGV[1] are
// the lease key and owner id, the job's keys and arguments follow.
constexpr char kFenceCheck[] =
    "if ARGV[1] ~= '' and redis.call('GET', KEYS[1]) ~= ARGV[1] then "
    "return redis.error_reply('FENCED this coordinator does not hold the lease ' .. KEYS[1]) "
    "end ";
constexpr char kIncr[] = "return redis.call('INCR', KEYS[2])";
// The job and its set membership appear together; a deleted job's id is refused (its tombstone,
// KEYS[4]), so a state write that lands late (sent before a delete, on a connection that timed
// out while Redis hung) cannot bring the job back. A state change leaves the upload stored with
// the submit where it is. ARGV[4] says what comes with the state: 'scene' (the scene in ARGV[5],
// written to KEYS[5]), 'state' (an unfinished job's state change: refused, writing nothing, when
// the job is not in the set or its scene's key is gone, Redis flushed or the key evicted: the job
// would come back without a scene) or 'final' (a finished job's state, which needs no scene).
constexpr char kPutJob[] =
    "if ARGV[4] ~= 'scene' and ARGV[4] ~= 'state' and ARGV[4] ~= 'final' then "
    "return redis.error_reply('BADMODE ' .. tostring(ARGV[4])) end "
    "if redis.call('EXISTS', KEYS[4]) == 1 then "
    "return redis.error_reply('GONE job ' .. ARGV[3] .. ' was deleted') end "
    "if ARGV[4] == 'state' and (redis.call('SISMEMBER', KEYS[3], ARGV[3]) == 0 or "
    "redis.call('EXISTS', KEYS[5]) == 0) then "
    "return redis.error_reply('NOSCENE job ' .. ARGV[3] .. ' has no stored scene') end "
    "redis.call('SET', KEYS[2], ARGV[2]) "
    "if ARGV[4] == 'scene' then redis.call('SET', KEYS[5], ARGV[5]) end "
    "redis.call('SADD', KEYS[3], ARGV[3]) return 1";
// A job stored with its scene inside (before the scene had a key of its own) moved to the two
// keys, if the job key still holds what was read (ARGV[2]; a write since then has won).
constexpr char kMoveScene[] =
    "if redis.call('GET', KEYS[2]) ~= ARGV[2] then return 0 end "
    "redis.call('SET', KEYS[3], ARGV[4]) redis.call('SET', KEYS[2], ARGV[3]) return 1";
// Tiles and records are written only for a job in the set (ARGV[4] / ARGV[3]): one that arrives
// after the job was deleted (a worker's result stored while a client deleted the cancelled job)
// would otherwise leave keys nothing ever reads or deletes.
constexpr char kPutTile[] =
    "if redis.call('SISMEMBER', KEYS[3], ARGV[4]) == 0 then "
    "return redis.error_reply('GONE no job ' .. ARGV[4]) end "
    "return redis.call('HSET', KEYS[2], ARGV[2], ARGV[3])";
constexpr char kAppend[] =
    "if redis.call('SISMEMBER', KEYS[3], ARGV[3]) == 0 then "
    "return redis.error_reply('GONE no job ' .. ARGV[3]) end "
    "return redis.call('RPUSH', KEYS[2], ARGV[2])";
// The job leaves the set together with its keys (a restart never sees half), and leaves a
// tombstone for a day (job ids are never reused: the counter).
constexpr char kDeleteJob[] =
    "redis.call('SREM', KEYS[2], ARGV[2]) redis.call('SET', KEYS[6], '1', 'EX', 86400) "
    "return redis.call('DEL', KEYS[3], KEYS[4], KEYS[5], KEYS[7])";

}  // namespace

absl::StatusOr<std::unique_ptr<RedisJobStore>> RedisJobStore::Connect(const std::string& address,
                                                                      const RedisOptions& options) {
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos)
    return absl::InvalidArgumentError("--redis expects HOST:PORT, got '" + address + "'");
  int port = 0;
  try {
    port = std::stoi(address.substr(colon + 1));
  } catch (...) {
    return absl::InvalidArgumentError("bad Redis port in '" + address + "'");
  }
  std::unique_ptr<RedisJobStore> s(new RedisJobStore(address.substr(0, colon), port, options));
  std::lock_guard<std::mutex> lock(s->mu_);
  absl::Status st = s->EnsureConnected();
  if (!st.ok()) return st;
  return s;
}

RedisJobStore::~RedisJobStore() {
  if (ctx_) redisFree(ctx_);
}

void RedisJobStore::Drop() {
  if (ctx_) redisFree(ctx_);
  ctx_ = nullptr;
}

// Not std::timed_mutex::try_lock_for: GCC 12 waits in it with pthread_mutex_clocklock, which its
// ThreadSanitizer does not intercept, so TSan saw no lock at all and reported every command under
// it as a race. try_lock with a doubling pause (50 us to 1 ms) until the deadline instead; a
// command holds the lock for a round trip to Redis (well under a millisecond on loopback).
absl::StatusOr<std::unique_lock<std::mutex>> RedisJobStore::Lock() {
  std::unique_lock<std::mutex> lock(mu_, std::try_to_lock);
  const auto deadline = std::chrono::steady_clock::now() + options_.timeout;
  std::chrono::microseconds pause(50);
  while (!lock.owns_lock()) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline)
      return absl::UnavailableError("redis " + host_ + ":" + std::to_string(port_) + ": busy for " +
                                    std::to_string(options_.timeout.count()) +
                                    " ms (not answering?)");
    std::this_thread::sleep_for(
        std::min<std::chrono::steady_clock::duration>(pause, deadline - now));
    pause = std::min(2 * pause, std::chrono::microseconds(1000));
    lock.try_lock();
  }
  return lock;
}

void RedisJobStore::SetCommandTimeout(std::chrono::milliseconds t) {
  if (ctx_) redisSetTimeout(ctx_, ToTimeval(t));
}

absl::Status RedisJobStore::EnsureConnected() {
  if (ctx_ && ctx_->err == 0) return absl::OkStatus();
  Drop();
  ctx_ = redisConnectWithTimeout(host_.c_str(), port_, ToTimeval(options_.timeout));
  if (ctx_ == nullptr || ctx_->err) {
    const std::string why = ctx_ ? ctx_->errstr : "out of memory";
    Drop();
    return absl::UnavailableError("redis " + host_ + ":" + std::to_string(port_) + ": " + why);
  }
  SetCommandTimeout(options_.timeout);
  Reply r(static_cast<redisReply*>(redisCommand(ctx_, "PING")));
  if (!r || r->type == REDIS_REPLY_ERROR) {
    Drop();
    return absl::UnavailableError("redis " + host_ + ":" + std::to_string(port_) +
                                  ": no answer to PING");
  }
  return absl::OkStatus();
}

// Runs one command on the connection; mu_ held. Returns UNAVAILABLE from the enclosing function
// when the connection or the command fails (a timeout included).
#define IRFARM_REDIS_CALL(reply, timeout, ...)                                       \
  absl::Status conn = EnsureConnected();                                             \
  if (conn.ok()) SetCommandTimeout(timeout);                                         \
  if (!conn.ok()) return conn;                                                       \
  Reply reply(static_cast<redisReply*>(redisCommand(ctx_, __VA_ARGS__)));            \
  if (!reply) {                                                                      \
    const std::string why = ctx_->errstr;                                            \
    Drop();                                                                          \
    return absl::UnavailableError("redis: " + why);                                  \
  }                                                                                  \
  if (reply->type == REDIS_REPLY_ERROR) {                                            \
    const std::string why(reply->str, reply->len);                                   \
    /* a key of the wrong type is damage, not an outage */                           \
    if (why.rfind("WRONGTYPE", 0) == 0) return absl::DataLossError("redis: " + why); \
    return absl::UnavailableError("redis: " + why);                                  \
  }

// Takes mu_ (or returns UNAVAILABLE from the enclosing function).
#define IRFARM_REDIS_LOCK(lock)                               \
  absl::StatusOr<std::unique_lock<std::mutex>> lock = Lock(); \
  if (!lock.ok()) return lock.status();

absl::StatusOr<long long> RedisJobStore::Write(const char* body,
                                               const std::vector<std::string>& keys,
                                               const std::vector<std::string>& args,
                                               std::chrono::milliseconds timeout) {
  const std::string script = std::string(kFenceCheck) + body;
  const std::string num_keys = std::to_string(keys.size() + 1);
  std::vector<const char*> argv = {"EVAL", script.data(), num_keys.data(),
                                   options_.fence_key.data()};
  std::vector<size_t> lengths = {4, script.size(), num_keys.size(), options_.fence_key.size()};
  for (const std::string& k : keys) {
    argv.push_back(k.data());
    lengths.push_back(k.size());
  }
  argv.push_back(options_.fence_owner.data());
  lengths.push_back(options_.fence_owner.size());
  for (const std::string& a : args) {
    argv.push_back(a.data());
    lengths.push_back(a.size());
  }
  IRFARM_REDIS_LOCK(lock);
  absl::Status conn = EnsureConnected();
  if (!conn.ok()) return conn;
  SetCommandTimeout(timeout.count() > 0 ? timeout : options_.timeout);
  Reply r(static_cast<redisReply*>(
      redisCommandArgv(ctx_, int(argv.size()), argv.data(), lengths.data())));
  if (!r) {
    const std::string why = ctx_->errstr;
    Drop();
    return absl::UnavailableError("redis: " + why);
  }
  if (r->type == REDIS_REPLY_ERROR) {
    const std::string why(r->str, r->len);
    if (why.rfind("FENCED", 0) == 0) return absl::FailedPreconditionError("redis: " + why);
    // a key of the wrong type is damage, not an outage
    if (why.find("WRONGTYPE") != std::string::npos) return absl::DataLossError("redis: " + why);
    if (why.rfind("GONE", 0) == 0) return absl::NotFoundError("redis: " + why.substr(5));
    if (why.rfind("NOSCENE", 0) == 0) return SceneMissingError("redis: " + why.substr(8));
    return absl::UnavailableError("redis: " + why);
  }
  if (r->type != REDIS_REPLY_INTEGER)
    return absl::InternalError("redis: a write script returned type " + std::to_string(r->type));
  return r->integer;
}

absl::StatusOr<uint64_t> RedisJobStore::NextJobNumber() {
  absl::StatusOr<long long> n = Write(kIncr, {prefix_ + "job_counter"}, {});
  if (!n.ok()) return n.status();
  return uint64_t(*n);
}

absl::Status RedisJobStore::PutJob(const v1::StoredJob& job) {
  const std::string& id = job.job().id();
  const std::string key = prefix_ + "job:" + id;
  std::vector<std::string> keys = {key, prefix_ + "jobs", prefix_ + "deleted:" + id,
                                   key + ":scene"};
  if (!job.has_scene())
    return Write(kPutJob, keys,
                 {job.SerializeAsString(), id, IsFinalState(job.job().state()) ? "final" : "state"})
        .status();
  // The submit (or a finished job's emptied bundle): the state without the scene, and the scene.
  v1::StoredJob state = job;
  state.clear_scene();
  return Write(kPutJob, keys,
               {state.SerializeAsString(), id, "scene", job.scene().SerializeAsString()})
      .status();
}

absl::StatusOr<std::vector<v1::StoredJob>> RedisJobStore::LoadJobs() {
  std::vector<std::string> ids;
  std::vector<v1::StoredJob> out;
  std::vector<std::pair<size_t, std::string>> to_move;  // old-format jobs: index, bytes read
  {
    IRFARM_REDIS_LOCK(lock);
    const std::string jobs = prefix_ + "jobs";
    {
      IRFARM_REDIS_CALL(r, options_.load_timeout, "SMEMBERS %b", jobs.data(), jobs.size());
      for (size_t i = 0; i < r->elements; ++i)
        ids.emplace_back(r->element[i]->str, r->element[i]->len);
    }
    for (const std::string& id : ids) {
      const std::string key = prefix_ + "job:" + id;
      Reply r(static_cast<redisReply*>(redisCommand(ctx_, "GET %b", key.data(), key.size())));
      if (!r) {
        Drop();
        return absl::UnavailableError("redis: connection lost");
      }
      v1::StoredJob job;
      if (r->type != REDIS_REPLY_STRING || !job.ParseFromArray(r->str, int(r->len)) ||
          job.job().id() != id) {
        // A damaged key is reported and skipped: the other jobs still resume.
        spdlog::error("redis: {} is missing or unreadable: job {} skipped", key, id);
        continue;
      }
      if (job.has_scene()) {
        to_move.emplace_back(out.size(), std::string(r->str, r->len));
        out.push_back(std::move(job));
        continue;
      }
      const std::string scene_key = key + ":scene";
      Reply sr(static_cast<redisReply*>(
          redisCommand(ctx_, "GET %b", scene_key.data(), scene_key.size())));
      if (!sr) {
        Drop();
        return absl::UnavailableError("redis: connection lost");
      }
      // A missing or damaged scene leaves the job without one (JobManager does not resume an
      // unfinished job that has none; a finished one needs it no more).
      if (sr->type != REDIS_REPLY_STRING ||
          !job.mutable_scene()->ParseFromArray(sr->str, int(sr->len))) {
        job.clear_scene();
        if (sr->type != REDIS_REPLY_NIL)
          spdlog::error("redis: {} is unreadable: job {} has no scene", scene_key, id);
      }
      out.push_back(std::move(job));
    }
  }
  // Jobs stored with the scene inside: moved to the two keys now, or the next state change
  // (which writes no scene) would lose it. Without the move the job is not resumed.
  for (auto& [index, bytes] : to_move) {
    v1::StoredJob& job = out[index];
    v1::StoredJob state = job;
    state.clear_scene();
    const std::string key = prefix_ + "job:" + job.job().id();
    // With the start-up deadline: the upload goes to Redis twice (to compare, and to store).
    absl::StatusOr<long long> moved = Write(
        kMoveScene, {key, key + ":scene"},
        {bytes, state.SerializeAsString(), job.scene().SerializeAsString()}, options_.load_timeout);
    if (!moved.ok()) return moved.status();
    if (*moved != 1)
      return absl::UnavailableError("redis: job " + job.job().id() +
                                    " changed while its scene was being moved; load again");
  }
  return out;
}

absl::Status RedisJobStore::PutTile(const std::string& job_id, int tile,
                                    const std::string& pixels) {
  return Write(kPutTile, {prefix_ + "job:" + job_id + ":tiles", prefix_ + "jobs"},
               {std::to_string(tile), pixels, job_id})
      .status();
}

absl::StatusOr<std::map<int, std::string>> RedisJobStore::LoadTiles(const std::string& job_id) {
  IRFARM_REDIS_LOCK(lock);
  const std::string key = prefix_ + "job:" + job_id + ":tiles";
  IRFARM_REDIS_CALL(r, options_.load_timeout, "HGETALL %b", key.data(), key.size());
  std::map<int, std::string> out;
  for (size_t i = 0; i + 1 < r->elements; i += 2) {
    const int tile = std::atoi(std::string(r->element[i]->str, r->element[i]->len).c_str());
    out[tile] = std::string(r->element[i + 1]->str, r->element[i + 1]->len);
  }
  return out;
}

absl::Status RedisJobStore::AppendRecords(const std::string& job_id,
                                          const std::vector<IrradianceRecord>& records) {
  if (records.empty()) return absl::OkStatus();
  v1::RecordBatch batch;
  PackRecords(records, 0, &batch);
  return Write(kAppend, {prefix_ + "job:" + job_id + ":records", prefix_ + "jobs"},
               {batch.SerializeAsString(), job_id})
      .status();
}

absl::StatusOr<std::vector<IrradianceRecord>> RedisJobStore::LoadRecords(
    const std::string& job_id) {
  IRFARM_REDIS_LOCK(lock);
  const std::string key = prefix_ + "job:" + job_id + ":records";
  IRFARM_REDIS_CALL(r, options_.load_timeout, "LRANGE %b 0 -1", key.data(), key.size());
  std::vector<IrradianceRecord> out;
  for (size_t i = 0; i < r->elements; ++i) {
    v1::RecordBatch batch;
    absl::StatusOr<std::vector<IrradianceRecord>> recs = absl::DataLossError("not a record batch");
    if (batch.ParseFromArray(r->element[i]->str, int(r->element[i]->len)))
      recs = DecodeRecords(batch);
    if (!recs.ok()) {  // reported and skipped: records are an optimisation
      spdlog::error("redis: record batch {} of {} is unreadable ({}): skipped", i, job_id,
                    recs.status().ToString());
      continue;
    }
    out.insert(out.end(), recs->begin(), recs->end());  // the caller validates each record
  }
  return out;
}

absl::Status RedisJobStore::DeleteJob(const std::string& job_id) {
  const std::string key = prefix_ + "job:" + job_id;
  return Write(kDeleteJob,
               {prefix_ + "jobs", key, key + ":tiles", key + ":records",
                prefix_ + "deleted:" + job_id, key + ":scene"},
               {job_id})
      .status();
}

}  // namespace irfarm
