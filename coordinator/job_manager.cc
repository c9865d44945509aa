// JobManager: jobs, tiles, record merge and fan-out, worker mailboxes (see job_manager.h).
#include "coordinator/job_manager.h"

#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <sstream>

#include "cache/snapshot.h"
#include "coordinator/cache_seed.h"
#include "render/image.h"
#include "service/job_settings.h"
#include "service/record_codec.h"
#include "service/scene_bundle.h"
#include "service/scene_hash.h"

namespace irfarm {
namespace {

Bounds3 DescBounds(const SceneDesc& desc) {
  Bounds3 b;
  for (const ShapeDesc& s : desc.shapes) {
    if (s.type == ShapeType::kSphere) {
      b.Extend(s.center - Vec3(s.radius));
      b.Extend(s.center + Vec3(s.radius));
    }
    for (const Vec3& p : s.mesh.positions) b.Extend(p);
  }
  if (b.Empty()) {
    b.Extend(Vec3(-1));
    b.Extend(Vec3(1));
  }
  return b;
}

CacheSettings CacheSettingsOf(const v1::StoredJob& stored) {
  CacheSettings cs;
  if (stored.cache_bounds_size() == 6) {
    cs.bounds.lo = Vec3(stored.cache_bounds(0), stored.cache_bounds(1), stored.cache_bounds(2));
    cs.bounds.hi = Vec3(stored.cache_bounds(3), stored.cache_bounds(4), stored.cache_bounds(5));
  }
  cs.max_accuracy = stored.max_accuracy() > 0 ? stored.max_accuracy() : 0.2f;
  return cs;
}

bool FinalState(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

absl::Status Unavailable(const absl::Status& st) {
  return absl::UnavailableError("job store: " + std::string(st.message()));
}

}  // namespace

absl::StatusOr<std::unique_ptr<JobManager>> JobManager::Create(const JobManagerOptions& options,
                                                               JobStore* store) {
  std::unique_ptr<JobManager> m(new JobManager(options, store));
  absl::Status st = m->Resume();
  if (!st.ok()) return st;
  return m;
}

absl::Status JobManager::Resume() {
  absl::StatusOr<std::vector<v1::StoredJob>> stored = store_->LoadJobs();
  if (!stored.ok()) return Unavailable(stored.status());
  for (v1::StoredJob& s : *stored) {
    auto job = std::make_unique<Job>();
    job->stored = s;
    const v1::Job& j = s.job();
    job->tiles = std::make_unique<TileScheduler>(j.width(), j.height(), JobTileSize(j.settings()),
                                                 options_.max_tile_attempts);
    job->cache = std::make_unique<GlobalCache>(CacheSettingsOf(s));
    absl::StatusOr<std::map<int, std::string>> tiles = store_->LoadTiles(j.id());
    if (!tiles.ok()) return Unavailable(tiles.status());
    for (auto& [tile, pixels] : *tiles) {
      if (tile < 0 || tile >= job->tiles->num_tiles()) continue;
      const PixelRect& r = job->tiles->rect(tile);
      const size_t floats = size_t(r.width()) * r.height() * (j.settings().denoise() ? 9 : 3);
      if (pixels.size() != floats * sizeof(float)) continue;
      job->tiles->MarkDone(tile);
      job->pixels[tile] = std::move(pixels);
    }
    absl::StatusOr<std::vector<IrradianceRecord>> records = store_->LoadRecords(j.id());
    if (!records.ok()) return Unavailable(records.status());
    job->cache->Merge(*records);  // validated again on the way in
    if (FinalState(j.state())) {
      job->tiles->Clear();
    } else if (j.state() == v1::JOB_STATE_RUNNING) {
      job->stored.mutable_job()->set_state(v1::JOB_STATE_QUEUED);  // no lease survives
    }
    next_sequence_ = std::max(next_sequence_, s.sequence() + 1);
    jobs_[j.id()] = std::move(job);
  }
  return absl::OkStatus();
}

bool JobManager::IsFinal(const Job& job) const { return FinalState(job.stored.job().state()); }

v1::Job JobManager::View(const Job& job) const {
  v1::Job j = job.stored.job();
  j.set_tiles_total(job.tiles->num_tiles());
  j.set_tiles_done(job.tiles->num_done());
  j.set_records_merged(job.cache->size());
  j.set_records_rejected(job.cache->rejected());
  for (const auto& [id, stats] : job.worker_stats) *j.add_workers() = stats;
  if (job.has_started) {
    const SteadyTime end = IsFinal(job) ? job.finished : std::chrono::steady_clock::now();
    j.set_elapsed_seconds(std::chrono::duration<double>(end - job.started).count());
  }
  return j;
}

void JobManager::Changed() {
  ++version_;
  changed_cv_.notify_all();
}

absl::StatusOr<v1::Job> JobManager::Submit(const v1::SubmitJobRequest& request) {
  if (request.ByteSizeLong() > options_.max_upload_bytes)
    return absl::ResourceExhaustedError("upload of " + std::to_string(request.ByteSizeLong()) +
                                        " bytes is over the limit of " +
                                        std::to_string(options_.max_upload_bytes) + " bytes");
  // Load the scene now, so that a bad scene is refused with the loader's file:line message.
  absl::StatusOr<SceneDesc> desc = absl::InvalidArgumentError("no scene given");
  std::string name = request.name();
  if (request.scene().has_bundle()) {
    const v1::SceneBundle& bundle = request.scene().bundle();
    for (const v1::BundleFile& f : bundle.files()) {
      absl::Status st = CheckBundlePath(f.path());
      if (!st.ok()) return st;
    }
    absl::StatusOr<std::string> dir = MakeTempDir("irfarm-submit-");
    if (!dir.ok()) return dir.status();
    absl::StatusOr<std::string> main = WriteBundle(bundle, *dir);
    if (main.ok()) desc = LoadJobScene(*main, request.settings());
    RemoveTree(*dir);
    if (!main.ok()) return main.status();
    if (name.empty()) name = bundle.main_file().empty() ? "scene.xml" : bundle.main_file();
  } else if (request.scene().has_path()) {
    desc = LoadJobScene(request.scene().path(), request.settings());
    if (name.empty()) name = request.scene().path();
  }
  if (!desc.ok()) return desc.status();
  absl::StatusOr<RenderSettings> settings = MakeRenderSettings(*desc, request.settings(), 0);
  if (!settings.ok()) return settings.status();
  if (request.settings().denoise()) {
    absl::StatusOr<const Denoiser*> denoiser = GetDenoiser();
    if (!denoiser.ok()) return absl::FailedPreconditionError(denoiser.status().message());
  }
  const uint64_t scene_hash = SceneHash(*desc);
  std::vector<IrradianceRecord> imported;
  if (!request.cache_snapshot().empty()) {
    absl::StatusOr<Snapshot> snap = ParseSnapshot(request.cache_snapshot(), "cache snapshot");
    if (!snap.ok()) return snap.status();
    absl::Status st = CheckSnapshotScene(*snap, scene_hash, "cache snapshot");
    if (!st.ok()) return st;
    imported = std::move(snap->records);
    for (IrradianceRecord& r : imported) r.origin = kSnapshotOrigin;
  }

  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<uint64_t> number = store_->NextJobNumber();
  if (!number.ok()) return Unavailable(number.status());
  auto job = std::make_unique<Job>();
  v1::StoredJob& s = job->stored;
  v1::Job* j = s.mutable_job();
  j->set_id("job-" + std::to_string(*number));
  j->set_name(name);
  j->set_state(v1::JOB_STATE_QUEUED);
  j->set_priority(request.priority());
  j->set_width(desc->camera.width);
  j->set_height(desc->camera.height);
  *j->mutable_settings() = request.settings();
  j->set_scene_hash(scene_hash);
  j->set_records_imported(imported.size());
  *s.mutable_scene() = request.scene();
  s.set_sequence(next_sequence_++);
  const Bounds3 b = DescBounds(*desc);
  for (float f : {b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z}) s.add_cache_bounds(f);
  s.set_max_accuracy(settings->irrcache.accuracy);
  job->tiles = std::make_unique<TileScheduler>(
      j->width(), j->height(), JobTileSize(request.settings()), options_.max_tile_attempts);
  job->cache = std::make_unique<GlobalCache>(CacheSettingsOf(s));
  absl::Status st = store_->PutJob(s);
  if (!st.ok()) return Unavailable(st);
  if (!imported.empty()) {
    std::vector<IrradianceRecord> merged = job->cache->Merge(imported);
    st = store_->AppendRecords(j->id(), merged);
    if (!st.ok()) return Unavailable(st);
  }
  const v1::Job view = View(*job);
  jobs_[j->id()] = std::move(job);
  Changed();
  return view;
}

absl::StatusOr<v1::Job> JobManager::GetJob(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return absl::NotFoundError("no job '" + id + "'");
  return View(*it->second);
}

std::vector<v1::Job> JobManager::ListJobs() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<v1::Job> out;
  for (const auto& [id, job] : jobs_) out.push_back(View(*job));
  std::sort(out.begin(), out.end(), [](const v1::Job& a, const v1::Job& b) {
    return a.id().size() != b.id().size() ? a.id().size() < b.id().size() : a.id() < b.id();
  });
  return out;
}

void JobManager::FinishJob(Job& job, v1::JobState state, const std::string& error) {
  v1::Job* j = job.stored.mutable_job();
  j->set_state(state);
  j->set_error(error);
  job.finished = std::chrono::steady_clock::now();
  job.tiles->Clear();
  (void)store_->PutJob(job.stored);  // if this fails the job resumes after a restart
  for (uint32_t w : job.workers) {
    auto it = workers_.find(w);
    if (it == workers_.end()) continue;
    v1::CoordinatorMessage m;
    m.mutable_job_closed()->set_job_id(j->id());
    it->second.outbox.push_back(std::move(m));
    it->second.jobs.erase(j->id());
  }
  job.workers.clear();
  Changed();
}

absl::StatusOr<v1::Job> JobManager::Cancel(const std::string& id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return absl::NotFoundError("no job '" + id + "'");
  Job& job = *it->second;
  if (IsFinal(job))
    return absl::FailedPreconditionError("job '" + id + "' is already " +
                                         v1::JobState_Name(job.stored.job().state()));
  FinishJob(job, v1::JOB_STATE_CANCELLED, "cancelled by a client");
  return View(job);
}

absl::StatusOr<const Denoiser*> JobManager::GetDenoiser() const {
  std::lock_guard<std::mutex> lock(denoiser_mu_);
  if (!denoiser_ && denoiser_error_.ok()) {
    absl::StatusOr<std::unique_ptr<Denoiser>> d = Denoiser::Open();
    if (d.ok()) {
      denoiser_ = std::move(*d);
    } else {
      denoiser_error_ = d.status();
    }
  }
  if (!denoiser_) return denoiser_error_;
  return denoiser_.get();
}

absl::StatusOr<std::string> JobManager::ResultExr(const std::string& id) const {
  Image image;
  AovImages guides;  // albedo and normal only, for denoised jobs
  bool denoise = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = jobs_.find(id);
    if (it == jobs_.end()) return absl::NotFoundError("no job '" + id + "'");
    const Job& job = *it->second;
    if (job.stored.job().state() != v1::JOB_STATE_SUCCEEDED)
      return absl::FailedPreconditionError("job '" + id + "' has no image: it is " +
                                           v1::JobState_Name(job.stored.job().state()));
    const int w = job.stored.job().width(), h = job.stored.job().height();
    image = Image(w, h);
    denoise = job.stored.job().settings().denoise();
    if (denoise) guides = AovImages(w, h);
    for (const auto& [tile, bytes] : job.pixels) {
      const PixelRect& r = job.tiles->rect(tile);
      std::vector<float> px(bytes.size() / sizeof(float));
      std::memcpy(px.data(), bytes.data(), px.size() * sizeof(float));
      const size_t n = size_t(r.width()) * r.height();
      const bool has_guides = px.size() == 9 * n;  // checked when the tile came in
      for (int y = r.y0; y < r.y1; ++y)
        for (int x = r.x0; x < r.x1; ++x) {
          const size_t k = size_t(y - r.y0) * r.width() + (x - r.x0), i = 3 * k;
          image.at(x, y) = Vec3(px[i], px[i + 1], px[i + 2]);
          if (denoise && has_guides) {
            const size_t g = 3 * n + 6 * k;
            guides.albedo.at(x, y) = Vec3(px[g], px[g + 1], px[g + 2]);
            guides.normal.at(x, y) = Vec3(px[g + 3], px[g + 4], px[g + 5]);
          }
        }
    }
  }
  std::vector<ExrLayer> layers;
  Image noisy;
  if (denoise) {
    absl::StatusOr<const Denoiser*> denoiser = GetDenoiser();
    if (!denoiser.ok()) return absl::FailedPreconditionError(denoiser.status().message());
    absl::StatusOr<Image> clean;
    {
      std::lock_guard<std::mutex> lock(denoiser_mu_);
      clean = DenoiseRender(**denoiser, image, guides, DenoiseMode::kImage);
    }
    if (!clean.ok()) return clean.status();
    noisy = std::move(image);
    image = std::move(*clean);
    layers = {{"noisy", {"R", "G", "B"}, &noisy},
              {"albedo", {"R", "G", "B"}, &guides.albedo},
              {"normal", {"X", "Y", "Z"}, &guides.normal}};
  }
  absl::StatusOr<std::string> dir = MakeTempDir("irfarm-result-");
  if (!dir.ok()) return dir.status();
  const std::string path = *dir + "/image.exr";
  absl::Status st = WriteExr(image, path, layers);
  std::string bytes;
  if (st.ok()) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    bytes = ss.str();
  }
  RemoveTree(*dir);
  if (!st.ok()) return st;
  return bytes;
}

