// WorkerServiceImpl: the gRPC WorkerService. Each worker's Session stream is read on the handler
// thread and written by a second thread that forwards what JobManager::Poll hands out (gRPC
// allows one concurrent reader and one writer per stream). When the stream breaks, the worker is
// gone and its tiles are requeued.
#pragma once

#include "coordinator/job_manager.h"
#include "irfarm/v1/worker.grpc.pb.h"

namespace irfarm {

class WorkerServiceImpl final : public v1::WorkerService::Service {
 public:
  explicit WorkerServiceImpl(JobManager* manager) : manager_(manager) {}

  grpc::Status Session(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::CoordinatorMessage, v1::WorkerMessage>* stream) override;

 private:
  JobManager* manager_;
};

}  // namespace irfarm
