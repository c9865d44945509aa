// Worker: session loop, tile rendering, record publishing, reconnects (see worker.h).
#include "worker/worker.h"

#include <grpcpp/grpcpp.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <optional>
#include <thread>
#include <tuple>

#include "service/coordinator_list.h"
#include "service/job_settings.h"
#include "service/record_codec.h"
#include "worker/tile_region.h"

namespace irfarm {
namespace {

// How long a warm-started job's tile waits for its region's records (RegionReady).
constexpr auto kRegionReadyWait = std::chrono::seconds(5);
// How long a stopped worker waits for the coordinator to end the session after its last message.
constexpr auto kGoodbyeWait = std::chrono::seconds(5);
// What one session holds for the coordinator at most (it is not trusted either): jobs loaded or
// failed (kMaxWorkerJobs, service/job_settings.h: each a scene, a cache and a temp dir until its
// JobClosed), and leases not yet started (an honest coordinator sends one at a time).
constexpr size_t kMaxQueuedLeases = 256;
// A lease token is 16 bytes (coordinator/lease_token.h); 64 is generous. A longer token, or a job
// id longer than JobContext::kMaxIdLength, from the coordinator is dropped on arrival: it was
// stored whole (256 queued leases of a 200 MB token each), logged and echoed back (a review).
constexpr size_t kMaxLeaseTokenBytes = 64;
// A lease's time is clamped to a week: steady_clock's nanoseconds overflow past about 9.2e12 ms.
constexpr int64_t kMaxLeaseMs = int64_t(7) * 24 * 3600 * 1000;

// State shared by a session's reader, publisher and render threads.
struct SessionState {
  std::mutex mu;
  std::condition_variable cv;
  // Leases not yet started, each with when it arrived (its lease time runs from then).
  std::deque<std::pair<v1::TileLease, std::chrono::steady_clock::time_point>> leases;
  std::map<std::string, std::shared_ptr<JobContext>> jobs;
  std::map<std::string, std::string> failed_jobs;  // job id -> why its scene did not load
  bool broken = false;
  // The tile being rendered: its job and the flag that stops its render (RenderSettings::cancel),
  // set when that job is closed (cancelled, failed, or finished by others) or the session breaks:
  // its result would go nowhere. A stopped worker (Stop) still finishes its tile.
  std::string tile_job;
  std::atomic<bool>* tile_cancel = nullptr;
  // The tile's lease deadline (received + TileLease::lease_ms; none when that is 0): past it the
  // coordinator has given the tile to another worker, so the render stops (tile_overdue) and the
  // worker is free for its next lease, rather than finish a tile whose result is stale (or hang
  // on one).
  std::optional<std::chrono::steady_clock::time_point> tile_deadline;
  bool tile_overdue = false;
  // The lease token a warm-started job's tile waits on (empty: none) and whether its RegionReady
  // has arrived.
  std::string region_wait;
  bool region_ready = false;
  uint32_t worker_id = 0;
  std::mutex write_mu;  // one writer at a time on the stream
  // Held while records are taken and written, so that a tile's records are all on the stream
  // before its result (the coordinator takes records only while the lease is held).
  std::mutex publish_mu;
};

}  // namespace

void Worker::Stop() {
  stop_ = true;
  stop_cv_.notify_all();
}

int Worker::Run() {
  absl::StatusOr<std::string> token = LoadClientToken(options_.auth);
  absl::StatusOr<std::shared_ptr<grpc::ChannelCredentials>> credentials =
      MakeChannelCredentials(options_.auth);
  if (!token.ok() || !credentials.ok()) {
    spdlog::error("{}", (!token.ok() ? token.status() : credentials.status()).ToString());
    return 2;
  }
  absl::StatusOr<std::vector<std::string>> addresses = CoordinatorList::Parse(options_.coordinator);
  if (!addresses.ok()) {
    spdlog::error("{}", addresses.status().ToString());
    return 2;
  }
  token_ = *token;
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(256 << 20);
  // Reconnect quickly after a coordinator restart or a standby's takeover (gRPC's default starts
  // at 1 s and grows 1.6x to 120 s): a coordinator that starts listening is seen within 1 s.
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
  const int keepalive_ms = int(std::chrono::milliseconds(options_.keepalive).count());
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, keepalive_ms);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, keepalive_ms);
  args.SetInt(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);  // an idle worker keeps pinging
  CoordinatorList coordinators(*addresses, *credentials, args);
  auto backoff = std::chrono::milliseconds(250);
  while (!stop_) {
    // Wait for a connection in short steps, so that a stop request is seen promptly.
    std::optional<size_t> i = coordinators.FindConnected(std::chrono::system_clock::now() +
                                                         std::chrono::milliseconds(500));
    if (!i) continue;
    std::unique_ptr<v1::WorkerService::Stub> stub =
        v1::WorkerService::NewStub(coordinators.channel(*i));
    const auto start = std::chrono::steady_clock::now();
    RunSession(stub.get(), coordinators.address(*i));
    if (stop_) break;
    if (std::chrono::steady_clock::now() - start > std::chrono::seconds(10))
      backoff = std::chrono::milliseconds(250);  // it was up for a while: retry soon
    spdlog::warn("coordinator {} unreachable; retrying in {} ms", options_.coordinator,
                 backoff.count());
    std::unique_lock<std::mutex> lock(stop_mu_);
    stop_cv_.wait_for(lock, backoff, [&] { return stop_.load(); });
    backoff = std::min(backoff * 2, std::chrono::milliseconds(10000));
  }
  return 0;
}