absl::StatusOr<std::string> JobManager::ExportSnapshot(const std::string& id) const {
  Snapshot snap;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = jobs_.find(id);
    if (it == jobs_.end()) return absl::NotFoundError("no job '" + id + "'");
    snap.scene_hash = it->second->stored.job().scene_hash();
    snap.records = it->second->cache->records();
  }
  return SerializeSnapshot(snap);
}

uint64_t JobManager::WaitForChange(uint64_t seen, std::chrono::milliseconds timeout) const {
  std::unique_lock<std::mutex> lock(mu_);
  changed_cv_.wait_for(lock, timeout, [&] { return version_ != seen; });
  return version_;
}

uint32_t JobManager::RegisterWorker(const std::string& name) {
  std::lock_guard<std::mutex> lock(mu_);
  const uint32_t id = next_worker_++;
  workers_[id].name = name;
  return id;
}

void JobManager::WorkerGone(uint32_t worker, const std::string& reason) {
  std::lock_guard<std::mutex> lock(mu_);
  auto wit = workers_.find(worker);
  if (wit == workers_.end()) return;
  for (auto& [id, job] : jobs_) {
    job->workers.erase(worker);
    if (IsFinal(*job)) continue;
    absl::Status st = job->tiles->ReleaseWorker(
        worker, "worker " + std::to_string(worker) + " (" + wit->second.name + ") " + reason);
    if (!st.ok()) FinishJob(*job, v1::JOB_STATE_FAILED, std::string(st.message()));
  }
  workers_.erase(wit);
  Changed();
}

