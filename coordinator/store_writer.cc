// StoreWriter: queued job-store writes on their own thread (see store_writer.h).
#include "coordinator/store_writer.h"

#include <spdlog/spdlog.h>

namespace irfarm {

StoreWriter::StoreWriter(JobStore* store, std::chrono::milliseconds retry, SceneOf scene_of)
    : store_(store), retry_(retry), scene_of_(std::move(scene_of)), thread_([this] { Run(); }) {}

StoreWriter::~StoreWriter() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void StoreWriter::PutJob(const v1::StoredJob& job) {
  std::lock_guard<std::mutex> lock(mu_);
  const std::string& id = job.job().id();
  // The job's last queued op: replace it when it is a PutJob (nothing of the job comes after it).
  for (auto it = queue_.rbegin(); it != queue_.rend(); ++it) {
    if (it->job_id != id) continue;
    if (it->job) {
      // A state change replacing a write that carries the scene keeps that scene.
      ReplaceKeepingScene(*it->job, job);
      return;
    }
    break;
  }
  queue_.push_back(Op{id, job, {}});
  cv_.notify_all();
}

void StoreWriter::AppendRecords(const std::string& job_id, std::vector<IrradianceRecord> records) {
  if (records.empty()) return;
  std::lock_guard<std::mutex> lock(mu_);
  queue_.push_back(Op{job_id, std::nullopt, std::move(records)});
  cv_.notify_all();
}

void StoreWriter::DeleteJob(const std::string& job_id) {
  std::lock_guard<std::mutex> lock(mu_);
  queue_.push_back(Op{job_id, std::nullopt, {}, true});
  cv_.notify_all();
}

bool StoreWriter::Flush(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  return cv_.wait_for(lock, timeout, [&] { return queue_.empty() && !busy_; });
}

size_t StoreWriter::pending() const {
  std::lock_guard<std::mutex> lock(mu_);
  return queue_.size() + (busy_ ? 1 : 0);
}

uint64_t StoreWriter::failures() const {
  std::lock_guard<std::mutex> lock(mu_);
  return failures_;
}

absl::Status StoreWriter::Write(const Op& op) {
  if (op.remove) return store_->DeleteJob(op.job_id);
  if (op.job) {
    const absl::Status st = store_->PutJob(*op.job);
    if (!IsSceneMissing(st)) return st;
    if (!scene_of_) {  // nothing to write the scene with: dropped, not retried for ever
      spdlog::warn("job {}: the store holds no scene for it and none is at hand: state dropped",
                   op.job_id);
      return absl::NotFoundError("job " + op.job_id + " has no scene to write: " + st.ToString());
    }
    // The store lost the job's scene (Redis flushed, or the key evicted): the state goes with the
    // scene the coordinator holds, or the job would come back without one after a restart.
    std::optional<v1::SceneSource> scene = scene_of_(op.job_id);
    if (!scene)  // gone, or finished (its own final write follows)
      return absl::NotFoundError("job " + op.job_id + " is gone or finished: " + st.ToString());
    spdlog::warn("job {}: the store had lost its scene (flushed or evicted); written again",
                 op.job_id);
    v1::StoredJob full = *op.job;
    *full.mutable_scene() = std::move(*scene);
    return store_->PutJob(full);
  }
  return store_->AppendRecords(op.job_id, op.records);
}

void StoreWriter::Run() {
  std::unique_lock<std::mutex> lock(mu_);
  for (;;) {
    cv_.wait(lock, [&] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, all written
    Op op = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
    const absl::Status st = Write(op);
    lock.lock();
    busy_ = false;
    if (st.ok()) {
      cv_.notify_all();  // Flush
      continue;
    }
    if (absl::IsNotFound(st)) {  // the job was deleted, or there is nothing to write it with
      spdlog::info("job store: a write for job {} dropped: {}", op.job_id, st.ToString());
      cv_.notify_all();
      continue;
    }
    ++failures_;
    if (stop_) {
      spdlog::warn("job store: {} writes not done at shutdown: {}", queue_.size() + 1,
                   st.ToString());
      return;
    }
    if (failures_ == 1 || failures_ % 20 == 0)
      spdlog::warn("job store write for {} failed ({} failures so far), retrying: {}", op.job_id,
                   failures_, st.ToString());
    // Back in front, unless a newer state of the same job was queued meanwhile (it replaces it,
    // and takes this one's scene if it has none).
    Op* newer = nullptr;
    if (op.job)
      for (Op& o : queue_)
        if (newer == nullptr && o.job_id == op.job_id && o.job) newer = &o;
    if (newer == nullptr) {
      queue_.push_front(std::move(op));
    } else {
      ReplaceKeepingScene(*op.job, *newer->job);
      newer->job = std::move(op.job);
    }
    cv_.wait_for(lock, retry_, [&] { return stop_; });
  }
}

}  // namespace irfarm
