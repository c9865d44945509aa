// WorkerServiceImpl: one reader and one writer thread per worker stream (see worker_service.h).
#include "coordinator/worker_service.h"

#include <spdlog/spdlog.h>

#include <atomic>
#include <thread>

#include "service/grpc_status.h"

namespace irfarm {

WorkerServiceImpl::WorkerServiceImpl(JobManager* manager, Authenticator* auth)
    : manager_(manager), auth_(auth) {
  MetricsRegistry* r = manager->metrics_registry();
  const char* help = "gRPC call handling time at the coordinator.";
  records_latency_ = r->AddHistogram("irfarm_rpc_duration_seconds", help, LatencyBuckets(),
                                     {{"method", "Session/records"}});
  result_latency_ = r->AddHistogram("irfarm_rpc_duration_seconds", help, LatencyBuckets(),
                                    {{"method", "Session/tile_result"}});
  failed_latency_ = r->AddHistogram("irfarm_rpc_duration_seconds", help, LatencyBuckets(),
                                    {{"method", "Session/tile_failed"}});
  sessions_ = r->AddCounter("irfarm_worker_sessions_total", "Worker sessions registered.");
}

grpc::Status WorkerServiceImpl::Session(
    grpc::ServerContext* context,
    grpc::ServerReaderWriter<v1::CoordinatorMessage, v1::WorkerMessage>* stream) {
  std::string token_name;
  if (auth_ != nullptr) {
    absl::StatusOr<std::string> who = auth_->Worker(*context);
    if (!who.ok()) return ToGrpcStatus(who.status());
    token_name = *who;
  }
  v1::WorkerMessage msg;
  if (!stream->Read(&msg) || !msg.has_register_())
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "first message must be register");
  if (msg.register_().name().size() > manager_->options().limits.max_name_bytes)
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "worker name too long");
  const uint32_t id =
      manager_->RegisterWorker(msg.register_().name(), context->peer(), msg.register_().threads(),
                               msg.register_().reports_regions(), token_name);
  sessions_->Add();
  spdlog::info("worker {} connected from {}", id, context->peer());
  {
    const int64_t heartbeat_ms = manager_->options().heartbeat.count();
    v1::CoordinatorMessage reply;
    reply.mutable_registered()->set_worker_id(id);
    reply.mutable_registered()->set_heartbeat_seconds(int((heartbeat_ms + 999) / 1000));
    reply.mutable_registered()->set_heartbeat_ms(int(heartbeat_ms));
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
  grpc::Status result = grpc::Status::OK;
  while (stream->Read(&msg)) {
    manager_->Heard(id);
    absl::Status st;
    switch (msg.msg_case()) {
      case v1::WorkerMessage::kRecords: {
        ScopedTimer timer(records_latency_);
        st = manager_->AddRecords(id, msg.records());
        break;
      }
      case v1::WorkerMessage::kTileResult: {
        ScopedTimer timer(result_latency_);
        st = manager_->CompleteTile(id, msg.tile_result());
        break;
      }
      case v1::WorkerMessage::kTileFailed: {
        ScopedTimer timer(failed_latency_);
        st = manager_->FailTile(id, msg.tile_failed());
        break;
      }
      case v1::WorkerMessage::kTileRegion:
        st = manager_->AddTileRegion(id, msg.tile_region());
        break;
      case v1::WorkerMessage::kDrain:
        manager_->Drain(id);
        reason = "drained";
        break;
      default:
        break;  // heartbeats only prove the stream is alive
    }
    if (absl::IsFailedPrecondition(st)) {
      spdlog::debug("worker {}: {}", id, st.ToString());  // stale, harmless
    } else if (!st.ok()) {
      spdlog::warn("worker {}: {}", id, st.ToString());
    }
    if (manager_->Expelled(id)) {
      reason = "disconnected: too many invalid messages";
      result = grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                            "too many invalid messages (last: " + std::string(st.message()) + ")");
      break;
    }
  }
  done = true;
  manager_->WorkerGone(id, reason);
  writer.join();
  spdlog::info("worker {} {}", id, reason);
  return result;
}

}  // namespace irfarm
