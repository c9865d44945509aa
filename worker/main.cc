// irfarm-worker: renders tiles for an irfarm coordinator (see worker/worker.h). SIGTERM/SIGINT:
// finish the current tile, report it, then exit. --metrics ADDR serves Prometheus metrics at
// http://ADDR/metrics (worker_metrics.h).
#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <thread>

#include "service/http_server.h"
#include "service/metrics.h"
#include "service/temp_dir.h"
#include "worker/worker.h"

int main(int argc, char** argv) {
  CLI::App app{"irfarm-worker: renders tiles leased by an irfarm coordinator"};
  irfarm::WorkerOptions options;
  int flush_ms = 50;
  int keepalive_seconds = 10;
  std::string metrics_address;
  app.add_option("--coordinator", options.coordinator,
                 "coordinator address (127.0.0.1:50051), or several separated by commas (an "
                 "active and its standbys, --ha): the one accepting connections is used");
  app.add_option("--threads", options.threads, "render threads (default: all cores)");
  app.add_option("--name", options.name, "name shown in job stats (default: host:pid)");
  app.add_option("--flush-ms", flush_ms, "publish new records at least this often (50)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--keepalive-seconds", keepalive_seconds,
                 "a coordinator that answers no HTTP/2 ping within this time is left for another "
                 "(or reconnected to) (10)")
      ->check(CLI::Range(2, 3600));
  app.add_option("--token-file", options.auth.token_file,
                 "worker token file (default: $IRFARM_TOKEN)");
  app.add_option("--tls-ca", options.auth.tls_ca, "use TLS, trusting this CA (PEM)");
  app.add_option("--tls-cert", options.auth.tls_cert, "client certificate for mutual TLS (PEM)");
  app.add_option("--tls-key", options.auth.tls_key, "client key for mutual TLS (PEM)");
  app.add_option("--metrics", metrics_address,
                 "serve Prometheus metrics on HOST:PORT at /metrics (default: off)");
  CLI11_PARSE(app, argc, argv);
  options.flush_interval = std::chrono::milliseconds(flush_ms);
  options.keepalive = std::chrono::seconds(keepalive_seconds);
  if (options.name.empty()) {
    char host[256] = "worker";
    gethostname(host, sizeof host - 1);
    options.name = std::string(host) + ":" + std::to_string(getpid());
  }

  // Scene bundles of workers on this machine that died without cleaning up (SIGKILL, a crash).
  if (const int n = irfarm::RemoveStaleTempDirs("irfarm-worker-"))
    spdlog::info("removed {} scene folder(s) of workers that are gone", n);

  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  irfarm::MetricsRegistry metrics;
  irfarm::AddProcessMetrics(&metrics);
  irfarm::Worker worker(options, &metrics);
  absl::StatusOr<std::unique_ptr<irfarm::HttpServer>> metrics_server =
      irfarm::StartMetricsServer(metrics_address, &metrics);
  if (!metrics_server.ok()) {
    spdlog::error("{}", metrics_server.status().ToString());
    return 1;
  }
  std::thread signal_thread([&] {
    int sig = 0;
    sigwait(&signals, &sig);
    spdlog::info("signal {}: finishing the current tile, then exiting", sig);
    worker.Stop();
  });
  const int code = worker.Run();
  signal_thread.detach();
  metrics_server->reset();
  return code;
}
