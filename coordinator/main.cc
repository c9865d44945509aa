// irfarm-coordinator: serves JobService (clients) and WorkerService (workers) on one address,
// with an in-memory job store, or Redis with --redis HOST:PORT (jobs survive a restart).
// Credentials: --client-token-file / --worker-token-file / --admin-token-file (coordinator/
// auth.h), TLS with --tls-cert/--tls-key and client certificates with --tls-client-ca. Without
// tokens it listens on a loopback address only, unless --insecure. The request limits
// (JobLimits) each have a flag. SIGINT/SIGTERM shut it down gracefully (in-flight calls get a
// 5 s deadline). --metrics ADDR serves Prometheus metrics at http://ADDR/metrics
// (coordinator_metrics.h); finished jobs expire after --job-ttl seconds or beyond
// --max-finished-jobs (JobManagerOptions).
// --ha (with --redis): active/standby failover. Several coordinators run on one Redis; the one
// holding the lease (coordinator_lease.h) serves, the others wait without listening on --listen
// (so clients and workers with a list of addresses, or a Kubernetes Service with a TCP readiness
// probe, find only the active one) and the first to get the lease after the active one dies
// loads the jobs from Redis as a restarted coordinator does, then listens. A coordinator that
// loses its lease stops at once and exits with status 3 (its store writes are already refused:
// they are fenced by the lease owner, redis_job_store.h); SIGTERM releases the lease after the
// graceful shutdown (1 s for in-flight calls with --ha), so a standby takes over without
// waiting for the lease to expire.
#include <grpcpp/grpcpp.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <condition_variable>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include "coordinator/auth.h"
#include "coordinator/coordinator_lease.h"
#include "coordinator/dashboard.h"

#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"
#include "coordinator/job_service.h"
#include "coordinator/redis_job_store.h"
#include "coordinator/timed_job_store.h"
#include "coordinator/worker_service.h"
#include "service/http_server.h"
#include "service/loopback.h"
#include "service/metrics.h"
#include "service/temp_dir.h"