void JobManager::Drain(uint32_t worker) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = workers_.find(worker);
  if (it != workers_.end()) it->second.draining = true;
}

absl::Status JobManager::AddRecords(uint32_t worker, const v1::JobRecords& records) {
  absl::StatusOr<std::vector<IrradianceRecord>> decoded = DecodeRecords(records.batch());
  if (!decoded.ok()) return decoded.status();
  for (IrradianceRecord& r : *decoded) r.origin = worker;  // a worker speaks for itself only
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(records.job_id());
  if (it == jobs_.end()) return absl::NotFoundError("no job '" + records.job_id() + "'");
  Job& job = *it->second;
  v1::WorkerJobStats& ws = job.worker_stats[worker];
  ws.set_worker_id(worker);
  ws.set_records_sent(ws.records_sent() + decoded->size());
  ws.set_bytes_sent(ws.bytes_sent() + BatchBytes(records.batch()));
  const std::vector<IrradianceRecord> accepted = job.cache->Merge(*decoded);
  if (accepted.empty()) return absl::OkStatus();
  absl::Status st = store_->AppendRecords(job.stored.job().id(), accepted);
  if (!st.ok()) return Unavailable(st);
  if (job.stored.job().settings().share_records() && !IsFinal(job)) {
    v1::CoordinatorMessage m;
    m.mutable_records()->set_job_id(records.job_id());
    PackRecords(accepted, worker, m.mutable_records()->mutable_batch());
    const size_t bytes = BatchBytes(m.records().batch());
    for (uint32_t other : job.workers) {
      if (other == worker) continue;
      auto wit = workers_.find(other);
      if (wit == workers_.end()) continue;
      wit->second.outbox.push_back(m);
      v1::WorkerJobStats& os = job.worker_stats[other];
      os.set_worker_id(other);
      os.set_bytes_received(os.bytes_received() + bytes);
    }
  }
  Changed();
  return absl::OkStatus();
}

