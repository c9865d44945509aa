// irfarm-coordinator: serves JobService (clients) and WorkerService (workers) on one address,
// with an in-memory job store, or Redis with --redis HOST:PORT (jobs survive a restart).
// SIGINT/SIGTERM shut it down gracefully (in-flight calls get a 5 s deadline).
#include <grpcpp/grpcpp.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <memory>
#include <thread>

#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"
#include "coordinator/job_service.h"
#include "coordinator/redis_job_store.h"
#include "coordinator/worker_service.h"

int main(int argc, char** argv) {
  CLI::App app{"irfarm-coordinator: job API and tile/record coordination for irfarm workers"};
  std::string listen = "127.0.0.1:50051", redis;
  double max_upload_mib = 64, lease_seconds = 120;
  int max_attempts = 3;
  app.add_option("--listen", listen, "address to serve on (default 127.0.0.1:50051)");
  app.add_option("--redis", redis, "HOST:PORT of a Redis server to keep jobs in");
  app.add_option("--max-upload-mib", max_upload_mib, "largest SubmitJob request (default 64)");
  app.add_option("--lease-seconds", lease_seconds, "tile lease deadline (default 120)");
  app.add_option("--max-tile-attempts", max_attempts, "failed attempts before a job fails (3)");
  CLI11_PARSE(app, argc, argv);

  // Signals are taken by a dedicated thread with sigwait: no handler, no global state.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  std::unique_ptr<irfarm::JobStore> store;
  if (redis.empty()) {
    store = std::make_unique<irfarm::InMemoryJobStore>();
  } else {
    absl::StatusOr<std::unique_ptr<irfarm::RedisJobStore>> r =
        irfarm::RedisJobStore::Connect(redis);
    if (!r.ok()) {
      spdlog::error("{}", r.status().ToString());
      return 1;
    }
    store = std::move(*r);
  }
  irfarm::JobManagerOptions options;
  options.max_upload_bytes = size_t(max_upload_mib * 1024 * 1024);
  options.lease_time = std::chrono::milliseconds(int64_t(lease_seconds * 1000));
  options.max_tile_attempts = max_attempts;
  absl::StatusOr<std::unique_ptr<irfarm::JobManager>> manager =
      irfarm::JobManager::Create(options, store.get());
  if (!manager.ok()) {
    spdlog::error("{}", manager.status().ToString());
    return 1;
  }
  irfarm::JobServiceImpl job_service(manager->get());
  irfarm::WorkerServiceImpl worker_service(manager->get());
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(listen, grpc::InsecureServerCredentials(), &port);
  builder.SetMaxReceiveMessageSize(int(options.max_upload_bytes + (size_t(1) << 20)));
  builder.RegisterService(&job_service);
  builder.RegisterService(&worker_service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    spdlog::error("cannot listen on {}", listen);
    return 1;
  }
  spdlog::info("irfarm-coordinator listening on {} (store: {})", listen,
               redis.empty() ? "memory" : "redis " + redis);

  std::atomic<bool> stop{false};
  std::thread expiry([&] {
    while (!stop.load()) {
      (*manager)->ExpireLeases();
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  });
  std::thread shutdown([&] {
    int sig = 0;
    sigwait(&signals, &sig);
    spdlog::info("signal {}: shutting down", sig);
    stop = true;
    server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(5));
  });
  server->Wait();
  stop = true;
  expiry.join();
  shutdown.detach();  // still blocked in sigwait when the server ended another way
  return 0;
}
