// Worker: one irfarm-worker process's connection to the coordinator. Registers on a Session
// stream, renders the tiles it is leased (one at a time, all threads on the tile) with a per-job
// local cache, publishes its new records in batches bounded by size (kMaxBatchRecords) and time
// (flush_interval), inserts the records other workers computed, and reconnects with exponential
// backoff when the stream breaks. Stop() (SIGTERM) lets the current tile finish and be reported,
// then drains and returns. It authenticates with a worker token and, optionally, TLS
// (service/client_auth.h), and sends heartbeats at the period the coordinator asks for (a worker
// silent for 3 periods loses its leases). Given several coordinator addresses (active and
// standbys, `irfarm-coordinator --ha`), it connects to whichever accepts connections, and after
// a broken session to whichever does next (service/coordinator_list.h).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "irfarm/v1/worker.grpc.pb.h"
#include "service/client_auth.h"
#include "worker/job_context.h"
#include "worker/worker_metrics.h"

namespace irfarm {

struct WorkerOptions {
  std::string coordinator = "127.0.0.1:50051";  // or "host1:port,host2:port,..."
  std::string name;
  int threads = 0;  // 0 = all cores
  std::chrono::milliseconds flush_interval{50};
  // HTTP/2 keepalive pings to the coordinator: a coordinator that does not answer one within
  // this time (hung, frozen, cut off without a reset) ends the session, and the worker
  // reconnects, to a standby if there is one. The coordinator sends nothing to an idle worker,
  // so without them a read would wait forever. At least 2 s (the coordinator refuses pings more
  // often than once a second).
  std::chrono::seconds keepalive{10};
  size_t max_batch_records = 4096;
  ClientAuthOptions auth;
};

class Worker {
 public:
  // Metrics go to `registry` (served on --metrics), or with none to a registry of its own.
  explicit Worker(WorkerOptions options, MetricsRegistry* registry = nullptr)
      : options_(std::move(options)),
        own_registry_(registry ? nullptr : std::make_unique<MetricsRegistry>()),
        metrics_(registry ? registry : own_registry_.get()) {}
  // Runs until Stop(); returns the process exit code.
  int Run();
  // Thread-safe; called from the signal thread.
  void Stop();

 private:
  // One connected session; returns when the stream breaks or the worker stops.
  void RunSession(v1::WorkerService::Stub* stub, const std::string& address);

  std::string token_;
  WorkerOptions options_;
  std::atomic<bool> stop_{false};
  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  std::unique_ptr<MetricsRegistry> own_registry_;
  WorkerMetrics metrics_;
};

}  // namespace irfarm
