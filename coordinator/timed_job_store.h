// TimedJobStore: a JobStore that forwards every call to another and records how long it took in
// the histogram irfarm_store_duration_seconds{op=...} (service/metrics.h), so that a slow Redis
// shows in the coordinator's metrics. Errors are counted in irfarm_store_errors_total{op=...}.
#pragma once

#include "coordinator/job_store.h"
#include "service/metrics.h"

namespace irfarm {

class TimedJobStore : public JobStore {
 public:
  // `inner` and `registry` must outlive this store.
  TimedJobStore(JobStore* inner, MetricsRegistry* registry);

  absl::StatusOr<uint64_t> NextJobNumber() override;
  absl::Status PutJob(const v1::StoredJob& job) override;
  absl::StatusOr<std::vector<v1::StoredJob>> LoadJobs() override;
  absl::Status PutTile(const std::string& job_id, int tile, const std::string& pixels) override;
  absl::StatusOr<std::map<int, std::string>> LoadTiles(const std::string& job_id) override;
  absl::Status AppendRecords(const std::string& job_id,
                             const std::vector<IrradianceRecord>& records) override;
  absl::StatusOr<std::vector<IrradianceRecord>> LoadRecords(const std::string& job_id) override;
  absl::Status DeleteJob(const std::string& job_id) override;

 private:
  enum Op {
    kNextJobNumber,
    kPutJob,
    kLoadJobs,
    kPutTile,
    kLoadTiles,
    kAppendRecords,
    kLoadRecords,
    kDeleteJob,
    kNumOps
  };
  // Runs `call`, timing it as `op`.
  template <typename Call>
  auto Timed(Op op, Call call) -> decltype(call());

  JobStore* const inner_;
  Histogram* duration_[kNumOps];
  Counter* errors_[kNumOps];
};

}  // namespace irfarm
