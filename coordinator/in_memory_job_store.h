// InMemoryJobStore: the default JobStore, in process memory (nothing to set up; nothing survives
// the process). Thread-safe.
#pragma once

#include <mutex>

#include "coordinator/job_store.h"

namespace irfarm {

class InMemoryJobStore : public JobStore {
 public:
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
  std::mutex mu_;
  uint64_t next_job_ = 1;
  std::map<std::string, v1::StoredJob> jobs_;
  std::map<std::string, std::map<int, std::string>> tiles_;
  std::map<std::string, std::vector<IrradianceRecord>> records_;
};

}  // namespace irfarm
