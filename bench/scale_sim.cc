// Scale simulation (issue 11 part 4): one real irfarm-coordinator process on a real redis-server,
// and 64 then 256 simulated workers in this process (sim_worker.h: the real worker protocol over
// one gRPC connection each, synthetic records at a set rate with realistic positions and radii,
// tile regions reported like the real worker's, tiles that take a realistic time), run with
// --fanout=region and --fanout=all. For each run it measures, over a window after a warm-up:
// the coordinator's CPU (utime + stime from /proc/PID/stat, in cores) and memory (RSS and peak),
// Redis's and this process's CPU, record delivery latency p50 / p99 (send time tagged into each
// record, read at receipt by the other simulated workers), lease latency p50 / p99 (tile result
// written to next lease read), bytes and records per worker per second, and fan-out batches the
// coordinator dropped (a worker's outbox over its bound). Prints one table row per run with the
// machine's load average (the simulated workers share the machine with the coordinator).
//
// The tile time is measured first from a real irfarm-worker (--threads 1) rendering the scene at
// its own resolution, unless --tile-seconds is given; the simulated job's film is sized so that
// every worker has tiles for the whole run (tiles keep their 32-pixel size, so a tile sees a small
// part of the scene, as in a production-size render).
//
// --smoke: a few seconds with 8 workers (ctest service_scale_smoke): runs the job to the end with
// each fan-out mode and checks that every record published reached exactly the workers whose
// reported regions it reaches (all others' records with --fanout=all), none twice, that the
// filter withheld some, that latencies were measured and that nothing was rejected. Exit code 1
// when a check fails.
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <unordered_set>
#include <vector>

#include "bench/child_process.h"
#include "bench/sim_worker.h"
#include "cache/snapshot.h"
#include "coordinator/fanout_region.h"
#include "render/record_bounds.h"
#include "irfarm/v1/jobs.grpc.pb.h"
#include "render/scene.h"
#include "service/job_settings.h"
#include "service/record_codec.h"
#include "service/scene_bundle.h"

