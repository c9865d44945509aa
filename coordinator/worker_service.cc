// WorkerServiceImpl: one reader and one writer thread per worker stream (see worker_service.h).
#include "coordinator/worker_service.h"

#include <spdlog/spdlog.h>

#include <atomic>
#include <thread>

namespace irfarm {

grpc::Status WorkerServiceImpl::Session(
    grpc::ServerContext* context,
    grpc::ServerReaderWriter<v1::CoordinatorMessage, v1::WorkerMessage>* stream) {
  v1::WorkerMessage msg;
  if (!stream->Read(&msg) || !msg.has_register_())
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "first message must be register");
  const uint32_t id = manager_->RegisterWorker(msg.register_().name());
  spdlog::info("worker {} ({}) connected from {}", id, msg.register_().name(), context->peer());
  {
    v1::CoordinatorMessage reply;
    reply.mutable_registered()->set_worker_id(id);
    reply.mutable_registered()->set_heartbeat_seconds(5);
    stream->Write(reply);
  }
  std::atomic<bool> done{false};
  std::thread writer([&] {
    while (!done.load() && !context->IsCancelled()) {
      for (const v1::CoordinatorMessage& m : manager_->Poll(id, std::chrono::milliseconds(200))) {
        if (!stream->Write(m)) {
          done = true;
          break;
        }
      }
    }
  });
  std::string reason = "disconnected";
  while (stream->Read(&msg)) {
    absl::Status st;
    switch (msg.msg_case()) {
      case v1::WorkerMessage::kRecords:
        st = manager_->AddRecords(id, msg.records());
        break;
      case v1::WorkerMessage::kTileResult:
        st = manager_->CompleteTile(id, msg.tile_result());
        break;
      case v1::WorkerMessage::kTileFailed:
        st = manager_->FailTile(id, msg.tile_failed());
        break;
      case v1::WorkerMessage::kDrain:
        manager_->Drain(id);
        reason = "drained";
        break;
      default:
        break;  // heartbeats only prove the stream is alive
    }
    if (!st.ok()) spdlog::warn("worker {}: {}", id, st.ToString());
  }
  done = true;
  manager_->WorkerGone(id, reason);
  writer.join();
  spdlog::info("worker {} {}", id, reason);
  return grpc::Status::OK;
}

}  // namespace irfarm
