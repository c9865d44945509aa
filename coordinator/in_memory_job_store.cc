// InMemoryJobStore: maps under one mutex (see in_memory_job_store.h).
#include "coordinator/in_memory_job_store.h"

namespace irfarm {

absl::StatusOr<uint64_t> InMemoryJobStore::NextJobNumber() {
  std::lock_guard<std::mutex> lock(mu_);
  return next_job_++;
}

absl::Status InMemoryJobStore::PutJob(const v1::StoredJob& job) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(job.job().id());
  if (!job.has_scene() && !IsFinalState(job.job().state()) &&
      (it == jobs_.end() || !it->second.has_scene()))
    return SceneMissingError("no stored scene for job " + job.job().id());
  ReplaceKeepingScene(jobs_[job.job().id()], job);  // a state change keeps the scene
  return absl::OkStatus();
}

absl::StatusOr<std::vector<v1::StoredJob>> InMemoryJobStore::LoadJobs() {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<v1::StoredJob> out;
  for (const auto& [id, job] : jobs_) out.push_back(job);
  return out;
}

absl::Status InMemoryJobStore::PutTile(const std::string& job_id, int tile,
                                       const std::string& pixels) {
  std::lock_guard<std::mutex> lock(mu_);
  if (jobs_.count(job_id) == 0) return absl::NotFoundError("no job " + job_id);
  tiles_[job_id][tile] = pixels;
  return absl::OkStatus();
}

absl::StatusOr<std::map<int, std::string>> InMemoryJobStore::LoadTiles(const std::string& job_id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = tiles_.find(job_id);
  if (it == tiles_.end()) return std::map<int, std::string>();
  return it->second;
}

absl::Status InMemoryJobStore::AppendRecords(const std::string& job_id,
                                             const std::vector<IrradianceRecord>& records) {
  std::lock_guard<std::mutex> lock(mu_);
  if (jobs_.count(job_id) == 0) return absl::NotFoundError("no job " + job_id);
  std::vector<IrradianceRecord>& all = records_[job_id];
  all.insert(all.end(), records.begin(), records.end());
  return absl::OkStatus();
}

absl::StatusOr<std::vector<IrradianceRecord>> InMemoryJobStore::LoadRecords(
    const std::string& job_id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = records_.find(job_id);
  if (it == records_.end()) return std::vector<IrradianceRecord>();
  return it->second;
}

absl::Status InMemoryJobStore::DeleteJob(const std::string& job_id) {
  std::lock_guard<std::mutex> lock(mu_);
  jobs_.erase(job_id);
  tiles_.erase(job_id);
  records_.erase(job_id);
  return absl::OkStatus();
}

}  // namespace irfarm