namespace irfarm {
namespace {

using Clock = std::chrono::steady_clock;

std::string LoadAverage() {
  std::ifstream f("/proc/loadavg");
  std::string a, b, c;
  f >> a >> b >> c;
  return a + " " + b + " " + c;
}

struct Setup {
  std::string bin, scene_path, tmp;
  std::string coordinator;      // the irfarm-coordinator binary of this run
  std::string label;            // its name in the table
  v1::RenderSettings settings;  // the job's (defines set the film size)
  SimScene* sim_scene = nullptr;
  float accuracy = 0;
  Bounds3 record_box;  // the coordinator's record box (regions are clipped to it)
  double rate = 2000, tile_seconds = 1, far_fraction = 0.1;
  double warmup = 3, seconds = 15;
  std::string perf_dir;  // record the coordinator with `perf record -g` during each window here
};

struct RunFigures {
  std::string error;
  int workers = 0;
  std::string fanout, load, label;
  double coord_cores = 0, redis_cores = 0, bench_cores = 0;
  double rss_mib = 0, peak_mib = 0;
  double rec_p50 = 0, rec_p99 = 0, lease_p50 = 0, lease_p99 = 0;
  uint64_t latency_samples = 0, lease_samples = 0;
  double sent_kib_s = 0, recv_kib_s = 0;          // per worker
  double records_sent_s = 0, records_recv_s = 0;  // per worker
  uint64_t dropped_batches = 0, rejected = 0, tiles = 0;
  std::vector<std::string> failures;  // smoke checks
};

std::unique_ptr<v1::JobService::Stub> JobStub(const std::string& addr) {
  grpc::ChannelArguments args;
  args.SetMaxSendMessageSize(-1);
  args.SetMaxReceiveMessageSize(-1);
  return v1::JobService::NewStub(
      grpc::CreateCustomChannel(addr, grpc::InsecureChannelCredentials(), args));
}

absl::StatusOr<v1::Job> Submit(v1::JobService::Stub* stub, const Setup& s) {
  absl::StatusOr<v1::SceneBundle> bundle = MakeBundle(s.scene_path);
  if (!bundle.ok()) return bundle.status();
  v1::SubmitJobRequest req;
  *req.mutable_scene()->mutable_bundle() = *bundle;
  *req.mutable_settings() = s.settings;
  grpc::ClientContext c;
  c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  v1::SubmitJobResponse resp;
  const grpc::Status st = stub->SubmitJob(&c, req, &resp);
  if (!st.ok()) return absl::InternalError("submit: " + st.error_message());
  return resp.job();
}

absl::StatusOr<v1::Job> GetJob(v1::JobService::Stub* stub, const std::string& id) {
  grpc::ClientContext c;
  c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  v1::GetJobRequest req;
  req.set_job_id(id);
  v1::GetJobResponse resp;
  const grpc::Status st = stub->GetJob(&c, req, &resp);
  if (!st.ok()) return absl::InternalError("get job: " + st.error_message());
  return resp.job();
}

bool Final(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

// Ids (RecordTag::Id) of the records merged into the job's cache, from ExportCache.
absl::StatusOr<std::unordered_set<uint64_t>> MergedIds(v1::JobService::Stub* stub,
                                                       const std::string& job_id) {
  grpc::ClientContext c;
  c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  v1::ExportCacheRequest req;
  req.set_job_id(job_id);
  auto reader = stub->ExportCache(&c, req);
  std::string bytes;
  v1::ExportCacheResponse chunk;
  while (reader->Read(&chunk)) bytes += chunk.chunk();
  const grpc::Status st = reader->Finish();
  if (!st.ok()) return absl::InternalError("export cache: " + st.error_message());
  absl::StatusOr<Snapshot> snap = ParseSnapshot(bytes, "export");
  if (!snap.ok()) return snap.status();
  std::unordered_set<uint64_t> ids;
  for (const IrradianceRecord& r : snap->records) {
    const float packed[kFloatsPerRecord] = {
        0, 0, 0, 0, 0, 0, r.irradiance.x, r.irradiance.y, r.irradiance.z, r.radius};
    ids.insert(GetTag(packed).Id());
  }
  return ids;
}

// The smoke checks: each worker received exactly the records of the others that the coordinator
// merged (`merged`: a batch it could not store is dropped, by design) and that reach the union of
// its regions (clipped like the coordinator clips them), or all of them unfiltered.
void CheckDeliveries(const Setup& s, bool filtered, const std::vector<SimWorker*>& workers,
                     const std::unordered_set<uint64_t>& merged, RunFigures* f) {
  uint64_t withheld = 0, expected_total = 0, published = 0, not_merged = 0;
  for (const SimWorker* a : workers) {
    for (const IrradianceRecord& r : a->stats().published) {
      const float packed[kFloatsPerRecord] = {
          0, 0, 0, 0, 0, 0, r.irradiance.x, r.irradiance.y, r.irradiance.z, r.radius};
      ++published;
      not_merged += !merged.count(GetTag(packed).Id());
    }
  }
  // Store failures drop whole batches now and then on a loaded machine; most must get through.
  if (published == 0 || merged.size() + not_merged != published || not_merged * 2 > published)
    f->failures.push_back(std::to_string(published) + " records published, " +
                          std::to_string(merged.size()) + " merged by the coordinator, " +
                          std::to_string(not_merged) + " of those published not merged");
  for (const SimWorker* b : workers) {
    const SimWorkerStats& bs = b->stats();
    Bounds3 region;
    for (const v1::TileRegion& r : bs.regions) {
      absl::StatusOr<Bounds3> box = ParseTileRegion(r, s.record_box);
      if (box.ok()) region.Extend(*box);
    }
    std::unordered_set<uint64_t> expected;
    for (const SimWorker* a : workers) {
      if (a == b) continue;
      for (const IrradianceRecord& r : a->stats().published) {
        uint64_t id = 0;
        {
          float packed[kFloatsPerRecord] = {
              0, 0, 0, 0, 0, 0, r.irradiance.x, r.irradiance.y, r.irradiance.z, r.radius};
          id = GetTag(packed).Id();
        }
        if (!merged.count(id)) continue;
        if (!filtered || RecordReachesBox(r, region, s.accuracy))
          expected.insert(id);
        else
          ++withheld;
      }
    }
    expected_total += expected.size();
    std::unordered_set<uint64_t> got;
    uint64_t duplicates = 0, extra = 0;
    for (uint64_t id : bs.received_ids) {
      if (!got.insert(id).second) ++duplicates;
      if (!expected.count(id)) ++extra;
    }
    uint64_t missing = 0;
    for (uint64_t id : expected) missing += !got.count(id);
    if (duplicates + extra + missing > 0)
      f->failures.push_back("worker " + std::to_string(bs.worker_id) + ": expected " +
                            std::to_string(expected.size()) + " records, received " +
                            std::to_string(bs.received_ids.size()) + " (" +
                            std::to_string(missing) + " missing, " + std::to_string(extra) +
                            " not reaching its region, " + std::to_string(duplicates) + " twice)");
    if (bs.rejected > 0)
      f->failures.push_back("worker " + std::to_string(bs.worker_id) + ": " +
                            std::to_string(bs.rejected) +
                            " messages rejected, last: " + bs.last_rejection);
    if (!bs.error.empty())
      f->failures.push_back("worker " + std::to_string(bs.worker_id) + ": " + bs.error);
  }
  if (expected_total == 0) f->failures.push_back("no record was expected anywhere");
  if (filtered && withheld == 0)
    f->failures.push_back("the filter had nothing to withhold (regions cover everything)");
  if (f->latency_samples == 0) f->failures.push_back("no record latency was measured");
  if (f->lease_samples == 0) f->failures.push_back("no lease latency was measured");
  std::fprintf(stderr,
               "  smoke %s: %llu records published, %llu not merged (store busy); %llu "
               "deliveries expected and checked, %llu withheld\n",
               filtered ? "region" : "all", (unsigned long long)published,
               (unsigned long long)not_merged, (unsigned long long)expected_total,
               (unsigned long long)withheld);
}

RunFigures RunConfig(const Setup& s, int n, const std::string& fanout, bool smoke) {
  RunFigures f;
  f.workers = n;
  f.fanout = fanout;
  const std::string tag = std::to_string(n) + "-" + fanout + "-" + s.label;
  const int redis_port = FreePort();
  ChildProcess redis({"redis-server", "--port", std::to_string(redis_port), "--bind", "127.0.0.1",
                      "--save", "", "--appendonly", "no", "--dir", s.tmp},
                     s.tmp + "/redis-" + tag + ".log");
  if (!WaitForPort(redis_port, std::chrono::seconds(10))) {
    f.error = "redis-server did not start (is it installed?)";
    return f;
  }
  const std::string addr = "127.0.0.1:" + std::to_string(FreePort());
  const std::string coord_log = s.tmp + "/coordinator-" + tag + ".log";
  ChildProcess coordinator({s.coordinator, "--listen", addr, "--redis",
                            "127.0.0.1:" + std::to_string(redis_port), "--fanout", fanout},
                           coord_log);
  std::unique_ptr<v1::JobService::Stub> stub = JobStub(addr);
  if (!WaitForJobService(stub.get(), std::chrono::seconds(15))) {
    f.error = "coordinator did not come up (log " + coord_log + ")";
    return f;
  }
  MeasureWindow window;
  std::vector<std::unique_ptr<SimWorker>> workers;
  for (int i = 0; i < n; ++i) {
    SimWorkerOptions o;
    o.coordinator = addr;
    o.index = uint32_t(i);
    o.records_per_second = s.rate;
    o.tile_seconds = s.tile_seconds;
    o.far_fraction = s.far_fraction;
    o.keep_records = smoke;
    o.filtered = fanout == "region";
    o.scene = s.sim_scene;
    o.window = &window;
    workers.push_back(std::make_unique<SimWorker>(o));
    workers.back()->Start();
  }
  const auto stop_all = [&] {
    for (auto& w : workers) w->Stop();
    for (auto& w : workers) w->Join();
  };
  const auto reg_deadline = Clock::now() + std::chrono::seconds(30);
  for (auto& w : workers)
    while (!w->registered() && Clock::now() < reg_deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
  for (auto& w : workers)
    if (!w->registered()) {
      size_t registered = 0;
      for (auto& v : workers) registered += v->registered() ? 1 : 0;
      stop_all();
      f.error = std::to_string(workers.size() - registered) + " of " +
                std::to_string(workers.size()) + " simulated workers did not register in 30 s";
      for (auto& v : workers)  // the first reason a session gave (stats are valid after Join)
        if (!v->stats().error.empty()) {
          f.error += ": " + v->stats().error;
          break;
        }
      return f;
    }
  absl::StatusOr<v1::Job> job = Submit(stub.get(), s);
  if (!job.ok()) {
    stop_all();
    f.error = job.status().ToString();
    return f;
  }
  const auto open_window = [&] {
    window.start_us = NowUs32();
    window.state = 1;
  };
  const auto close_window = [&] {
    window.end_us = NowUs32();
    window.state = 2;
  };
  ProcessUsage c0, r0, b0, c1, r1, b1;
  Clock::time_point t0, t1;
  if (smoke) {
    open_window();
    t0 = Clock::now();
    c0 = ReadProcessUsage(coordinator.pid());
    r0 = ReadProcessUsage(redis.pid());
    b0 = ReadProcessUsage(getpid());
    const auto end = Clock::now() + std::chrono::seconds(120);
    while (Clock::now() < end) {
      job = GetJob(stub.get(), job->id());
      if (!job.ok() || Final(job->state())) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    t1 = Clock::now();
    c1 = ReadProcessUsage(coordinator.pid());
    r1 = ReadProcessUsage(redis.pid());
    b1 = ReadProcessUsage(getpid());
    close_window();
    if (!job.ok() || job->state() != v1::JOB_STATE_SUCCEEDED)
      f.failures.push_back("job did not succeed: " +
                           (job.ok() ? v1::JobState_Name(job->state()) + " " + job->error()
                                     : job.status().ToString()));
    // Every worker's outbox up to its JobClosed notice was read: all deliveries are in.
    const auto closed_deadline = Clock::now() + std::chrono::seconds(20);
    for (auto& w : workers)
      while (!w->job_closed() && Clock::now() < closed_deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
  } else {
    std::this_thread::sleep_for(std::chrono::duration<double>(s.warmup));
    f.load = LoadAverage();
    open_window();
    t0 = Clock::now();
    c0 = ReadProcessUsage(coordinator.pid());
    r0 = ReadProcessUsage(redis.pid());
    b0 = ReadProcessUsage(getpid());
    std::unique_ptr<ChildProcess> perf;
    if (!s.perf_dir.empty())
      perf = std::make_unique<ChildProcess>(
          std::vector<std::string>{"perf", "record", "-F", "499", "-g", "-p",
                                   std::to_string(coordinator.pid()), "-o",
                                   s.perf_dir + "/perf-" + tag + ".data"},
          s.tmp + "/perf-" + tag + ".log");
    std::this_thread::sleep_for(std::chrono::duration<double>(s.seconds));
    t1 = Clock::now();
    c1 = ReadProcessUsage(coordinator.pid());
    r1 = ReadProcessUsage(redis.pid());
    b1 = ReadProcessUsage(getpid());
    close_window();
    perf.reset();
    // Records sent inside the window still on their way count when they arrive.
    std::this_thread::sleep_for(std::chrono::seconds(2));
  }
  {
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    v1::GetClusterResponse cluster;
    if (stub->GetCluster(&c, v1::GetClusterRequest(), &cluster).ok())
      for (const v1::WorkerInfo& w : cluster.workers()) f.dropped_batches += w.batches_dropped();
  }
  if (!smoke) {
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    v1::CancelJobRequest req;
    req.set_job_id(job->id());
    v1::CancelJobResponse resp;
    (void)stub->CancelJob(&c, req, &resp);
  }
  absl::StatusOr<std::unordered_set<uint64_t>> merged = std::unordered_set<uint64_t>();
  if (smoke) merged = MergedIds(stub.get(), job->id());
  stop_all();
  coordinator.Stop();
  redis.Stop();
  if (!c0.ok || !c1.ok) {
    f.error = "cannot read the coordinator's /proc entries";
    return f;
  }
  const double wall = std::chrono::duration<double>(t1 - t0).count();
  f.coord_cores = (c1.cpu_seconds - c0.cpu_seconds) / wall;
  f.redis_cores = (r1.cpu_seconds - r0.cpu_seconds) / wall;
  f.bench_cores = (b1.cpu_seconds - b0.cpu_seconds) / wall;
  f.rss_mib = c1.rss_mib;
  f.peak_mib = c1.peak_mib;
  LatencyHistogram records, leases;
  uint64_t bytes_sent = 0, bytes_recv = 0, recs_sent = 0, recs_recv = 0;
  for (auto& w : workers) {
    const SimWorkerStats& st = w->stats();
    records.Merge(st.record_latency);
    leases.Merge(st.lease_latency);
    bytes_sent += st.window_bytes_sent;
    bytes_recv += st.window_bytes_received;
    recs_sent += st.window_records_sent;
    recs_recv += st.window_records_received;
    f.rejected += st.rejected;
    f.tiles += st.tiles;
  }
  f.latency_samples = records.count();
  f.lease_samples = leases.count();
  f.rec_p50 = records.QuantileMs(0.5);
  f.rec_p99 = records.QuantileMs(0.99);
  f.lease_p50 = leases.QuantileMs(0.5);
  f.lease_p99 = leases.QuantileMs(0.99);
  const double per = double(n) * wall;
  f.sent_kib_s = double(bytes_sent) / 1024 / per;
  f.recv_kib_s = double(bytes_recv) / 1024 / per;
  f.records_sent_s = double(recs_sent) / per;
  f.records_recv_s = double(recs_recv) / per;
  if (smoke) {
    std::vector<SimWorker*> ws;
    for (auto& w : workers) ws.push_back(w.get());
    if (merged.ok())
      CheckDeliveries(s, fanout == "region", ws, *merged, &f);
    else
      f.failures.push_back(merged.status().ToString());
  }
  return f;
}

// Mean wall seconds per tile and records per second of a real irfarm-worker (--threads 1)
// rendering the scene at its own resolution with the job's other settings.
absl::StatusOr<std::pair<double, double>> MeasureRealTile(const Setup& s) {
  const std::string addr = "127.0.0.1:" + std::to_string(FreePort());
  ChildProcess coordinator({s.bin + "/irfarm-coordinator", "--listen", addr},
                           s.tmp + "/measure-coordinator.log");
  std::unique_ptr<v1::JobService::Stub> stub = JobStub(addr);
  if (!WaitForJobService(stub.get(), std::chrono::seconds(15)))
    return absl::UnavailableError("coordinator did not come up");
  ChildProcess worker(
      {s.bin + "/irfarm-worker", "--coordinator", addr, "--threads", "1", "--name", "measure"},
      s.tmp + "/measure-worker.log");
  Setup own = s;
  own.settings.mutable_defines()->erase("resx");
  own.settings.mutable_defines()->erase("resy");
  absl::StatusOr<v1::Job> job = Submit(stub.get(), own);
  if (!job.ok()) return job.status();
  const auto end = Clock::now() + std::chrono::seconds(600);
  while (Clock::now() < end) {
    job = GetJob(stub.get(), job->id());
    if (!job.ok() || Final(job->state())) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  if (!job.ok()) return job.status();
  if (job->state() != v1::JOB_STATE_SUCCEEDED || job->workers_size() == 0)
    return absl::InternalError("measuring job ended " + v1::JobState_Name(job->state()));
  double seconds = 0, tiles = 0, records = 0;
  for (const v1::WorkerJobStats& w : job->workers()) {
    seconds += w.render_seconds();
    tiles += w.tiles();
    records += double(w.records_computed());
  }
  return std::make_pair(seconds / std::max(1.0, tiles), records / std::max(1e-9, seconds));
}

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

}  // namespace
}  // namespace irfarm

int main(int argc, char** argv) {
  using namespace irfarm;
  CLI::App app{"irfarm scale simulation: one coordinator, many simulated workers"};
  std::string scenes_dir = IRFARM_SCENES_DIR, scene_name = "two-rooms", bin = IRFARM_BIN_DIR;
  std::string worker_list = "64,256", fanout_list = "region,all";
  Setup s;
  s.tile_seconds = 0;
  bool smoke = false;
  std::vector<std::string> compare;
  app.add_option("--scenes", scenes_dir, "scenes directory (default tests/data/scenes)");
  app.add_option("--scene", scene_name, "scene folder name (default two-rooms)");
  app.add_option("--bin", bin, "directory of irfarm-coordinator and irfarm-worker");
  app.add_option("--workers", worker_list, "simulated worker counts, comma-separated (64,256)");
  app.add_option("--fanout", fanout_list, "coordinator --fanout modes (region,all)");
  app.add_option("--rate", s.rate, "records per second per worker while rendering (2000)");
  app.add_option("--tile-seconds", s.tile_seconds,
                 "mean tile time (default: measured from a real worker on the scene)");
  app.add_option("--far-fraction", s.far_fraction,
                 "fraction of records anywhere the camera sees, not near the tile (0.1)");
  app.add_option("--warmup", s.warmup, "seconds before the measurement window (3)");
  app.add_option("--seconds", s.seconds, "measurement window, seconds (15)");
  app.add_option("--compare", compare,
                 "LABEL=PATH: also run each configuration with this irfarm-coordinator binary "
                 "(before/after figures side by side; repeatable)");
  app.add_option("--perf", s.perf_dir,
                 "directory: record the coordinator with perf record -g during each window");
  app.add_flag("--smoke", smoke,
               "8 workers, short tiles, the job to the end; check deliveries (ctest)");
  CLI11_PARSE(app, argc, argv);
  s.bin = bin;
  s.scene_path = scenes_dir + "/" + scene_name + "/scene.xml";
  std::vector<int> counts;
  for (const std::string& c : Split(worker_list)) counts.push_back(std::stoi(c));
  std::vector<std::string> modes = Split(fanout_list);
  if (smoke) {
    counts = {8};
    modes = {"region", "all"};
    if (s.tile_seconds <= 0) s.tile_seconds = 0.25;
  }
  for (const std::string& m : modes)
    if (m != "region" && m != "all") {
      std::fprintf(stderr, "error: --fanout takes region and all, not '%s'\n", m.c_str());
      return 2;
    }
  char tmpl[] = "/tmp/irfarm-scale-XXXXXX";
  if (!mkdtemp(tmpl)) {
    std::perror("mkdtemp");
    return 1;
  }
  s.tmp = tmpl;
  s.settings.set_share_records(true);
  if (s.tile_seconds <= 0) {
    std::fprintf(stderr, "measuring a real worker's tile time on %s ...\n", scene_name.c_str());
    absl::StatusOr<std::pair<double, double>> m = MeasureRealTile(s);
    if (!m.ok()) {
      std::fprintf(stderr, "error: %s (logs in %s)\n", m.status().ToString().c_str(),
                   s.tmp.c_str());
      return 1;
    }
    s.tile_seconds = m->first;
    std::printf("real worker (--threads 1) on %s: %.3f s per tile, %.0f records/s\n",
                scene_name.c_str(), m->first, m->second);
  }
  // The film: 32-pixel tiles, enough of them that no worker runs out during the run (2x margin),
  // with the scene's own aspect ratio.
  absl::StatusOr<SceneDesc> base = LoadJobScene(s.scene_path, s.settings);
  if (!base.ok()) {
    std::fprintf(stderr, "error: %s\n", base.status().ToString().c_str());
    return 1;
  }
  const int max_workers = *std::max_element(counts.begin(), counts.end());
  const double run_seconds = smoke ? 0 : s.warmup + s.seconds + 3;
  const double aspect = double(base->camera.width) / double(base->camera.height);
  int tiles_y = 1, tiles_x = 1;
  if (smoke) {
    tiles_x = 8;  // 32 tiles: 4 per worker, about a second of rendering
    tiles_y = 4;
  } else {
    const double needed = 2.0 * max_workers * run_seconds / s.tile_seconds;
    tiles_y = std::max(1, int(std::ceil(std::sqrt(needed / aspect))));
    tiles_x = std::max(1, int(std::ceil(needed / tiles_y)));
  }
  (*s.settings.mutable_defines())["resx"] = std::to_string(tiles_x * kDefaultTileSize);
  (*s.settings.mutable_defines())["resy"] = std::to_string(tiles_y * kDefaultTileSize);
  absl::StatusOr<SceneDesc> desc = LoadJobScene(s.scene_path, s.settings);
  absl::StatusOr<std::unique_ptr<Scene>> scene =
      desc.ok() ? Scene::Build(*desc) : absl::StatusOr<std::unique_ptr<Scene>>(desc.status());
  absl::StatusOr<RenderSettings> rs = desc.ok() ? MakeRenderSettings(*desc, s.settings, 0)
                                                : absl::StatusOr<RenderSettings>(desc.status());
  if (!scene.ok() || !rs.ok()) {
    std::fprintf(stderr, "error: %s\n",
                 (!scene.ok() ? scene.status() : rs.status()).ToString().c_str());
    return 1;
  }
  const RecordBounds bounds = RecordBoundsForScene(*desc);
  s.record_box = bounds.box;
  s.accuracy = std::min(rs->irrcache.accuracy, 1.0f);
  SimScene sim_scene(scene->get(), bounds, s.accuracy, kDefaultTileSize);
  s.sim_scene = &sim_scene;
  {
    const Clock::time_point t0 = Clock::now();
    sim_scene.PrepareAll(int(std::thread::hardware_concurrency()));
    std::fprintf(stderr, "tile regions of %d tiles: %.1f s\n", tiles_x * tiles_y,
                 std::chrono::duration<double>(Clock::now() - t0).count());
  }

  std::printf(
      "scene %s at %dx%d (%d tiles of %d px), %.0f records/s per worker, tiles %.3f s "
      "mean (uniform 0.5-1.5x), %s\n",
      scene_name.c_str(), tiles_x * kDefaultTileSize, tiles_y * kDefaultTileSize, tiles_x * tiles_y,
      kDefaultTileSize, s.rate, s.tile_seconds,
      smoke ? "smoke run (job to the end)"
            : ("window " + std::to_string(int(s.seconds)) + " s after " +
               std::to_string(int(s.warmup)) + " s warm-up")
                  .c_str());
  std::printf("machine: %u cores, load average %s at start\n\n",
              std::thread::hardware_concurrency(), LoadAverage().c_str());
  std::vector<std::pair<std::string, std::string>> coordinators = {
      {"this", s.bin + "/irfarm-coordinator"}};
  for (const std::string& c : compare) {
    const size_t eq = c.find('=');
    if (eq == std::string::npos) {
      std::fprintf(stderr, "error: --compare takes LABEL=PATH, not '%s'\n", c.c_str());
      return 2;
    }
    coordinators.emplace_back(c.substr(0, eq), c.substr(eq + 1));
  }
  std::printf("%7s %6s %8s %6s %13s %6s %6s %8s %8s %8s %8s %9s %9s %8s %8s %7s %5s\n", "workers",
              "fanout", "coord", "CPU", "RSS MiB", "redis", "bench", "rec p50", "rec p99",
              "lease50", "lease99", "sent KiB/s", "recv KiB/s", "rec out", "rec in", "dropped",
              "load");
  std::printf("%7s %6s %8s %6s %13s %6s %6s %8s %8s %8s %8s %9s %9s %8s %8s %7s %5s\n", "", "",
              "binary", "cores", "now (peak)", "cores", "cores", "ms", "ms", "ms", "ms", "/worker",
              "/worker", "/w/s", "/w/s", "batches", "1min");
  bool failed = false;
  for (int n : counts) {
    for (const std::string& mode : modes) {
      for (const auto& [label, path] : coordinators) {
        s.coordinator = path;
        s.label = label;
        RunFigures f = RunConfig(s, n, mode, smoke);
        if (!f.error.empty()) {
          std::fprintf(stderr, "error: %d workers, --fanout=%s, %s: %s (logs in %s)\n", n,
                       mode.c_str(), label.c_str(), f.error.c_str(), s.tmp.c_str());
          return 1;
        }
        const std::string load = f.load.empty() ? LoadAverage() : f.load;
        std::printf(
            "%7d %6s %8s %6.2f %6.0f (%4.0f) %6.2f %6.2f %8.1f %8.1f %8.1f %8.1f %9.1f %9.1f "
            "%8.0f %8.0f %7llu %5s\n",
            n, mode.c_str(), label.substr(0, 8).c_str(), f.coord_cores, f.rss_mib, f.peak_mib,
            f.redis_cores, f.bench_cores, f.rec_p50, f.rec_p99, f.lease_p50, f.lease_p99,
            f.sent_kib_s, f.recv_kib_s, f.records_sent_s, f.records_recv_s,
            (unsigned long long)f.dropped_batches, load.substr(0, load.find(' ')).c_str());
        std::fflush(stdout);
        for (const std::string& why : f.failures) {
          std::fprintf(stderr, "FAILED: %d workers, --fanout=%s, %s: %s\n", n, mode.c_str(),
                       label.c_str(), why.c_str());
          failed = true;
        }
      }
    }
  }
  std::printf("\nload average at the end: %s\n", LoadAverage().c_str());
  if (!failed) std::system(("rm -rf '" + s.tmp + "'").c_str());
  return failed ? 1 : 0;
}