absl::Status JobManager::CompleteTile(uint32_t worker, const v1::TileResult& result) {
  std::lock_guard<std::mutex> lock(mu_);
  auto wit = workers_.find(worker);
  if (wit != workers_.end() && wit->second.lease_id == result.lease_id() &&
      wit->second.lease_job == result.job_id())
    wit->second.has_lease = false;
  Changed();
  auto it = jobs_.find(result.job_id());
  if (it == jobs_.end()) return absl::NotFoundError("no job '" + result.job_id() + "'");
  Job& job = *it->second;
  const int tile = result.tile_index();
  if (tile < 0 || tile >= job.tiles->num_tiles())
    return absl::InvalidArgumentError("no tile " + std::to_string(tile));
  if (!job.tiles->IsCurrent(tile, result.lease_id()))
    return absl::FailedPreconditionError("stale result for tile " + std::to_string(tile));
  const PixelRect& r = job.tiles->rect(tile);
  if (result.pixels_size() != r.width() * r.height() * 3)
    return absl::InvalidArgumentError("tile " + std::to_string(tile) + " has " +
                                      std::to_string(result.pixels_size()) + " floats, expected " +
                                      std::to_string(r.width() * r.height() * 3));
  const bool denoise = job.stored.job().settings().denoise();
  if (result.guides_size() != (denoise ? r.width() * r.height() * 6 : 0))
    return absl::InvalidArgumentError("tile " + std::to_string(tile) + " has " +
                                      std::to_string(result.guides_size()) +
                                      " guide floats, expected " +
                                      std::to_string(denoise ? r.width() * r.height() * 6 : 0));
  std::string bytes(reinterpret_cast<const char*>(result.pixels().data()),
                    size_t(result.pixels_size()) * sizeof(float));
  bytes.append(reinterpret_cast<const char*>(result.guides().data()),
               size_t(result.guides_size()) * sizeof(float));
  absl::Status st = store_->PutTile(job.stored.job().id(), tile, bytes);
  if (!st.ok()) {
    // Not stored, so not done: the tile is rendered again.
    (void)job.tiles->Requeue(tile, result.lease_id(), "job store failed");
    return Unavailable(st);
  }
  st = job.tiles->Complete(tile, result.lease_id());
  if (!st.ok()) return st;
  job.pixels[tile] = std::move(bytes);
  v1::WorkerJobStats& ws = job.worker_stats[worker];
  const v1::TileStats& ts = result.stats();
  ws.set_worker_id(worker);
  if (wit != workers_.end()) ws.set_worker_name(wit->second.name);
  ws.set_tiles(ws.tiles() + 1);
  ws.set_records_computed(ws.records_computed() + ts.records_computed());
  ws.set_records_received(ws.records_received() + ts.records_received());
  ws.set_remote_records_used(ws.remote_records_used() + ts.remote_records_used());
  ws.set_records_used(ws.records_used() + ts.records_used());
  ws.set_lookups(ws.lookups() + ts.lookups());
  ws.set_lookup_hits(ws.lookup_hits() + ts.lookup_hits());
  ws.set_render_seconds(ws.render_seconds() + ts.wall_seconds());
  if (job.tiles->all_done()) FinishJob(job, v1::JOB_STATE_SUCCEEDED, "");
  return absl::OkStatus();
}

