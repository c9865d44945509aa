// SimWorker and SimScene: the scale simulation's workers (see sim_worker.h).
#include "bench/sim_worker.h"

#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <cmath>

#include "coordinator/fanout_region.h"
#include "service/record_codec.h"
#include "worker/tile_region.h"

namespace irfarm {
namespace {

constexpr size_t kTileHits = 256;    // first hits drawn per tile (records jitter around them)
constexpr size_t kImageHits = 8192;  // first hits over the whole image

// splitmix64: a tiny deterministic generator (one per worker or per tile).
uint64_t SplitMix(uint64_t* state) {
  uint64_t z = (*state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
float Unit(uint64_t* state) { return float(SplitMix(state) >> 40) * (1.0f / 16777216.0f); }

// First hit of the camera ray through image point (x, y), if any.
std::optional<SimHit> CameraHit(const Scene& scene, float x, float y) {
  const Camera& camera = scene.camera();
  Ray ray;
  ray.origin = camera.origin();
  ray.dir = camera.Direction(x, y);
  SurfaceHit hit;
  if (!scene.Intersect(ray, &hit)) return std::nullopt;
  Vec3 n = hit.ns;
  if (Dot(n, ray.dir) > 0) n = -n;  // records face the side they were made for
  return SimHit{hit.p, n, camera.PixelSpread(hit.t)};
}

}  // namespace

SimScene::SimScene(const Scene* scene, const RecordBounds& bounds, float accuracy, int tile_size)
    : scene_(scene), tile_size_(tile_size), bounds_(bounds), accuracy_(accuracy) {
  const Camera& camera = scene->camera();
  const int tx = (camera.width() + tile_size - 1) / tile_size;
  const int ty = (camera.height() + tile_size - 1) / tile_size;
  tiles_.resize(size_t(tx) * size_t(ty));
  for (auto& t : tiles_) t = std::make_unique<Tile>();
  uint64_t rng = 12345;
  for (size_t i = 0; i < kImageHits * 4 && image_hits_.size() < kImageHits; ++i) {
    const float x = Unit(&rng) * float(camera.width()), y = Unit(&rng) * float(camera.height());
    if (std::optional<SimHit> h = CameraHit(*scene, x, y)) image_hits_.push_back(*h);
  }
}

const SimScene::Tile* SimScene::TileInfo(int index, const PixelRect& rect) {
  if (index < 0 || size_t(index) >= tiles_.size()) return nullptr;
  Tile* t = tiles_[size_t(index)].get();
  std::call_once(t->once, [&] {
    t->region = TileRegionOf(*scene_, rect);
    uint64_t rng = 777 + uint64_t(index);
    for (size_t i = 0; i < kTileHits * 4 && t->hits.size() < kTileHits; ++i) {
      const float x = float(rect.x0) + Unit(&rng) * float(rect.width());
      const float y = float(rect.y0) + Unit(&rng) * float(rect.height());
      if (std::optional<SimHit> h = CameraHit(*scene_, x, y)) t->hits.push_back(*h);
    }
  });
  return t;
}

void SimScene::PrepareAll(int threads) {
  const Camera& camera = scene_->camera();
  const int tx = (camera.width() + tile_size_ - 1) / tile_size_;
  std::atomic<int> next{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < std::max(1, threads); ++t)
    pool.emplace_back([&] {
      for (int i = next++; size_t(i) < tiles_.size(); i = next++) {
        const int x0 = (i % tx) * tile_size_, y0 = (i / tx) * tile_size_;
        TileInfo(i, PixelRect{x0, y0, std::min(x0 + tile_size_, camera.width()),
                              std::min(y0 + tile_size_, camera.height())});
      }
    });
  for (std::thread& t : pool) t.join();
}

void SimWorker::Start() {
  rng_ = 0x5eed0000ull + options_.index;
  thread_ = std::thread([this] { Run(); });
}

uint64_t SimWorker::NextRandom() { return SplitMix(&rng_); }

void SimWorker::DrawRecords(size_t n, const SimScene::Tile* tile) {
  const SimScene& s = *options_.scene;
  const std::vector<SimHit>& image = s.image_hits();
  const RecordBounds& b = s.bounds();
  records_.clear();
  for (size_t i = 0; i < n; ++i) {
    const bool far = tile == nullptr || tile->hits.empty() || Uniform() < options_.far_fraction;
    const std::vector<SimHit>& pool = far ? image : tile->hits;
    if (pool.empty()) return;
    const SimHit& h = pool[NextRandom() % pool.size()];
    // Jitter within about a pixel footprint in the tangent plane (records do not pile up on the
    // pool's points), kept inside the record bounds the coordinator enforces.
    const Vec3 t1 =
        Normalize(std::abs(h.n.x) > 0.5f ? Cross(h.n, Vec3(0, 1, 0)) : Cross(h.n, Vec3(1, 0, 0)));
    const Vec3 t2 = Cross(h.n, t1);
    IrradianceRecord r;
    r.position =
        h.p + t1 * ((Uniform() - 0.5f) * h.footprint) + t2 * ((Uniform() - 0.5f) * h.footprint);
    r.position = Min(Max(r.position, b.box.lo), b.box.hi);
    r.normal = h.n;
    // Reach a * R between 1.5 and 16 pixel footprints, log-uniform.
    const float spacing_px = 1.5f * std::exp(Uniform() * std::log(16.0f / 1.5f));
    r.radius = std::min(spacing_px * h.footprint / s.accuracy(), 0.5f * b.max_radius);
    if (!(r.radius > 1e-6f)) r.radius = 1e-6f;
    const float e_max = std::min(10.0f, 0.5f * b.max_irradiance);
    r.irradiance = Vec3(0.02f + Uniform(), 0.02f + Uniform(), 0.02f + Uniform()) * (e_max / 1.02f);
    records_.push_back(r);
  }
}

void SimWorker::ReceiveRecords(const v1::RecordBatch& batch, uint32_t now_us) {
  const int n = batch.origins_size();
  if (batch.values_size() != n * kFloatsPerRecord) return;
  const float* v = batch.values().data();
  const MeasureWindow& window = *options_.window;
  for (int i = 0; i < n; ++i, v += kFloatsPerRecord) {
    const RecordTag tag = GetTag(v);
    if (options_.keep_records) stats_.received_ids.push_back(tag.Id());
    if (!Live(v, tag.send_us)) {
      ++stats_.records_late;
      continue;
    }
    ++stats_.records_live;
    if (window.SentInside(tag.send_us)) {
      stats_.record_latency.Add(now_us - tag.send_us);
      ++stats_.window_records_received;
    }
  }
}

bool SimWorker::Live(const float* packed, uint32_t send_us) {
  if (!has_steps_.load()) return false;
  // Sent after the last region step: filtered against that union or a larger one, so live.
  if (int32_t(send_us - last_step_us_.load()) >= 0) return true;
  std::lock_guard<std::mutex> lock(mu_);
  for (size_t i = region_steps_.size(); i-- > 0;) {
    if (int32_t(send_us - region_steps_[i].at_us) < 0) continue;
    if (!options_.filtered) return true;
    IrradianceRecord r;
    r.position = Vec3(packed[0], packed[1], packed[2]);
    r.radius = packed[9];
    return RecordReachesBox(r, region_steps_[i].box, options_.scene->accuracy());
  }
  return false;  // sent before this worker joined the job
}

void SimWorker::Read(grpc::ClientReaderWriter<v1::WorkerMessage, v1::CoordinatorMessage>* stream) {
  v1::CoordinatorMessage m;
  const MeasureWindow& window = *options_.window;
  while (stream->Read(&m)) {
    const uint32_t now_us = NowUs32();
    if (window.open()) stats_.window_bytes_received += m.ByteSizeLong();
    switch (m.msg_case()) {
      case v1::CoordinatorMessage::kRecords:
        ReceiveRecords(m.records().batch(), now_us);
        break;
      case v1::CoordinatorMessage::kLease: {
        if (awaiting_lease_.exchange(false) && window.open())
          stats_.lease_latency.Add(now_us - result_sent_us_.load());
        std::lock_guard<std::mutex> lock(mu_);
        leases_.push_back(m.lease());
        cv_.notify_all();
        break;
      }
      case v1::CoordinatorMessage::kJobSpec: {
        std::lock_guard<std::mutex> lock(mu_);
        job_id_ = m.job_spec().job_id();
        Bounds3 all;
        if (!options_.filtered) all = options_.scene->bounds().box;
        region_steps_.assign(1, RegionStep{now_us, all});
        last_step_us_ = now_us;
        has_steps_ = true;
        break;
      }
      case v1::CoordinatorMessage::kJobClosed:
        stats_.job_closed = true;
        job_closed_ = true;
        break;
      case v1::CoordinatorMessage::kRejected:
        ++stats_.rejected;
        stats_.last_rejection = m.rejected().reason();
        break;
      default:
        break;
    }
  }
  std::lock_guard<std::mutex> lock(mu_);
  broken_ = true;
  cv_.notify_all();
}

void SimWorker::Run() {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(256 << 20);
  // A connection of its own, as a separate worker process would have (channels with equal
  // arguments otherwise share one).
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  std::shared_ptr<grpc::Channel> channel =
      grpc::CreateCustomChannel(options_.coordinator, grpc::InsecureChannelCredentials(), args);
  std::unique_ptr<v1::WorkerService::Stub> stub = v1::WorkerService::NewStub(channel);
  // Wait for the connection, and let the session wait for it too: with many simulated workers
  // connecting at once, a first connection attempt failed now and then ("failed to connect to
  // all addresses"), and a call without wait-for-ready gave up at once (service_scale_smoke saw
  // 1 of 8 workers not register in 30 s, in one run of three beside other tests).
  if (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(20))) {
    stats_.error = "session refused: no connection to " + options_.coordinator + " in 20 s";
    return;
  }
  grpc::ClientContext context;
  context.set_wait_for_ready(true);
  auto stream = stub->Session(&context);
  const MeasureWindow& window = *options_.window;
  auto heartbeat = std::chrono::milliseconds(1000);
  {
    v1::WorkerMessage reg;
    reg.mutable_register_()->set_name("sim-" + std::to_string(options_.index));
    reg.mutable_register_()->set_threads(1);
    reg.mutable_register_()->set_reports_regions(true);
    v1::CoordinatorMessage reply;
    if (!stream->Write(reg) || !stream->Read(&reply) || !reply.has_registered()) {
      context.TryCancel();
      stats_.error = "session refused: " + stream->Finish().error_message();
      return;
    }
    stats_.worker_id = reply.registered().worker_id();
    if (reply.registered().heartbeat_ms() > 0)
      heartbeat = std::chrono::milliseconds(reply.registered().heartbeat_ms());
  }
  registered_ = true;
  std::thread reader([&] { Read(stream.get()); });
  auto last_write = std::chrono::steady_clock::now();
  const auto write = [&](const v1::WorkerMessage& m) {
    if (window.open()) stats_.window_bytes_sent += m.ByteSizeLong();
    last_write = std::chrono::steady_clock::now();
    return stream->Write(m);
  };
  bool ok = true;
  while (ok && !stop_) {
    v1::TileLease lease;
    std::string job_id;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait_for(lock, heartbeat / 2, [&] { return !leases_.empty() || broken_ || stop_; });
      if (broken_) break;
      if (leases_.empty()) {
        lock.unlock();
        if (std::chrono::steady_clock::now() - last_write >= heartbeat / 2) {
          v1::WorkerMessage hb;
          hb.mutable_heartbeat();
          ok = write(hb);
        }
        continue;
      }
      lease = leases_.front();
      leases_.pop_front();
      job_id = job_id_;
    }
    const PixelRect rect{lease.rect().x0(), lease.rect().y0(), lease.rect().x1(),
                         lease.rect().y1()};
    const SimScene::Tile* tile = options_.scene->TileInfo(lease.tile_index(), rect);
    if (job_id != lease.job_id() || tile == nullptr) {
      v1::WorkerMessage m;
      v1::TileFailed* tf = m.mutable_tile_failed();
      tf->set_job_id(lease.job_id());
      tf->set_tile_index(lease.tile_index());
      tf->set_lease_token(lease.lease_token());
      tf->set_reason("simulated worker: no job spec for the lease");
      ok = write(m);
      continue;
    }
    const auto lease_start = std::chrono::steady_clock::now();
    if (tile->region) {
      v1::WorkerMessage rm;
      v1::TileRegion* tr = rm.mutable_tile_region();
      tr->set_job_id(lease.job_id());
      tr->set_lease_token(lease.lease_token());
      tr->set_min_x(tile->region->lo.x);
      tr->set_min_y(tile->region->lo.y);
      tr->set_min_z(tile->region->lo.z);
      tr->set_max_x(tile->region->hi.x);
      tr->set_max_y(tile->region->hi.y);
      tr->set_max_z(tile->region->hi.z);
      if (options_.keep_records) stats_.regions.push_back(*tr);
      if (options_.filtered) {
        absl::StatusOr<Bounds3> clipped = ParseTileRegion(*tr, options_.scene->bounds().box);
        std::lock_guard<std::mutex> lock(mu_);
        if (clipped.ok() && !region_steps_.empty()) {
          RegionStep step = region_steps_.back();
          step.box.Extend(*clipped);
          step.at_us = NowUs32();
          region_steps_.push_back(step);
          last_step_us_ = step.at_us;
        }
      }
      if (!(ok = write(rm))) break;
    }
    // "Render": publish records at the rate, every flush interval, for the drawn tile time.
    const auto end =
        lease_start +
        std::chrono::microseconds(int64_t(options_.tile_seconds * 1e6 * (0.5 + double(Uniform()))));
    double owed = 0;  // records due but not yet drawn (fractions carry over)
    uint64_t tile_records = 0;
    auto last = lease_start;
    for (bool last_flush = false; ok && !last_flush && !stop_;) {
      auto next = std::min(last + options_.flush_interval, end);
      std::this_thread::sleep_until(next);
      const auto now = std::chrono::steady_clock::now();
      last_flush = now >= end;
      owed += options_.records_per_second * std::chrono::duration<double>(now - last).count();
      last = now;
      const size_t n = size_t(owed);
      owed -= double(n);
      if (n == 0) continue;
      DrawRecords(n, tile);
      const uint32_t send_us = NowUs32();
      for (IrradianceRecord& r : records_) {
        PutTag(RecordTag{options_.index, sequence_++, send_us}, &r);
        if (options_.keep_records) stats_.published.push_back(r);
      }
      v1::WorkerMessage m;
      m.mutable_records()->set_job_id(lease.job_id());
      PackRecords(records_, stats_.worker_id, m.mutable_records()->mutable_batch());
      ok = write(m);
      stats_.records_sent += records_.size();
      tile_records += records_.size();
      if (window.SentInside(send_us)) stats_.window_records_sent += records_.size();
    }
    if (!ok || stop_) break;
    v1::WorkerMessage m;
    v1::TileResult* tr = m.mutable_tile_result();
    tr->set_job_id(lease.job_id());
    tr->set_tile_index(lease.tile_index());
    tr->set_lease_token(lease.lease_token());
    *tr->mutable_rect() = lease.rect();
    const int floats = rect.width() * rect.height() * 3;
    tr->mutable_pixels()->Resize(floats, 0.18f);
    v1::TileStats* ts = tr->mutable_stats();
    ts->set_records_computed(tile_records);
    ts->set_lookups(uint64_t(rect.width()) * rect.height());
    ts->set_lookup_hits(uint64_t(rect.width()) * rect.height() / 2);
    ts->set_wall_seconds(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - lease_start).count());
    result_sent_us_ = NowUs32();
    awaiting_lease_ = true;
    ok = write(m);
    ++stats_.tiles;
  }
  if (!ok) stats_.error = "stream broke";
  stream->WritesDone();
  context.TryCancel();
  reader.join();
  (void)stream->Finish();
}

}  // namespace irfarm
