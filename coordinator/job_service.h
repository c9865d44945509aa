// JobServiceImpl: the gRPC JobService. Authenticates each call (auth.h: UNAUTHENTICATED without
// a client token, when tokens are configured), then translates requests into JobManager calls
// for that caller and statuses back (service/grpc_status.h); no logic of its own.
#pragma once

#include <atomic>

#include "coordinator/auth.h"
#include "coordinator/job_manager.h"
#include "irfarm/v1/jobs.grpc.pb.h"

namespace irfarm {

class JobServiceImpl final : public v1::JobService::Service {
 public:
  // `auth` may be null: every call is then an anonymous admin.
  // Call latencies go to manager->metrics_registry() (irfarm_rpc_duration_seconds{method}).
  explicit JobServiceImpl(JobManager* manager, Authenticator* auth = nullptr);

  grpc::Status SubmitJob(grpc::ServerContext* context, const v1::SubmitJobRequest* request,
                         v1::SubmitJobResponse* response) override;
  grpc::Status GetJob(grpc::ServerContext* context, const v1::GetJobRequest* request,
                      v1::GetJobResponse* response) override;
  grpc::Status ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest* request,
                        v1::ListJobsResponse* response) override;
  grpc::Status WatchJob(grpc::ServerContext* context, const v1::WatchJobRequest* request,
                        grpc::ServerWriter<v1::WatchJobResponse>* writer) override;
  grpc::Status CancelJob(grpc::ServerContext* context, const v1::CancelJobRequest* request,
                         v1::CancelJobResponse* response) override;
  grpc::Status GetResult(grpc::ServerContext* context, const v1::GetResultRequest* request,
                         grpc::ServerWriter<v1::GetResultResponse>* writer) override;
  grpc::Status ExportCache(grpc::ServerContext* context, const v1::ExportCacheRequest* request,
                           grpc::ServerWriter<v1::ExportCacheResponse>* writer) override;
  grpc::Status GetCluster(grpc::ServerContext* context, const v1::GetClusterRequest* request,
                          v1::GetClusterResponse* response) override;
  grpc::Status DeleteJob(grpc::ServerContext* context, const v1::DeleteJobRequest* request,
                         v1::DeleteJobResponse* response) override;

 private:
  absl::StatusOr<Caller> Authenticate(const grpc::ServerContext* context);

  enum Method { kSubmit, kGet, kList, kCancel, kResult, kExport, kCluster, kDelete, kNumMethods };

  // Takes one of `limit` slots counted by `in_use` (GetResult / ExportCache calls: max_downloads;
  // WatchJob streams: max_watches); false (and nothing taken) when all are in use.
  static bool TakeSlot(std::atomic<int>& in_use, int limit);

  JobManager* manager_;
  std::atomic<int> downloads_{0};  // GetResult / ExportCache calls in progress
  std::atomic<int> watches_{0};    // WatchJob streams open
  Authenticator* auth_;
  Histogram* latency_[kNumMethods];  // WatchJob is a long stream: not timed
};

}  // namespace irfarm