absl::Status JobManager::FailTile(uint32_t worker, const v1::TileFailed& failed) {
  std::lock_guard<std::mutex> lock(mu_);
  auto wit = workers_.find(worker);
  if (wit != workers_.end() && wit->second.lease_id == failed.lease_id()) {
    wit->second.has_lease = false;
  }
  Changed();
  auto it = jobs_.find(failed.job_id());
  if (it == jobs_.end()) return absl::NotFoundError("no job '" + failed.job_id() + "'");
  Job& job = *it->second;
  if (IsFinal(job)) return absl::OkStatus();
  absl::Status st = job.tiles->Requeue(failed.tile_index(), failed.lease_id(),
                                       "worker " + std::to_string(worker) + ": " + failed.reason());
  if (!st.ok()) FinishJob(job, v1::JOB_STATE_FAILED, std::string(st.message()));
  return absl::OkStatus();
}

void JobManager::SeedCache(Job& job) {
  v1::Job* j = job.stored.mutable_job();
  // Once per job (a resumed job has its seed in the store already); a job warm-started from a
  // snapshot keeps the cache it was given.
  if (!j->seeded_from().empty() || j->records_imported() > 0) return;
  std::vector<const Job*> sources;
  for (const auto& [id, other] : jobs_) {
    if (other.get() == &job || other->stored.sequence() > job.stored.sequence()) continue;
    if (other->cache->size() > 0 && CanSeed(other->stored, job.stored))
      sources.push_back(other.get());
  }
  if (sources.empty()) return;
  std::sort(sources.begin(), sources.end(),
            [](const Job* a, const Job* b) { return a->stored.sequence() < b->stored.sequence(); });
  SeedSet seed;
  std::string from;
  for (const Job* src : sources) {
    seed.Add(src->cache->records());
    from += (from.empty() ? "" : ",") + src->stored.job().id();
  }
  std::vector<IrradianceRecord> records = seed.records();
  // Stamped like imported records: sent to every worker of the job when it joins.
  for (IrradianceRecord& r : records) r.origin = kSnapshotOrigin;
  const std::vector<IrradianceRecord> merged = job.cache->Merge(records);
  j->set_records_seeded(merged.size());
  j->set_seeded_from(from);
  // If the store fails here the job still renders with its seed; a restart seeds it again.
  (void)store_->AppendRecords(j->id(), merged);
  (void)store_->PutJob(job.stored);
}

