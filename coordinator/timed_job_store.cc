// TimedJobStore: per-call latency of the job store (see timed_job_store.h).
#include "coordinator/timed_job_store.h"

#include <chrono>

namespace irfarm {
namespace {

bool Ok(const absl::Status& s) { return s.ok(); }
template <typename T>
bool Ok(const absl::StatusOr<T>& s) {
  return s.ok();
}

}  // namespace

TimedJobStore::TimedJobStore(JobStore* inner, MetricsRegistry* registry) : inner_(inner) {
  const char* names[kNumOps] = {"next_job_number", "put_job",        "load_jobs",    "put_tile",
                                "load_tiles",      "append_records", "load_records", "delete_job"};
  for (int i = 0; i < kNumOps; ++i) {
    duration_[i] = registry->AddHistogram("irfarm_store_duration_seconds",
                                          "Job store (memory or Redis) call latency.",
                                          LatencyBuckets(), {{"op", names[i]}});
    errors_[i] = registry->AddCounter("irfarm_store_errors_total", "Job store calls that failed.",
                                      {{"op", names[i]}});
  }
}

template <typename Call>
auto TimedJobStore::Timed(Op op, Call call) -> decltype(call()) {
  const auto start = std::chrono::steady_clock::now();
  auto result = call();
  duration_[op]->Observe(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  if (!Ok(result)) errors_[op]->Add();
  return result;
}

absl::StatusOr<uint64_t> TimedJobStore::NextJobNumber() {
  return Timed(kNextJobNumber, [&] { return inner_->NextJobNumber(); });
}
absl::Status TimedJobStore::PutJob(const v1::StoredJob& job) {
  return Timed(kPutJob, [&] { return inner_->PutJob(job); });
}
absl::StatusOr<std::vector<v1::StoredJob>> TimedJobStore::LoadJobs() {
  return Timed(kLoadJobs, [&] { return inner_->LoadJobs(); });
}
absl::Status TimedJobStore::PutTile(const std::string& job_id, int tile,
                                    const std::string& pixels) {
  return Timed(kPutTile, [&] { return inner_->PutTile(job_id, tile, pixels); });
}
absl::StatusOr<std::map<int, std::string>> TimedJobStore::LoadTiles(const std::string& job_id) {
  return Timed(kLoadTiles, [&] { return inner_->LoadTiles(job_id); });
}
absl::Status TimedJobStore::AppendRecords(const std::string& job_id,
                                          const std::vector<IrradianceRecord>& records) {
  return Timed(kAppendRecords, [&] { return inner_->AppendRecords(job_id, records); });
}
absl::StatusOr<std::vector<IrradianceRecord>> TimedJobStore::LoadRecords(
    const std::string& job_id) {
  return Timed(kLoadRecords, [&] { return inner_->LoadRecords(job_id); });
}
absl::Status TimedJobStore::DeleteJob(const std::string& job_id) {
  return Timed(kDeleteJob, [&] { return inner_->DeleteJob(job_id); });
}

}  // namespace irfarm