namespace {

bool ReadFile(const std::string& path, std::string* out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream ss;
  ss << in.rdbuf();
  *out = ss.str();
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  // Signals are taken by a dedicated thread with sigwait: no handler, no global state. Blocked
  // first, before anything starts a thread (gRPC's credentials start its threads, which would
  // otherwise inherit an open mask and let SIGTERM kill the process: exit 143, no graceful
  // shutdown).
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  CLI::App app{"irfarm-coordinator: job API and tile/record coordination for irfarm workers"};
  std::string listen = "127.0.0.1:50051", redis, metrics_address, http_address;
  double job_ttl_seconds = 7 * 24 * 3600;
  double max_upload_mib = 64, lease_seconds = 120, heartbeat_seconds = 1, quarantine_seconds = 30;
  double max_outbox_mib = 64;
  irfarm::JobManagerOptions options;
  irfarm::JobLimits& lim = options.limits;
  std::string client_tokens, worker_tokens, admin_tokens, tls_cert, tls_key, tls_client_ca;
  bool insecure = false, ha = false;
  int ha_lease_ms = 3000;
  app.add_option("--listen", listen, "address to serve on (default 127.0.0.1:50051)");
  app.add_option("--redis", redis, "HOST:PORT of a Redis server to keep jobs in");
  int redis_timeout_ms = 500;
  app.add_option("--redis-timeout-ms", redis_timeout_ms,
                 "deadline of a Redis call; a hung Redis makes calls fail UNAVAILABLE after it "
                 "(default 500)")
      ->check(CLI::Range(10, 60000));
  app.add_flag("--ha", ha,
               "active/standby with other coordinators on the same --redis: serve only while "
               "holding the lease in Redis, else wait for it without listening");
  app.add_option("--ha-lease-ms", ha_lease_ms,
                 "--ha lease time: renewed every third of it; a standby takes over at most this "
                 "plus a twelfth after the active coordinator stops (default 3000)")
      ->check(CLI::Range(300, 600000));
  app.add_option("--client-token-file", client_tokens, "client tokens ('[NAME] TOKEN' lines)");
  app.add_option("--worker-token-file", worker_tokens, "worker tokens, one a line");
  app.add_option("--admin-token-file", admin_tokens, "admin tokens (see every client's jobs)");
  app.add_option("--tls-cert", tls_cert, "server certificate chain (PEM); needs --tls-key");
  app.add_option("--tls-key", tls_key, "server private key (PEM)");
  app.add_option("--tls-client-ca", tls_client_ca,
                 "require client certificates signed by this CA (PEM): mutual TLS");
  app.add_flag("--insecure", insecure, "allow a non-loopback address without tokens");
  app.add_option("--scene-path-root", options.scene_path_root,
                 "allow jobs whose scene is a path under this directory (default: admins only)");
  app.add_option("--max-upload-mib", max_upload_mib, "largest SubmitJob request (default 64)");
  app.add_option("--lease-seconds", lease_seconds, "tile lease deadline (default 120)");
  app.add_option("--heartbeat-seconds", heartbeat_seconds,
                 "worker heartbeat period; 3 missed periods take its leases (default 1)");
  app.add_option("--tile-failure-workers", options.tile_retry.failure_workers,
                 "a tile failing on this many distinct workers fails its job (default 3)");
  app.add_option("--max-tile-attempts", options.tile_retry.max_attempts,
                 "... or failing this many times in all (default 10)");
  app.add_option("--quarantine-after", options.quarantine_after,
                 "failed tiles in a row that quarantine a worker (default 3)");
  app.add_option("--quarantine-seconds", quarantine_seconds, "quarantine length (default 30)");
  app.add_option("--max-violations", options.max_violations,
                 "invalid messages before a worker is disconnected (default 16)");
  app.add_option("--max-film-side", lim.max_film_side, "film width/height limit (32768)");
  app.add_option("--max-film-pixels", lim.max_film_pixels, "film pixel limit (67108864)");
  app.add_option("--max-tiles", lim.max_tiles, "tiles per job (65536)");
  app.add_option("--max-samples", lim.max_samples, "spp x pixels per job (68719476736)");
  app.add_option("--max-record-rays", lim.max_record_rays, "rays per record (65536)");
  app.add_option("--max-name-bytes", lim.max_name_bytes, "job and worker name length (1024)");
  app.add_option("--max-defines", lim.max_defines, "-D overrides per job (256)");
  app.add_option("--max-define-bytes", lim.max_define_bytes, "bytes of one -D (4096)");
  app.add_option("--max-batch-records", lim.max_batch_records,
                 "records per worker message (65536)");
  app.add_option("--max-job-records", lim.max_job_records,
                 "records one job's cache holds, from all its workers (16777216)");
  app.add_option("--max-downloads", lim.max_downloads,
                 "GetResult / ExportCache calls in progress at once; more are refused "
                 "RESOURCE_EXHAUSTED (4)")
      ->check(CLI::Range(1, 1024));
  app.add_option("--max-watches", lim.max_watches,
                 "WatchJob streams open at once, each a server thread until its job ends; more "
                 "are refused RESOURCE_EXHAUSTED (64)")
      ->check(CLI::Range(1, 65536));
  app.add_option("--max-outbox-mib", max_outbox_mib,
                 "record fan-out queued per worker before batches are dropped (64)");
  double max_total_outbox_mib = 1024;
  app.add_option("--max-total-outbox-mib", max_total_outbox_mib,
                 "record fan-out queued for all workers together before batches are dropped "
                 "(1024)");
  std::string fanout = "region";
  app.add_option("--fanout", fanout,
                 "which records a worker is sent: 'region' (those reaching what its tiles see) "
                 "or 'all' (every record of its jobs); default region")
      ->check(CLI::IsMember({"region", "all"}));
  int fanout_linger_ms = int(options.fanout_linger.count());
  app.add_option("--fanout-linger-ms", fanout_linger_ms,
                 "records for a rendering worker wait this long for others to join them in one "
                 "message (default 10; 0 = send each batch at once)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--max-live-jobs", lim.max_live_jobs_per_client,
                 "queued + running jobs per client (64)");
  app.add_option("--metrics", metrics_address,
                 "serve Prometheus metrics on HOST:PORT at /metrics (default: off)");
  app.add_option("--http", http_address,
                 "serve the web dashboard on HOST:PORT (default: off; same tokens as the job API)");
  app.add_option("--job-ttl", job_ttl_seconds,
                 "seconds a finished job (image, tiles, records) is kept; 0 = forever (604800)");
  app.add_option("--max-finished-jobs", options.max_finished_jobs,
                 "finished jobs kept at most, oldest removed first; 0 = no limit (1000)");
  CLI11_PARSE(app, argc, argv);
  // Uploaded scenes and assembled results of an earlier coordinator that died without cleaning up.
  if (const int n = irfarm::RemoveStaleTempDirs("irfarm-submit-") +
                    irfarm::RemoveStaleTempDirs("irfarm-result-"))
    spdlog::info("removed {} temporary folder(s) of coordinators that are gone", n);
  if (job_ttl_seconds < 0 || options.max_finished_jobs < 0) {
    spdlog::error("--job-ttl and --max-finished-jobs must be >= 0");
    return 1;
  }
  options.job_ttl = std::chrono::milliseconds(int64_t(job_ttl_seconds * 1000));
  if (ha && redis.empty()) {
    spdlog::error("--ha needs --redis: the coordinators share their jobs and the lease there");
    return 1;
  }

  std::vector<irfarm::NamedToken> tokens[3];
  const std::string* files[3] = {&client_tokens, &worker_tokens, &admin_tokens};
  const char* prefixes[3] = {"client-", "worker-", "admin-"};
  for (int i = 0; i < 3; ++i) {
    if (files[i]->empty()) continue;
    absl::StatusOr<std::vector<irfarm::NamedToken>> t =
        irfarm::ReadTokenFile(*files[i], prefixes[i]);
    if (!t.ok()) {
      spdlog::error("{}", t.status().ToString());
      return 1;
    }
    tokens[i] = std::move(*t);
  }
  irfarm::Authenticator auth(tokens[0], tokens[1], tokens[2]);
  if (!http_address.empty() && !irfarm::IsLoopbackAddress(http_address) && auth.clients_open() &&
      !insecure) {
    spdlog::error(
        "refusing to serve the dashboard on {} without client tokens; pass --insecure "
        "to do it anyway",
        http_address);
    return 1;
  }
  if (!irfarm::IsLoopbackAddress(listen) && (auth.clients_open() || auth.workers_open()) &&
      !insecure) {
    spdlog::error(
        "refusing to listen on {} without client and worker tokens (--client-token-file, "
        "--worker-token-file); pass --insecure to do it anyway",
        listen);
    return 1;
  }
  std::shared_ptr<grpc::ServerCredentials> credentials = grpc::InsecureServerCredentials();
  if (!tls_cert.empty() || !tls_key.empty()) {
    grpc::SslServerCredentialsOptions ssl(
        tls_client_ca.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                              : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
    grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
    if (!ReadFile(tls_cert, &pair.cert_chain) || !ReadFile(tls_key, &pair.private_key) ||
        (!tls_client_ca.empty() && !ReadFile(tls_client_ca, &ssl.pem_root_certs))) {
      spdlog::error("cannot read --tls-cert, --tls-key or --tls-client-ca");
      return 1;
    }
    ssl.pem_key_cert_pairs.push_back(pair);
    credentials = grpc::SslServerCredentials(ssl);
  } else if (!tls_client_ca.empty()) {
    spdlog::error("--tls-client-ca needs --tls-cert and --tls-key");
    return 1;
  } else if (!irfarm::IsLoopbackAddress(listen)) {
    spdlog::warn("listening on {} without TLS: tokens travel in clear text", listen);
  }

  // Stop requests: a signal (exit 0) or a lost lease (exit kLeaseLost). Taken by the main thread,
  // which shuts the server down.
  constexpr int kLeaseLost = 3;
  std::mutex stop_mu;
  std::condition_variable stop_cv;
  bool stop_requested = false;
  int exit_code = 0;
  const auto request_stop = [&](int code) {
    {
      std::lock_guard<std::mutex> lock(stop_mu);
      if (stop_requested) return;
      stop_requested = true;
      exit_code = code;
    }
    stop_cv.notify_all();
  };
  std::thread shutdown([&] {
    int sig = 0;
    sigwait(&signals, &sig);
    spdlog::info("signal {}: shutting down", sig);
    request_stop(0);
  });
  shutdown.detach();  // stays blocked in sigwait when the process ends another way

  irfarm::RedisOptions redis_options{"irfarm:", std::chrono::milliseconds(redis_timeout_ms)};
  irfarm::LeaseOptions lease_options;
  std::string lease_owner;
  if (ha) {
    lease_owner = irfarm::NewOwnerId(listen);
    lease_options.key = redis_options.prefix + "coordinator_lease";
    lease_options.ttl = std::chrono::milliseconds(ha_lease_ms);
    lease_options.renew_every = lease_options.ttl / 3;
    lease_options.timeout = redis_options.timeout;
    redis_options.fence_key = lease_options.key;  // every store write checks the lease owner
    redis_options.fence_owner = lease_owner;
  }
  std::unique_ptr<irfarm::JobStore> store;
  if (redis.empty()) {
    store = std::make_unique<irfarm::InMemoryJobStore>();
  } else {
    absl::StatusOr<std::unique_ptr<irfarm::RedisJobStore>> r =
        irfarm::RedisJobStore::Connect(redis, redis_options);
    if (!r.ok()) {
      spdlog::error("{}", r.status().ToString());
      return 1;
    }
    store = std::move(*r);
  }
  irfarm::MetricsRegistry metrics;
  irfarm::AddProcessMetrics(&metrics);
  irfarm::Gauge* active = metrics.AddGauge(
      "irfarm_coordinator_active",
      "1 while this coordinator serves; 0 while it waits as a standby (--ha) or shuts down");
  // Served from the start, so that a standby is scraped (and probed for liveness) too.
  absl::StatusOr<std::unique_ptr<irfarm::HttpServer>> metrics_server =
      irfarm::StartMetricsServer(metrics_address, &metrics);
  if (!metrics_server.ok()) {
    spdlog::error("{}", metrics_server.status().ToString());
    return 1;
  }

  std::unique_ptr<irfarm::CoordinatorLease> lease;
  if (ha) {
    absl::StatusOr<std::unique_ptr<irfarm::CoordinatorLease>> l =
        irfarm::CoordinatorLease::Create(redis, lease_owner, lease_options);
    if (!l.ok()) {
      spdlog::error("{}", l.status().ToString());
      return 1;
    }
    lease = std::move(*l);
    // Standby: poll for the lease (a twelfth of its time: 250 ms at the default 3 s).
    const auto poll = std::max(lease_options.ttl / 12, std::chrono::milliseconds(10));
    const auto standby_since = std::chrono::steady_clock::now();
    std::string last_seen;
    std::chrono::steady_clock::time_point acquired_at;
    for (;;) {
      const auto sent = std::chrono::steady_clock::now();
      std::string holder;
      absl::StatusOr<bool> got = lease->TryAcquire(&holder);
      if (got.ok() && *got) {
        acquired_at = sent;
        break;
      }
      const std::string seen = got.ok() ? holder : got.status().ToString();
      if (seen != last_seen)
        spdlog::info("standby: {} {}; waiting for the coordinator lease",
                     got.ok() ? "the lease is held by" : "cannot ask Redis:", seen);
      last_seen = seen;
      std::unique_lock<std::mutex> lock(stop_mu);
      if (stop_cv.wait_for(lock, poll, [&] { return stop_requested; })) return exit_code;
    }
    spdlog::info("coordinator lease {} acquired as {} after {:.3f} s of standby; loading jobs",
                 lease_options.key, lease_owner,
                 std::chrono::duration<double>(acquired_at - standby_since).count());
    lease->Start(acquired_at, [&](const std::string& why) {
      active->Set(0);
      spdlog::error(
          "coordinator lease lost ({}): the store refuses this coordinator's writes; "
          "stopping",
          why);
      request_stop(kLeaseLost);
    });
  }
  irfarm::TimedJobStore timed_store(store.get(), &metrics);
  options.max_upload_bytes = size_t(max_upload_mib * 1024 * 1024);
  lim.max_outbox_bytes = size_t(max_outbox_mib * 1024 * 1024);
  lim.max_total_outbox_bytes = size_t(max_total_outbox_mib * 1024 * 1024);
  lim.max_tile_result_bytes = options.max_upload_bytes;  // the receive limit less 1 MiB
  options.filter_fanout = fanout == "region";
  options.fanout_linger = std::chrono::milliseconds(fanout_linger_ms);
  options.lease_time = std::chrono::milliseconds(int64_t(lease_seconds * 1000));
  options.heartbeat =
      std::chrono::milliseconds(std::max<int64_t>(50, int64_t(heartbeat_seconds * 1000)));
  options.quarantine_time = std::chrono::milliseconds(int64_t(quarantine_seconds * 1000));
  absl::StatusOr<std::unique_ptr<irfarm::JobManager>> manager =
      irfarm::JobManager::Create(options, &timed_store, &metrics);
  if (!manager.ok()) {
    spdlog::error("{}", manager.status().ToString());
    return 1;
  }
  irfarm::JobServiceImpl job_service(manager->get(), &auth);
  irfarm::WorkerServiceImpl worker_service(manager->get(), &auth);
  grpc::ServerBuilder builder;
  int port = 0;
  // No SO_REUSEPORT (gRPC sets it by default on Linux): a second coordinator started on a port
  // one already listens on would bind it too, and the kernel would share the connections out
  // between the two; it must fail to start instead.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  // Workers ping (keepalive, at least 2 s apart) to find out that a coordinator hung; allow that
  // (gRPC's default refuses pings more often than every 5 minutes when it sends no data, which an
  // idle worker's coordinator does not). Closer pings still count as strikes.
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 1000);
  builder.AddListeningPort(listen, credentials, &port);
  builder.SetMaxReceiveMessageSize(int(options.max_upload_bytes + (size_t(1) << 20)));
  builder.RegisterService(&job_service);
  builder.RegisterService(&worker_service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    spdlog::error("cannot listen on {}", listen);
    return 1;
  }
  active->Set(lease == nullptr || lease->held() ? 1 : 0);
  spdlog::info(
      "irfarm-coordinator listening on {} (store: {}{}; {}; client tokens: {}, worker "
      "tokens: {})",
      listen, redis.empty() ? "memory" : "redis " + redis, ha ? ", active (--ha)" : "",
      tls_cert.empty()        ? "no TLS"
      : tls_client_ca.empty() ? "TLS"
                              : "mutual TLS",
      tokens[0].size() + tokens[2].size(), tokens[1].size());

  std::unique_ptr<irfarm::HttpServer> dashboard;
  if (!http_address.empty()) {
    absl::StatusOr<std::unique_ptr<irfarm::HttpServer>> http =
        irfarm::HttpServer::Start(http_address, irfarm::DashboardRoutes(manager->get(), &auth));
    if (!http.ok()) {
      spdlog::error("--http: {}", http.status().ToString());
      return 1;
    }
    dashboard = std::move(*http);
    spdlog::info("dashboard on http://{}/", http_address);
  }

  std::atomic<bool> stop{false};
  std::thread expiry([&] {
    for (int tick = 0; !stop.load(); ++tick) {
      (*manager)->ExpireLeases();
      if (tick % 4 == 0) (*manager)->ExpireJobs();  // retention: once a second
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  });
  {
    std::unique_lock<std::mutex> lock(stop_mu);
    stop_cv.wait(lock, [&] { return stop_requested; });
  }
  // A signal lets in-flight calls end within 5 s, or 1 s with --ha, where a standby is waiting
  // for the lease (worker sessions and watches never end by themselves: the whole grace period
  // is waited whenever one is open). A lost lease stops at once: its writes are refused anyway,
  // and another coordinator serves.
  active->Set(0);
  const std::chrono::seconds grace(exit_code == kLeaseLost ? 0 : ha ? 1 : 5);
  server->Shutdown(std::chrono::system_clock::now() + grace);
  server->Wait();
  stop = true;
  expiry.join();
  metrics_server->reset();
  dashboard.reset();
  manager->reset();  // lands the job states still queued (StoreWriter) while the lease is held
  if (lease && exit_code != kLeaseLost) {
    absl::Status st = lease->Release();  // a standby takes over now, not after the lease time
    if (!st.ok()) spdlog::warn("coordinator lease not released: {}", st.ToString());
  }
  return exit_code;
}