void JobManager::TryAssign(uint32_t worker_id, Worker& worker,
                           std::vector<v1::CoordinatorMessage>* out) {
  Job* best = nullptr;
  for (auto& [id, job] : jobs_) {
    if (IsFinal(*job) || !job->tiles->has_pending()) continue;
    if (best == nullptr || job->stored.job().priority() > best->stored.job().priority() ||
        (job->stored.job().priority() == best->stored.job().priority() &&
         job->stored.sequence() < best->stored.sequence()))
      best = job.get();
  }
  if (best == nullptr) return;
  Job& job = *best;
  const std::string& id = job.stored.job().id();
  if (!job.has_started) SeedCache(job);
  std::optional<TileLeaseInfo> lease =
      job.tiles->Lease(worker_id, std::chrono::steady_clock::now(), options_.lease_time);
  if (!lease) return;
  if (!job.workers.count(worker_id)) {
    v1::CoordinatorMessage spec;
    spec.mutable_job_spec()->set_job_id(id);
    *spec.mutable_job_spec()->mutable_scene() = job.stored.scene();
    *spec.mutable_job_spec()->mutable_settings() = job.stored.job().settings();
    out->push_back(std::move(spec));
    // Late join: the job's records so far (imported ones always, others' when sharing).
    const bool share = job.stored.job().settings().share_records();
    const std::vector<IrradianceRecord>& all = job.cache->records();
    std::vector<IrradianceRecord> chunk;
    for (size_t i = 0; i <= all.size(); ++i) {
      if (i == all.size() || chunk.size() == options_.sync_batch_records) {
        if (!chunk.empty()) {
          v1::CoordinatorMessage m;
          m.mutable_records()->set_job_id(id);
          PackRecords(chunk, kSnapshotOrigin, m.mutable_records()->mutable_batch());
          v1::WorkerJobStats& ws = job.worker_stats[worker_id];
          ws.set_worker_id(worker_id);
          ws.set_bytes_received(ws.bytes_received() + BatchBytes(m.records().batch()));
          out->push_back(std::move(m));
          chunk.clear();
        }
        if (i == all.size()) break;
      }
      if (share || all[i].origin == kSnapshotOrigin) chunk.push_back(all[i]);
    }
    job.workers.insert(worker_id);
    worker.jobs.insert(id);
  }
  if (!job.has_started) {
    job.has_started = true;
    job.started = std::chrono::steady_clock::now();
  }
  if (job.stored.job().state() == v1::JOB_STATE_QUEUED) {
    job.stored.mutable_job()->set_state(v1::JOB_STATE_RUNNING);
    (void)store_->PutJob(job.stored);
  }
  v1::CoordinatorMessage m;
  v1::TileLease* l = m.mutable_lease();
  l->set_job_id(id);
  l->set_tile_index(lease->tile);
  l->set_lease_id(lease->lease_id);
  const PixelRect& r = job.tiles->rect(lease->tile);
  l->mutable_rect()->set_x0(r.x0);
  l->mutable_rect()->set_y0(r.y0);
  l->mutable_rect()->set_x1(r.x1);
  l->mutable_rect()->set_y1(r.y1);
  const auto wall_deadline = std::chrono::system_clock::now() + options_.lease_time;
  l->set_deadline_unix_ms(
      std::chrono::duration_cast<std::chrono::milliseconds>(wall_deadline.time_since_epoch())
          .count());
  out->push_back(std::move(m));
  worker.has_lease = true;
  worker.lease_job = id;
  worker.lease_id = lease->lease_id;
  Changed();
}

std::vector<v1::CoordinatorMessage> JobManager::Poll(uint32_t worker,
                                                     std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  std::vector<v1::CoordinatorMessage> out;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    auto it = workers_.find(worker);
    if (it == workers_.end()) return out;
    Worker& w = it->second;
    while (!w.outbox.empty()) {
      out.push_back(std::move(w.outbox.front()));
      w.outbox.pop_front();
    }
    if (!w.has_lease && !w.draining) TryAssign(worker, w, &out);
    if (!out.empty()) return out;
    const uint64_t seen = version_;
    if (!changed_cv_.wait_until(lock, deadline, [&] { return version_ != seen; })) return out;
  }
}

void JobManager::ExpireLeases() {
  std::lock_guard<std::mutex> lock(mu_);
  const SteadyTime now = std::chrono::steady_clock::now();
  for (auto& [id, job] : jobs_) {
    if (IsFinal(*job)) continue;
    absl::Status st = job->tiles->ExpireLeases(now);
    if (!st.ok()) FinishJob(*job, v1::JOB_STATE_FAILED, std::string(st.message()));
  }
}

}  // namespace irfarm
