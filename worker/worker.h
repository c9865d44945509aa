// Worker: one irfarm-worker process's connection to the coordinator. Registers on a Session
// stream, renders the tiles it is leased (one at a time, all threads on the tile) with a per-job
// local cache, publishes its new records in batches bounded by size (kMaxBatchRecords) and time
// (flush_interval), inserts the records other workers computed, and reconnects with exponential
// backoff when the stream breaks. Stop() (SIGTERM) lets the current tile finish and be reported,
// then drains and returns. It authenticates with a worker token and, optionally, TLS
// (service/client_auth.h), and sends heartbeats at the period the coordinator asks for (a worker
// silent for 3 periods loses its leases).
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

namespace irfarm {

struct WorkerOptions {
  std::string coordinator = "127.0.0.1:50051";
  std::string name;
  int threads = 0;  // 0 = all cores
  std::chrono::milliseconds flush_interval{50};
  size_t max_batch_records = 4096;
  ClientAuthOptions auth;
};

class Worker {
 public:
  explicit Worker(WorkerOptions options) : options_(std::move(options)) {}
  // Runs until Stop(); returns the process exit code.
  int Run();
  // Thread-safe; called from the signal thread.
  void Stop();

 private:
  // One connected session; returns when the stream breaks or the worker stops.
  void RunSession(v1::WorkerService::Stub* stub);

  std::string token_;
  WorkerOptions options_;
  std::atomic<bool> stop_{false};
  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
};

}  // namespace irfarm