void Worker::RunSession(v1::WorkerService::Stub* stub, const std::string& address) {
  grpc::ClientContext context;
  AddToken(&context, token_);
  std::unique_ptr<grpc::ClientReaderWriter<v1::WorkerMessage, v1::CoordinatorMessage>> stream =
      stub->Session(&context);
  SessionState s;
  auto heartbeat = std::chrono::milliseconds(5000);
  {
    v1::WorkerMessage reg;
    reg.mutable_register_()->set_name(options_.name);
    reg.mutable_register_()->set_threads(options_.threads);
    reg.mutable_register_()->set_reports_regions(true);
    v1::CoordinatorMessage reply;
    if (!stream->Write(reg) || !stream->Read(&reply) || !reply.has_registered()) {
      context.TryCancel();
      const grpc::Status st = stream->Finish();
      if (!st.ok()) spdlog::error("session refused: {}", st.error_message());
      return;
    }
    s.worker_id = reply.registered().worker_id();
    metrics_.sessions->Add();
    metrics_.connected->Set(1);
    if (reply.registered().heartbeat_ms() > 0)
      heartbeat = std::chrono::milliseconds(reply.registered().heartbeat_ms());
    else if (reply.registered().heartbeat_seconds() > 0)
      heartbeat = std::chrono::seconds(reply.registered().heartbeat_seconds());
    spdlog::info("registered with {} as worker {}", address, s.worker_id);
  }
  const auto write = [&](const v1::WorkerMessage& m) {
    std::lock_guard<std::mutex> lock(s.write_mu);
    ScopedTimer timer(metrics_.write_seconds);
    return stream->Write(m);
  };

  std::thread reader([&] {
    v1::CoordinatorMessage m;
    while (stream->Read(&m)) {
      if (m.has_job_spec()) {
        if (m.job_spec().job_id().size() > JobContext::kMaxIdLength) {
          spdlog::warn("job spec ignored: its id of {} bytes is longer than {}",
                       m.job_spec().job_id().size(), JobContext::kMaxIdLength);
          continue;
        }
        {
          // A job is loaded once: a second spec for it would replace the scene of a tile in
          // progress (whose records then never went out) and load on this thread again.
          std::lock_guard<std::mutex> lock(s.mu);
          if (s.jobs.count(m.job_spec().job_id()) || s.failed_jobs.count(m.job_spec().job_id())) {
            spdlog::warn("job {}: a second job spec ignored", m.job_spec().job_id().substr(0, 64));
            continue;
          }
          if (s.jobs.size() + s.failed_jobs.size() >= kMaxWorkerJobs) {
            spdlog::warn("job {}: spec ignored, {} jobs are open already",
                         m.job_spec().job_id().substr(0, 64), kMaxWorkerJobs);
            continue;
          }
        }
        absl::StatusOr<std::unique_ptr<JobContext>> job =
            JobContext::Create(m.job_spec(), options_.threads);
        std::lock_guard<std::mutex> lock(s.mu);
        if (job.ok()) {
          s.jobs[m.job_spec().job_id()] = std::move(*job);
        } else {
          spdlog::error("job {}: {}", m.job_spec().job_id(), job.status().ToString());
          s.failed_jobs[m.job_spec().job_id()] = std::string(job.status().message());
        }
      } else if (m.has_records()) {
        std::shared_ptr<JobContext> job;
        {
          std::lock_guard<std::mutex> lock(s.mu);
          auto it = s.jobs.find(m.records().job_id());
          if (it != s.jobs.end()) job = it->second;
        }
        absl::StatusOr<std::vector<IrradianceRecord>> recs = DecodeRecords(m.records().batch());
        if (recs.ok()) {
          metrics_.records_received->Add(recs->size());
          metrics_.record_bytes_received->Add(BatchBytes(m.records().batch()));
        }
        if (job && recs.ok()) job->InsertRemote(*recs);
      } else if (m.has_lease()) {
        if (m.lease().job_id().size() > JobContext::kMaxIdLength ||
            m.lease().lease_token().size() > kMaxLeaseTokenBytes) {
          spdlog::warn(
              "lease of tile {} ignored: a job id of {} bytes (at most {}) or a token of {} (at "
              "most {})",
              m.lease().tile_index(), m.lease().job_id().size(), JobContext::kMaxIdLength,
              m.lease().lease_token().size(), kMaxLeaseTokenBytes);
          continue;
        }
        std::lock_guard<std::mutex> lock(s.mu);
        if (s.leases.size() >= kMaxQueuedLeases) {
          spdlog::warn("lease of tile {} ignored: {} leases are waiting already",
                       m.lease().tile_index(), kMaxQueuedLeases);
          continue;
        }
        s.leases.emplace_back(m.lease(), std::chrono::steady_clock::now());
        s.cv.notify_all();
      } else if (m.has_region_ready()) {
        // In stream order: the region's records, read before it, are in the job's cache.
        // Only the one a tile waits on counts (other jobs' tiles do not wait).
        std::lock_guard<std::mutex> lock(s.mu);
        if (!s.region_wait.empty() && m.region_ready().lease_token() == s.region_wait) {
          s.region_ready = true;
          s.cv.notify_all();
        }
      } else if (m.has_job_closed()) {
        std::lock_guard<std::mutex> lock(s.mu);
        s.jobs.erase(m.job_closed().job_id());  // a tile in progress keeps its shared_ptr
        s.failed_jobs.erase(m.job_closed().job_id());
        if (s.tile_cancel != nullptr && s.tile_job == m.job_closed().job_id())
          s.tile_cancel->store(true);
      } else if (m.has_drain()) {
        Stop();
      } else if (m.has_rejected()) {
        spdlog::warn("coordinator rejected a message ({} of {}): {}", m.rejected().violations(),
                     m.rejected().limit(), m.rejected().reason());
      }
    }
    std::lock_guard<std::mutex> lock(s.mu);
    s.broken = true;
    if (s.tile_cancel != nullptr) s.tile_cancel->store(true);
    s.cv.notify_all();
  });

  // Publisher: new own records of every job, at least every flush_interval; heartbeats.
  std::atomic<bool> session_done{false};
  const auto publish_all = [&] {
    std::lock_guard<std::mutex> publishing(s.publish_mu);
    std::vector<std::shared_ptr<JobContext>> jobs;
    {
      std::lock_guard<std::mutex> lock(s.mu);
      for (auto& [id, j] : s.jobs) jobs.push_back(j);
    }
    for (const std::shared_ptr<JobContext>& j : jobs) {
      for (;;) {
        std::vector<IrradianceRecord> recs = j->TakeNewOwnRecords(options_.max_batch_records);
        if (recs.empty()) break;
        v1::WorkerMessage m;
        m.mutable_records()->set_job_id(j->job_id());
        PackRecords(recs, s.worker_id, m.mutable_records()->mutable_batch());
        if (!write(m)) return;
        metrics_.records_sent->Add(recs.size());
        metrics_.record_bytes_sent->Add(BatchBytes(m.records().batch()));
      }
    }
  };
  // Drain goes out as soon as the worker is stopped (not after its tile): the coordinator then
  // leases it nothing more while the tile in progress finishes and is reported.
  std::atomic<bool> drain_sent{false};
  const auto send_drain = [&] {
    if (!stop_ || drain_sent.exchange(true)) return;
    v1::WorkerMessage drain;
    drain.mutable_drain();
    write(drain);
  };
  std::thread publisher([&] {
    auto last_heartbeat = std::chrono::steady_clock::now();
    while (!session_done) {
      std::this_thread::sleep_for(options_.flush_interval);
      {
        std::lock_guard<std::mutex> lock(s.mu);
        if (s.tile_cancel != nullptr && s.tile_deadline && !s.tile_overdue &&
            std::chrono::steady_clock::now() > *s.tile_deadline) {
          s.tile_overdue = true;
          s.tile_cancel->store(true);
        }
      }
      send_drain();
      publish_all();
      if (std::chrono::steady_clock::now() - last_heartbeat >= heartbeat) {
        v1::WorkerMessage hb;
        hb.mutable_heartbeat();
        write(hb);
        last_heartbeat = std::chrono::steady_clock::now();
      }
    }
  });

  // Tells the coordinator a leased tile will not come (it holds the lease until it hears).
  const auto tile_failed = [&](const v1::TileLease& lease, const std::string& reason) {
    v1::WorkerMessage m;
    v1::TileFailed* tf = m.mutable_tile_failed();
    tf->set_job_id(lease.job_id());
    tf->set_tile_index(lease.tile_index());
    tf->set_lease_token(lease.lease_token());
    tf->set_reason(reason);
    write(m);
  };

  // Render loop (this thread).
  for (;;) {
    v1::TileLease lease;
    std::chrono::steady_clock::time_point received;
    std::shared_ptr<JobContext> job;
    std::string failure;
    {
      std::unique_lock<std::mutex> lock(s.mu);
      s.cv.wait_for(lock, std::chrono::milliseconds(200),
                    [&] { return !s.leases.empty() || s.broken || stop_; });
      if (s.broken || stop_) break;
      if (s.leases.empty()) continue;
      std::tie(lease, received) = s.leases.front();
      s.leases.pop_front();
      auto it = s.jobs.find(lease.job_id());
      if (it != s.jobs.end()) job = it->second;
      auto f = s.failed_jobs.find(lease.job_id());
      failure = f != s.failed_jobs.end() ? f->second : "job spec not received";
    }
    const PixelRect rect{lease.rect().x0(), lease.rect().y0(), lease.rect().x1(),
                         lease.rect().y1()};
    // The rectangle comes over the network: inside the film and not empty, or the tile fails
    // (a negative or huge one would reach the image allocation).
    // Nor larger than the job's tiles (the coordinator leases no more): a whole 40000 x 40000
    // film as one lease would be allocated as one image.
    if (job && !(0 <= rect.x0 && rect.x0 < rect.x1 && rect.x1 <= job->scene().camera().width() &&
                 0 <= rect.y0 && rect.y0 < rect.y1 && rect.y1 <= job->scene().camera().height() &&
                 rect.x1 - rect.x0 <= job->tile_size() && rect.y1 - rect.y0 <= job->tile_size())) {
      failure = "lease rectangle [" + std::to_string(rect.x0) + ", " + std::to_string(rect.x1) +
                ") x [" + std::to_string(rect.y0) + ", " + std::to_string(rect.y1) +
                ") is empty, outside the " + std::to_string(job->scene().camera().width()) + " x " +
                std::to_string(job->scene().camera().height()) + " film or larger than the job's " +
                std::to_string(job->tile_size()) + " px tiles";
      spdlog::error("job {}: {}", lease.job_id(), failure);
      job.reset();
    }
    if (!job) {
      tile_failed(lease, failure);
      metrics_.tiles_failed->Add();
      continue;
    }
    // What the tile sees, before rendering it: the coordinator then sends the records that
    // reach it (filtered fan-out), while the tile renders.
    if (std::optional<Bounds3> box = TileRegionOf(job->scene(), rect)) {
      v1::WorkerMessage rm;
      v1::TileRegion* tr = rm.mutable_tile_region();
      tr->set_job_id(lease.job_id());
      tr->set_lease_token(lease.lease_token());
      tr->set_min_x(box->lo.x);
      tr->set_min_y(box->lo.y);
      tr->set_min_z(box->lo.z);
      tr->set_max_x(box->hi.x);
      tr->set_max_y(box->hi.y);
      tr->set_max_z(box->hi.z);
      // A warm-started job's records come from the snapshot: with filtered fan-out those that
      // reach this tile come with the region's backlog, and a tile rendered before they arrive
      // remakes them (two workers, cornell-box at 64x64: 61-89 new records against 4-16 for a
      // local render of the same snapshot). Wait for them, a bounded time (an older coordinator
      // sends no RegionReady). Armed before the region goes out, so an early reply counts.
      if (job->warm()) {
        std::lock_guard<std::mutex> lock(s.mu);
        s.region_wait = lease.lease_token();
        s.region_ready = false;
      }
      if (!write(rm)) break;
      if (job->warm()) {
        std::unique_lock<std::mutex> lock(s.mu);
        s.cv.wait_for(lock, kRegionReadyWait, [&] { return s.region_ready || s.broken || stop_; });
        s.region_wait.clear();
      }
    }
    RenderSettings tile_settings = job->settings();
    tile_settings.budget_carry = job->TakeBudgetCarry();
    std::atomic<bool> cancel{false};
    {
      std::lock_guard<std::mutex> lock(s.mu);
      s.tile_job = lease.job_id();
      s.tile_cancel = &cancel;
      s.tile_deadline.reset();
      if (lease.lease_ms() > 0)
        s.tile_deadline =
            received + std::chrono::milliseconds(std::min(lease.lease_ms(), kMaxLeaseMs));
      s.tile_overdue = false;
      // Closed meanwhile, or closed and sent again as a new job of the same id (this tile's
      // records would go out with neither job: publish_all walks s.jobs).
      const auto open = s.jobs.find(lease.job_id());
      if (s.broken || open == s.jobs.end() || open->second != job) cancel = true;
    }
    tile_settings.cancel = &cancel;
    RenderOutput out = RenderRect(job->scene(), tile_settings, job->cache(), rect);
    bool overdue = false;
    {
      std::lock_guard<std::mutex> lock(s.mu);
      s.tile_cancel = nullptr;
      s.tile_job.clear();
      overdue = s.tile_overdue;
    }
    job->AddBudgetCarry(out.stats.budget_left);
    if (out.stats.cancelled) {
      metrics_.tiles_cancelled->Add();
      const std::string why =
          overdue ? "the lease deadline passed" : "the job was closed or the session broke";
      spdlog::info("job {}: tile {} stopped ({})", lease.job_id(), lease.tile_index(), why);
      // A closed job's tile too (it is not counted as a failure there), and an overdue one
      // (stale there: the lease expired): the coordinator then leases the next tile. A broken
      // session ends at the loop's top.
      tile_failed(lease, "stopped: " + why + " while the tile rendered");
      continue;
    }
    publish_all();  // the tile's records go out before its result
    v1::WorkerMessage m;
    v1::TileResult* tr = m.mutable_tile_result();
    tr->set_job_id(lease.job_id());
    tr->set_tile_index(lease.tile_index());
    tr->set_lease_token(lease.lease_token());
    *tr->mutable_rect() = lease.rect();
    tr->mutable_pixels()->Reserve(int(out.image.pixels.size() * 3));
    for (const Vec3& p : out.image.pixels) {
      tr->add_pixels(p.x);
      tr->add_pixels(p.y);
      tr->add_pixels(p.z);
    }
    if (!out.aovs.empty()) {  // the job is denoised: send the guides along
      tr->mutable_guides()->Reserve(int(out.image.pixels.size() * 6));
      for (size_t i = 0; i < out.image.pixels.size(); ++i)
        for (const Vec3* v : {&out.aovs.albedo.pixels[i], &out.aovs.normal.pixels[i]})
          for (int k = 0; k < 3; ++k) tr->add_guides((*v)[k]);
    }
    if (!out.peak.pixels.empty()) {  // the job's fireflies are spread by the coordinator
      tr->mutable_peaks()->Reserve(int(out.peak.pixels.size() * 3));
      for (const Vec3& p : out.peak.pixels)
        for (int k = 0; k < 3; ++k) tr->add_peaks(p[k]);
    }
    const RenderCounters& c = out.stats.counters;
    v1::TileStats* ts = tr->mutable_stats();
    ts->set_records_computed(c.records_computed);
    ts->set_lookups(c.lookups);
    ts->set_lookup_hits(c.lookup_hits);
    ts->set_records_used(c.records_used);
    ts->set_remote_records_used(c.remote_records_used);
    ts->set_wall_seconds(out.stats.PhaseWall("overture") + out.stats.PhaseWall("render"));
    ts->set_records_received(job->TakeReceivedCount());
    if (!write(m)) break;
    metrics_.tiles_completed->Add();
    metrics_.tile_seconds->Observe(ts->wall_seconds());
    metrics_.records_computed->Add(c.records_computed);
    metrics_.lookups->Add(c.lookups);
    metrics_.lookup_hits->Add(c.lookup_hits);
    metrics_.camera_rays->Add(c.camera_rays);
    metrics_.bounce_rays->Add(c.bounce_rays);
    metrics_.shadow_rays->Add(c.shadow_rays);
    metrics_.record_rays->Add(c.record_rays);
  }

  session_done = true;
  publisher.join();
  if (stop_) {
    send_drain();
    stream->WritesDone();
    // The coordinator ends the session once it has read all that was sent (the last tile's
    // result and records): wait for that, a bounded time, before cancelling the call, which
    // could otherwise drop a result still on its way (the tile would be rendered again).
    std::unique_lock<std::mutex> lock(s.mu);
    s.cv.wait_for(lock, kGoodbyeWait, [&] { return s.broken; });
  }
  bool ended = false;  // by the coordinator (or the network), not by this worker
  {
    std::lock_guard<std::mutex> lock(s.mu);
    ended = s.broken;
  }
  if (!ended) context.TryCancel();
  reader.join();
  const grpc::Status status = stream->Finish();
  // Why it ended (PERMISSION_DENIED when the coordinator expelled this worker, a message over
  // its size limit, ...): it went unsaid before.
  if (ended && !status.ok())
    spdlog::warn("session with {} ended: {} ({})", address, status.error_message(),
                 int(status.error_code()));
  metrics_.connected->Set(0);
}

}  // namespace irfarm
