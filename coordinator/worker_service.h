// WorkerServiceImpl: the gRPC WorkerService. Each worker's Session stream is read on the handler
// thread and written by a second thread that forwards what JobManager::Poll hands out (gRPC
// allows one concurrent reader and one writer per stream). A session without a worker token
// (when tokens are configured, auth.h) ends UNAUTHENTICATED before it registers; one whose worker
// sends too many invalid messages (JobManager::Expelled) ends PERMISSION_DENIED. When the stream
// ends, the worker is gone and its tiles are requeued.
#pragma once

#include "coordinator/auth.h"
#include "coordinator/job_manager.h"
#include "irfarm/v1/worker.grpc.pb.h"

namespace irfarm {

class WorkerServiceImpl final : public v1::WorkerService::Service {
 public:
  // `auth` may be null: any worker may connect.
  // Message handling times go to manager->metrics_registry()
  // (irfarm_rpc_duration_seconds{method="Session/records"|"Session/tile_result"|...}).
  explicit WorkerServiceImpl(JobManager* manager, Authenticator* auth = nullptr);

  grpc::Status Session(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::CoordinatorMessage, v1::WorkerMessage>* stream) override;

 private:
  JobManager* manager_;
  Authenticator* auth_;
  Histogram* records_latency_;
  Histogram* result_latency_;
  Histogram* failed_latency_;
  Counter* sessions_;
};

}  // namespace irfarm
