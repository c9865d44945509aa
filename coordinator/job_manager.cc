// JobManager: jobs, tiles, record merge and fan-out, worker mailboxes (see job_manager.h).
#include "coordinator/job_manager.h"

#include <limits.h>
#include <spdlog/spdlog.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>

#include "absl/strings/str_replace.h"
#include "cache/snapshot.h"
#include "coordinator/cache_seed.h"
#include "coordinator/fanout_region.h"
#include "coordinator/record_map.h"
#include "render/firefly_filter.h"
#include "render/image.h"
#include "service/job_settings.h"
#include "service/record_codec.h"
#include "service/scene_bundle.h"
#include "service/scene_hash.h"
#include "service/unix_time.h"

namespace irfarm {
namespace {

CacheSettings CacheSettingsOf(const v1::StoredJob& stored) {
  CacheSettings cs;
  if (stored.cache_bounds_size() == 6) {
    cs.bounds.lo = Vec3(stored.cache_bounds(0), stored.cache_bounds(1), stored.cache_bounds(2));
    cs.bounds.hi = Vec3(stored.cache_bounds(3), stored.cache_bounds(4), stored.cache_bounds(5));
  }
  cs.max_accuracy = stored.max_accuracy() > 0 ? stored.max_accuracy() : 0.2f;
  return cs;
}

// The bounds a stored job's records must satisfy (record_bounds.h); jobs stored before the
// radius and irradiance bounds existed get the box only.
RecordBounds RecordBoundsOf(const v1::StoredJob& stored) {
  RecordBounds b;
  if (stored.cache_bounds_size() == 6) {
    const Vec3 lo(stored.cache_bounds(0), stored.cache_bounds(1), stored.cache_bounds(2));
    const Vec3 hi(stored.cache_bounds(3), stored.cache_bounds(4), stored.cache_bounds(5));
    const Vec3 d = hi - lo;
    const float margin = 0.01f * std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    b.box.lo = lo - Vec3(margin);
    b.box.hi = hi + Vec3(margin);
  } else {
    b.box.lo = Vec3(-std::numeric_limits<float>::max());
    b.box.hi = Vec3(std::numeric_limits<float>::max());
  }
  if (stored.record_max_radius() > 0) b.max_radius = stored.record_max_radius();
  if (stored.record_max_irradiance() > 0) b.max_irradiance = stored.record_max_irradiance();
  return b;
}

// Printable, bounded text of something a peer sent, for messages and logs: control bytes
// (newlines, ANSI escapes, NUL) and bytes that are not UTF-8 become '?', and at most `max` bytes
// are kept, cut between characters. It goes into proto3 strings (a job's error), which must be
// valid UTF-8: one cut inside a character was stored, and the job could no longer be parsed, by
// clients or by the coordinator resuming it from Redis.
std::string Printable(const std::string& s, size_t max = 200) {
  std::string out;
  size_t i = 0;
  while (i < s.size()) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    // The length of the UTF-8 sequence starting here, 0 when it is not one.
    size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (n > 1) {
      if (i + n > s.size()) n = 0;
      for (size_t k = 1; k < n; ++k)
        if ((static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) n = 0;
      // Overlong forms and surrogates are not UTF-8 either.
      if (n == 2 && c < 0xC2) n = 0;
      if (n == 3) {
        const unsigned char d = static_cast<unsigned char>(s[i + 1]);
        if ((c == 0xE0 && d < 0xA0) || (c == 0xED && d >= 0xA0)) n = 0;
      }
      if (n == 4) {
        const unsigned char d = static_cast<unsigned char>(s[i + 1]);
        if ((c == 0xF0 && d < 0x90) || c > 0xF4 || (c == 0xF4 && d >= 0x90)) n = 0;
      }
    }
    const size_t len = n == 0 ? 1 : n;
    if (out.size() + len > max) break;
    if (n == 0 || (n == 1 && (c < 0x20 || c == 0x7f))) {
      out += '?';
    } else {
      out.append(s, i, n);
    }
    i += len;
  }
  if (i < s.size()) out += "...";
  return out;
}

// Floats a finished tile keeps per pixel: its RGB, then the denoiser's guides (albedo and normal)
// for a denoised job, then the firefly filter's peaks (RGB) unless the job turned it off.
int64_t GuideFloats(const v1::RenderSettings& s) { return s.denoise() ? 6 : 0; }
int64_t PeakFloats(const v1::RenderSettings& s) { return s.no_firefly_filter() ? 0 : 3; }
int64_t TileFloatsPerPixel(const v1::RenderSettings& s) {
  return 3 + GuideFloats(s) + PeakFloats(s);
}

// Why a job read back from the store cannot be resumed as it is ("" when it can): the limits a
// submit is held to, on what sizes the job's tiles and cache (a store anyone else can write to,
// or a damaged one, must not make a coordinator allocate tens of GB or overflow at start-up).
// Why a job of a w x h film with these settings is too large for the limits ("" when it is
// not): its film, then its tile count. Submit and Resume both hold jobs to it.
std::string JobSizeProblem(int64_t w, int64_t h, const v1::RenderSettings& settings,
                           const JobLimits& lim) {
  // The film, before anything is sized by it (a 2^31-pixel-wide film must not get to the tiles).
  if (w < 1 || h < 1 || w > lim.max_film_side || h > lim.max_film_side ||
      w * h > lim.max_film_pixels)
    return "film " + std::to_string(w) + "x" + std::to_string(h) +
           " is outside the limits (sides 1.." + std::to_string(lim.max_film_side) + ", at most " +
           std::to_string(lim.max_film_pixels) + " pixels)";
  const int64_t tile = JobTileSize(settings);
  const int64_t tiles = ((w + tile - 1) / tile) * ((h + tile - 1) / tile);
  if (tiles > lim.max_tiles)
    return std::to_string(tiles) + " tiles of " + std::to_string(tile) +
           " px is over the limit of " + std::to_string(lim.max_tiles) + " tiles per job";
  // 3 floats a pixel, 6 more for the denoiser's guides, 3 for the firefly filter's peaks.
  const int64_t result_bytes =
      std::min(tile, w) * std::min(tile, h) * TileFloatsPerPixel(settings) * int64_t(sizeof(float));
  if (result_bytes > int64_t(lim.max_tile_result_bytes))
    return "a tile of " + std::to_string(std::min(tile, w)) + "x" +
           std::to_string(std::min(tile, h)) + " px" + (settings.denoise() ? " with denoise" : "") +
           (PeakFloats(settings) > 0 ? " and the firefly filter's peaks" : "") + " is a " +
           std::to_string(result_bytes) + "-byte result, over the coordinator's " +
           std::to_string(lim.max_tile_result_bytes) +
           "-byte message limit: use a smaller tile_size" +
           (PeakFloats(settings) > 0 ? " (or no_firefly_filter)" : "");
  return "";
}

// A job stored before tiles carried the firefly filter's peaks, whose tiles fit the message
// limit only without them, resumes with the filter off (its workers then send none).
void FitStoredJobWithoutPeaks(v1::StoredJob& s, const JobLimits& lim) {
  v1::Job& j = *s.mutable_job();
  if (j.settings().no_firefly_filter() ||
      JobSizeProblem(j.width(), j.height(), j.settings(), lim).empty())
    return;
  v1::RenderSettings without = j.settings();
  without.set_no_firefly_filter(true);
  if (JobSizeProblem(j.width(), j.height(), without, lim).empty())
    j.mutable_settings()->set_no_firefly_filter(true);
}

std::string StoredJobProblem(const v1::StoredJob& s, const JobLimits& lim) {
  const v1::Job& j = s.job();
  const int64_t tile = j.settings().tile_size();
  if (tile < 0 || tile > 4096 || (tile > 0 && tile < 4))
    return "tile size " + std::to_string(tile) + " is outside [4, 4096]";
  if (std::string why = JobSizeProblem(j.width(), j.height(), j.settings(), lim); !why.empty())
    return why;
  if (s.cache_bounds_size() != 0 && s.cache_bounds_size() != 6)
    return std::to_string(s.cache_bounds_size()) + " cache bound values, expected 6";
  for (int k = 0; k < s.cache_bounds_size(); ++k)
    if (!std::isfinite(s.cache_bounds(k)) ||
        (k < 3 && !(s.cache_bounds(k) <= s.cache_bounds(k + 3))))
      return "cache bounds are not a finite box";
  if (!(s.max_accuracy() >= 0 && s.max_accuracy() <= 1)) return "max_accuracy is outside [0, 1]";
  if (!s.has_scene() && !IsFinalState(j.state())) return "its scene is missing";
  if (!(s.record_max_radius() >= 0 && std::isfinite(s.record_max_radius())) ||
      !(s.record_max_irradiance() >= 0 && std::isfinite(s.record_max_irradiance())))
    return "record bounds are not finite and non-negative";
  return "";
}

// Whether a finished tile read back from the store holds what CompleteTile accepts: its pixels
// (the first `pixel_floats`) finite and non-negative, its guides finite.
bool SaneTile(const std::string& bytes, size_t pixel_floats) {
  const size_t n = bytes.size() / sizeof(float);
  for (size_t i = 0; i < n; ++i) {
    float v;
    std::memcpy(&v, bytes.data() + i * sizeof(float), sizeof v);
    if (!std::isfinite(v) || (i < pixel_floats && v < 0)) return false;
  }
  return true;
}

absl::Status Unavailable(const absl::Status& st) {
  return absl::UnavailableError("job store: " + std::string(st.message()));
}

void StoreCamera(const CameraDesc& d, v1::StoredCamera* out) {
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out->add_to_world(d.to_world.m[r][c]);
  out->set_fov_x_deg(d.fov_x_deg);
  out->set_width(d.width);
  out->set_height(d.height);
  out->set_film_width(d.film_width);
  out->set_film_height(d.film_height);
  out->set_crop_x(d.crop_x);
  out->set_crop_y(d.crop_y);
}

// The record map's camera of a stored job, checked as anything read back from the store is
// (null when absent or not sane: the job then has no record map).
std::unique_ptr<Camera> CameraOf(const v1::StoredJob& s) {
  const v1::StoredCamera& c = s.camera();
  if (c.to_world_size() != 16 || c.width() != s.job().width() || c.height() != s.job().height())
    return nullptr;
  if (!(c.fov_x_deg() > 0 && c.fov_x_deg() < 180) || c.film_width() < 0 || c.film_height() < 0 ||
      c.crop_x() < 0 || c.crop_y() < 0)
    return nullptr;
  CameraDesc d;
  for (int i = 0; i < 16; ++i) {
    if (!std::isfinite(c.to_world(i))) return nullptr;
    d.to_world.m[i / 4][i % 4] = c.to_world(i);
  }
  d.fov_x_deg = c.fov_x_deg();
  d.width = c.width();
  d.height = c.height();
  d.film_width = c.film_width();
  d.film_height = c.film_height();
  d.crop_x = c.crop_x();
  d.crop_y = c.crop_y();
  return std::make_unique<Camera>(d);
}

}  // namespace

JobManager::JobManager(const JobManagerOptions& options, JobStore* store, MetricsRegistry* registry)
    : options_(options),
      store_(store),
      own_registry_(registry ? nullptr : std::make_unique<MetricsRegistry>()),
      registry_(registry ? registry : own_registry_.get()),
      metrics_(registry_) {
  collector_ = registry_->AddCollector([this](MetricsWriter& w) { CollectMetrics(w); });
}

JobManager::~JobManager() {
  writer_.reset();  // first: its last writes may ask for a job's scene (SceneOf)
  registry_->RemoveCollector(collector_);
}

std::optional<v1::SceneSource> JobManager::SceneOf(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = jobs_.find(id);
  // A finished job's own final write (with its emptied scene, or none) is queued behind the
  // refused one: its scene is not to be paired with an older state.
  if (it == jobs_.end() || !it->second->stored.has_scene() || IsFinal(*it->second))
    return std::nullopt;
  return it->second->stored.scene();  // a copy under the lock: only after the store lost it
}

void JobManager::CollectMetrics(MetricsWriter& w) const {
  std::lock_guard<std::mutex> lock(mu_);
  int by_state[v1::JobState_ARRAYSIZE] = {};
  for (const auto& [id, job] : jobs_) ++by_state[job->stored.job().state()];
  w.Family("irfarm_jobs", "gauge", "Jobs held by the coordinator, by state.");
  for (int s = v1::JOB_STATE_QUEUED; s < v1::JobState_ARRAYSIZE; ++s) {
    std::string name = v1::JobState_Name(v1::JobState(s)).substr(std::strlen("JOB_STATE_"));
    for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
    w.Sample("irfarm_jobs", {{"state", name}}, by_state[s]);
  }
  // Per job: bounded by the jobs held (finished ones until retention removes them).
  w.Family("irfarm_job_tiles_done", "gauge", "Finished tiles of a job.");
  for (const auto& [id, job] : jobs_)
    w.Sample("irfarm_job_tiles_done", {{"job", id}}, job->tiles->num_done());
  w.Family("irfarm_job_tiles", "gauge", "Tiles of a job.");
  for (const auto& [id, job] : jobs_)
    w.Sample("irfarm_job_tiles", {{"job", id}}, job->tiles->num_tiles());
  w.Family("irfarm_job_records_merged", "gauge", "Records in a job's global cache.");
  for (const auto& [id, job] : jobs_)
    w.Sample("irfarm_job_records_merged", {{"job", id}}, double(job->cache->size()));
  w.Family("irfarm_job_records_rejected", "gauge", "Records of a job refused by validation.");
  for (const auto& [id, job] : jobs_)
    w.Sample("irfarm_job_records_rejected", {{"job", id}}, double(job->cache->rejected()));
  int silent = 0, leased = 0;
  for (const auto& [id, worker] : workers_) {
    silent += worker.silent;
    leased += worker.has_lease;
  }
  w.Family("irfarm_worker_records_delivered", "counter",
           "Records of other workers (and imported ones) sent to a connected worker.");
  for (const auto& [id, worker] : workers_)
    w.Sample("irfarm_worker_records_delivered",
             {{"worker", std::to_string(id)}, {"name", worker.name}},
             double(worker.records_delivered));
  w.Family("irfarm_worker_records_withheld", "counter",
           "Records not sent to a connected worker when they reached none of its tile regions "
           "(filtered fan-out; some are sent later from the backlog).");
  for (const auto& [id, worker] : workers_)
    w.Sample("irfarm_worker_records_withheld",
             {{"worker", std::to_string(id)}, {"name", worker.name}},
             double(worker.records_withheld));
  w.Family("irfarm_workers", "gauge", "Connected workers: all, holding a lease, silent.");
  w.Sample("irfarm_workers", {{"state", "connected"}}, double(workers_.size()));
  w.Sample("irfarm_workers", {{"state", "leased"}}, leased);
  w.Sample("irfarm_workers", {{"state", "silent"}}, silent);
  const double lookups = double(metrics_.lookups->value());
  w.Family("irfarm_cache_hit_ratio", "gauge",
           "Irradiance-cache queries answered by interpolation / all queries (workers' tile "
           "stats, since start; NaN before any).");
  w.Sample("irfarm_cache_hit_ratio", {},
           lookups > 0 ? double(metrics_.lookup_hits->value()) / lookups
                       : std::numeric_limits<double>::quiet_NaN());
}

absl::StatusOr<std::unique_ptr<JobManager>> JobManager::Create(const JobManagerOptions& options,
                                                               JobStore* store,
                                                               MetricsRegistry* registry) {
  std::unique_ptr<JobManager> m(new JobManager(options, store, registry));
  JobManager* raw = m.get();
  m->writer_ = std::make_unique<StoreWriter>(
      store, StoreWriter::kDefaultRetry, [raw](const std::string& id) { return raw->SceneOf(id); });
  absl::Status st = m->Resume();
  if (!st.ok()) return st;
  return m;
}

absl::Status JobManager::Resume() {
  absl::StatusOr<std::vector<v1::StoredJob>> stored = store_->LoadJobs();
  if (!stored.ok()) return Unavailable(stored.status());
  // Retention first, from the job records alone: expired jobs are deleted, not loaded (their
  // tiles and records are never read). A final job stored before finish times were kept counts
  // as finished now.
  const int64_t now_ms = UnixMs();
  for (v1::StoredJob& s : *stored)
    if (IsFinalState(s.job().state()) && s.finished_unix_ms() == 0) s.set_finished_unix_ms(now_ms);
  std::vector<size_t> finished;
  for (size_t i = 0; i < stored->size(); ++i)
    if (IsFinalState((*stored)[i].job().state())) finished.push_back(i);
  std::sort(finished.begin(), finished.end(), [&](size_t a, size_t b) {
    return (*stored)[a].finished_unix_ms() > (*stored)[b].finished_unix_ms();  // newest first
  });
  std::vector<bool> expired(stored->size(), false);
  for (size_t k = 0; k < finished.size(); ++k) {
    const v1::StoredJob& s = (*stored)[finished[k]];
    if ((options_.job_ttl.count() > 0 &&
         now_ms - s.finished_unix_ms() > options_.job_ttl.count()) ||
        (options_.max_finished_jobs > 0 && k >= size_t(options_.max_finished_jobs)))
      expired[finished[k]] = true;
  }
  int removed = 0;
  for (size_t i = 0; i < stored->size(); ++i) {
    if (!expired[i]) continue;
    absl::Status st = store_->DeleteJob((*stored)[i].job().id());
    if (!st.ok()) return Unavailable(st);
    ++removed;
  }
  if (removed > 0) {
    metrics_.jobs_expired->Add(uint64_t(removed));
    spdlog::info("retention: {} finished jobs expired, not loaded", removed);
  }
  for (size_t i = 0; i < stored->size(); ++i) {
    if (expired[i]) continue;
    v1::StoredJob& s = (*stored)[i];
    FitStoredJobWithoutPeaks(s, options_.limits);
    if (const std::string why = StoredJobProblem(s, options_.limits); !why.empty()) {
      // Left in the store for an operator to look at; its id is never reused (the counter).
      spdlog::error("job {}: not resumed, its stored job is not sane: {}",
                    Printable(s.job().id(), 64), why);
      continue;
    }
    auto job = std::make_unique<Job>();
    job->stored = s;
    const v1::Job& j = s.job();
    job->tiles = std::make_unique<TileScheduler>(j.width(), j.height(), JobTileSize(j.settings()),
                                                 options_.tile_retry);
    job->cache = std::make_unique<GlobalCache>(CacheSettingsOf(s), RecordBoundsOf(s));
    job->camera = CameraOf(s);
    // A failed or cancelled job's pixels are not fetched by anyone (FinishJob released them).
    const bool wants_pixels = !IsFinalState(j.state()) || j.state() == v1::JOB_STATE_SUCCEEDED;
    absl::StatusOr<std::map<int, std::string>> tiles =
        wants_pixels ? store_->LoadTiles(j.id()) : std::map<int, std::string>();
    // A damaged key (DATA_LOSS) is reported and skipped: the job renders those tiles again.
    if (!tiles.ok() && !absl::IsDataLoss(tiles.status())) return Unavailable(tiles.status());
    if (!tiles.ok()) {
      spdlog::error("job {}: finished tiles unreadable, rendered again: {}", j.id(),
                    tiles.status().ToString());
      tiles = std::map<int, std::string>();
    }
    for (auto& [tile, pixels] : *tiles) {
      if (tile < 0 || tile >= job->tiles->num_tiles()) continue;
      const PixelRect& r = job->tiles->rect(tile);
      // With the peaks, or (stored by a coordinator before them) without: then that tile's
      // fireflies stay where they are.
      const size_t n = size_t(r.width()) * r.height();
      const size_t floats = n * size_t(TileFloatsPerPixel(j.settings()));
      const size_t floats_before_peaks = n * size_t(3 + GuideFloats(j.settings()));
      if ((pixels.size() != floats * sizeof(float) &&
           pixels.size() != floats_before_peaks * sizeof(float)) ||
          !SaneTile(pixels, n * 3)) {
        spdlog::error("job {}: stored tile {} is not sane, rendered again", j.id(), tile);
        continue;
      }
      job->tiles->MarkDone(tile);
      job->pixels[tile] = std::make_shared<const std::string>(std::move(pixels));
    }
    absl::StatusOr<std::vector<IrradianceRecord>> records = store_->LoadRecords(j.id());
    if (!records.ok() && !absl::IsDataLoss(records.status())) return Unavailable(records.status());
    if (!records.ok()) {
      spdlog::error("job {}: records unreadable, skipped: {}", j.id(), records.status().ToString());
      records = std::vector<IrradianceRecord>();
    }
    job->cache->Merge(*records);  // validated again on the way in
    if (j.state() == v1::JOB_STATE_SUCCEEDED && !job->tiles->all_done()) {
      // Its tiles are gone from the store (evicted, or damaged): not an image to serve as black.
      const std::string why = std::to_string(job->tiles->num_tiles() - job->tiles->num_done()) +
                              " of " + std::to_string(job->tiles->num_tiles()) +
                              " finished tiles were lost from the store";
      spdlog::error("job {}: {}: failed", j.id(), why);
      FinishJob(*job, v1::JOB_STATE_FAILED, why);
    }
    if (IsFinalState(j.state())) {
      job->tiles->Clear();
      job->cache->Close();
    } else if (j.state() == v1::JOB_STATE_RUNNING) {
      job->stored.mutable_job()->set_state(v1::JOB_STATE_QUEUED);  // no lease survives
    }
    // Under the lock: the metrics server, started before the manager, reads jobs_ (CollectMetrics).
    std::lock_guard<std::mutex> lock(mu_);
    next_sequence_ = std::max(next_sequence_, s.sequence() + 1);
    jobs_[j.id()] = std::move(job);
  }
  return absl::OkStatus();
}

bool JobManager::IsFinal(const Job& job) const { return IsFinalState(job.stored.job().state()); }

v1::Job JobManager::View(const Job& job) const {
  v1::Job j = job.stored.job();
  j.set_tiles_total(job.tiles->num_tiles());
  j.set_tiles_done(job.tiles->num_done());
  j.set_records_merged(job.cache->size());
  j.set_records_rejected(job.cache->rejected());
  for (const auto& [id, stats] : job.worker_stats) {
    v1::WorkerJobStats* ws = j.add_workers();
    *ws = stats;
    auto t = job.tallies.find(id);
    if (t != job.tallies.end())
      ws->set_records_withheld(ws->records_withheld() + Unsettled(job, t->second));
  }
  if (job.has_started) {
    const SteadyTime end = IsFinal(job) ? job.finished : std::chrono::steady_clock::now();
    j.set_elapsed_seconds(std::chrono::duration<double>(end - job.started).count());
  }
  return j;
}

void JobManager::Changed() {
  ++version_;
  changed_cv_.notify_all();
  for (auto& [id, w] : workers_) WakeWorker(w);
}

void JobManager::Touched(Worker* worker) {
  ++version_;
  changed_cv_.notify_all();
  if (worker != nullptr) WakeWorker(*worker);
}

size_t JobManager::QueueRecords(Worker& worker, const std::string& job_id,
                                const std::vector<IrradianceRecord>& records) {
  const bool was_empty = worker.outbox.empty();
  v1::CoordinatorMessage* m = nullptr;
  if (!was_empty) {
    v1::CoordinatorMessage& back = worker.outbox.back();
    if (back.has_records() && back.records().job_id() == job_id &&
        size_t(back.records().batch().origins_size()) + records.size() <=
            options_.sync_batch_records)
      m = &back;
  }
  if (m == nullptr) {
    worker.outbox.emplace_back();
    m = &worker.outbox.back();
    m->mutable_records()->set_job_id(job_id);
  }
  const size_t before = BatchBytes(m->records().batch());
  PackRecords(records, kSnapshotOrigin, m->mutable_records()->mutable_batch());
  const size_t bytes = BatchBytes(m->records().batch()) - before;
  worker.outbox_bytes += bytes;
  total_outbox_bytes_ += bytes;
  if (was_empty) {
    worker.records_queued_at = std::chrono::steady_clock::now();
    WakeWorker(worker);
  }
  return bytes;
}

absl::StatusOr<v1::Job> JobManager::Submit(const v1::SubmitJobRequest& request,
                                           const Caller& caller) {
  const JobLimits& lim = options_.limits;
  if (request.ByteSizeLong() > options_.max_upload_bytes)
    return absl::ResourceExhaustedError("upload of " + std::to_string(request.ByteSizeLong()) +
                                        " bytes is over the limit of " +
                                        std::to_string(options_.max_upload_bytes) + " bytes");
  // Cheap checks first: nothing is loaded for a request that asks too much.
  if (request.settings().defines_size() > lim.max_defines)
    return absl::InvalidArgumentError(std::to_string(request.settings().defines_size()) +
                                      " defines, over the limit of " +
                                      std::to_string(lim.max_defines));
  for (const auto& [key, value] : request.settings().defines())
    if (key.size() + value.size() > lim.max_define_bytes)
      return absl::InvalidArgumentError(
          "define '" + Printable(key, 64) + "' is " + std::to_string(key.size() + value.size()) +
          " bytes, over the limit of " + std::to_string(lim.max_define_bytes));
  if (request.settings().record_rays() > lim.max_record_rays)
    return absl::InvalidArgumentError(
        "record_rays " + std::to_string(request.settings().record_rays()) +
        " is over the limit of " + std::to_string(lim.max_record_rays));
  if (request.priority() < 0 || request.priority() > JobLimits::kMaxPriority)
    return absl::InvalidArgumentError("priority must be in [0, " +
                                      std::to_string(JobLimits::kMaxPriority) + "], got " +
                                      std::to_string(request.priority()));
  // This submit counts as a live job of its client from the check until it is in jobs_ (or
  // refused): parallel submits see each other.
  struct Submitting {
    JobManager* m;
    const std::string& owner;
    bool counted = false;
    void Done() {  // under mu_
      if (!counted) return;
      counted = false;
      auto it = m->submitting_.find(owner);
      if (--it->second == 0) m->submitting_.erase(it);
    }
    ~Submitting() {
      if (!counted) return;
      std::lock_guard<std::mutex> lock(m->mu_);
      Done();
    }
  } submitting{this, caller.name};
  if (!caller.admin) {
    std::lock_guard<std::mutex> lock(mu_);
    auto pending = submitting_.find(caller.name);
    int live = pending == submitting_.end() ? 0 : pending->second;
    for (const auto& [id, job] : jobs_)
      if (!IsFinal(*job) && job->stored.job().owner() == caller.name) ++live;
    if (live >= lim.max_live_jobs_per_client)
      return absl::ResourceExhaustedError("client '" + caller.name + "' has " +
                                          std::to_string(live) + " live jobs, the limit is " +
                                          std::to_string(lim.max_live_jobs_per_client));
    ++submitting_[caller.name];
    submitting.counted = true;
  }
  // Load the scene now, so that a bad scene is refused with the loader's file:line message.
  absl::StatusOr<SceneDesc> desc = absl::InvalidArgumentError("no scene given");
  // The scene hash reads the scene's image files (SceneHash): taken while they are on disk.
  uint64_t plain_hash = 0;
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
    if (desc.ok()) plain_hash = SceneHash(*desc);
    // The loader names files by their path here: the client sees them by the bundle's own
    // ("scene.xml:12: ..."), not this coordinator's temporary folder.
    if (!desc.ok())
      desc = absl::Status(desc.status().code(),
                          absl::StrReplaceAll(desc.status().message(), {{*dir + "/", ""}}));
    RemoveTree(*dir);
    if (!main.ok()) return main.status();
    if (name.empty()) name = bundle.main_file().empty() ? "scene.xml" : bundle.main_file();
  } else if (request.scene().has_path()) {
    absl::Status st = CheckScenePath(request.scene().path(), caller);
    if (!st.ok()) return st;
    desc = LoadJobScene(request.scene().path(), request.settings());
    if (desc.ok()) plain_hash = SceneHash(*desc);
    if (name.empty()) name = request.scene().path();
  }
  if (!desc.ok()) return desc.status();
  if (name.size() > lim.max_name_bytes)
    return absl::InvalidArgumentError("job name is " + std::to_string(name.size()) +
                                      " bytes, over the limit of " +
                                      std::to_string(lim.max_name_bytes));
  // Shown to other clients' admins (irfarm status, the dashboard): no control characters (a
  // terminal escape in a name reached an admin's terminal) and valid UTF-8, as worker names.
  name = Printable(name, lim.max_name_bytes);
  const int w = desc->camera.width, h = desc->camera.height;
  if (std::string why = JobSizeProblem(w, h, request.settings(), lim); !why.empty())
    return absl::InvalidArgumentError(why);
  const int64_t tile = JobTileSize(request.settings());
  absl::StatusOr<RenderSettings> settings = MakeRenderSettings(*desc, request.settings(), 0);
  if (!settings.ok()) return settings.status();
  if (double(settings->spp) * double(w) * double(h) > double(lim.max_samples))
    return absl::InvalidArgumentError(
        std::to_string(settings->spp) + " spp x " + std::to_string(int64_t(w) * h) +
        " pixels is over the limit of " + std::to_string(lim.max_samples) + " samples per job");
  if (settings->irrcache.record_rays > lim.max_record_rays)
    return absl::InvalidArgumentError(
        "record_rays " + std::to_string(settings->irrcache.record_rays) +
        " (from the scene) is over the limit of " + std::to_string(lim.max_record_rays));
  if (request.settings().denoise()) {
    absl::StatusOr<const Denoiser*> denoiser = GetDenoiser();
    if (!denoiser.ok()) return absl::FailedPreconditionError(denoiser.status().message());
  }
  // Jobs have no direct-sun setting (it is on): the settings part is the photon map's.
  const uint64_t scene_hash = CacheHash(plain_hash, !request.settings().no_caustics(), true);
  const RecordBounds record_bounds = RecordBoundsForScene(*desc);
  std::vector<IrradianceRecord> imported;
  if (!request.cache_snapshot().empty()) {
    absl::StatusOr<Snapshot> snap = ParseSnapshot(request.cache_snapshot(), "cache snapshot");
    if (!snap.ok()) return snap.status();
    absl::Status st = CheckSnapshotScene(*snap, scene_hash, "cache snapshot");
    if (!st.ok()) return st;
    imported = std::move(snap->records);
    // Counted against the job's record limit as workers' records are (imports were not: jobs
    // holding 64 MiB of imported records each were kept after they ended and seeded the next).
    if (int64_t(imported.size()) > options_.limits.max_job_records)
      return absl::ResourceExhaustedError(
          "cache snapshot: " + std::to_string(imported.size()) + " records, over the limit of " +
          std::to_string(options_.limits.max_job_records) + " per job");
    // The same checks as a worker's records: a snapshot is as untrusted as a worker.
    st = SnapshotRecordsProblem(record_bounds, imported, "cache snapshot");
    if (!st.ok()) return st;
    for (IrradianceRecord& r : imported) r.origin = kSnapshotOrigin;
  }

  // From here on the store is called without mu_: the job is stored before it is inserted (so
  // before anyone can see it), under an id reserved until then.
  absl::StatusOr<std::string> id = ReserveJobId();
  if (!id.ok()) return Unavailable(id.status());
  struct Unreserve {
    JobManager* m;
    std::vector<std::string> ids;
    ~Unreserve() {
      std::lock_guard<std::mutex> lock(m->mu_);
      for (const std::string& i : ids) m->reserved_ids_.erase(i);
    }
  } unreserve{this, {*id}};
  auto job = std::make_unique<Job>();
  v1::StoredJob& s = job->stored;
  v1::Job* j = s.mutable_job();
  j->set_id(*id);
  j->set_name(name);
  j->set_owner(caller.name);
  j->set_state(v1::JOB_STATE_QUEUED);
  j->set_priority(request.priority());
  j->set_width(w);
  j->set_height(h);
  *j->mutable_settings() = request.settings();
  j->set_scene_hash(scene_hash);
  j->set_records_imported(imported.size());
  *s.mutable_scene() = request.scene();
  {
    std::lock_guard<std::mutex> lock(mu_);
    s.set_sequence(next_sequence_++);
  }
  const Bounds3 b = SceneShapeBounds(*desc);
  for (float f : {b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z}) s.add_cache_bounds(f);
  s.set_max_accuracy(settings->irrcache.accuracy);
  s.set_record_max_radius(record_bounds.max_radius);
  s.set_record_max_irradiance(record_bounds.max_irradiance);
  job->tiles = std::make_unique<TileScheduler>(w, h, int(tile), options_.tile_retry);
  job->cache = std::make_unique<GlobalCache>(CacheSettingsOf(s), RecordBoundsOf(s));
  StoreCamera(desc->camera, s.mutable_camera());
  job->camera = CameraOf(s);
  absl::Status st = store_->PutJob(s);
  // A store whose job counter went back (evicted, or reset) can hand out the id of a job deleted
  // within the day, which its tombstone refuses (RedisJobStore): the next id is taken.
  for (int retry = 0; absl::IsNotFound(st) && retry < 16; ++retry) {
    absl::StatusOr<std::string> next = ReserveJobId();
    if (!next.ok()) {
      st = next.status();
      break;
    }
    unreserve.ids.push_back(*next);
    j->set_id(*next);
    st = store_->PutJob(s);
  }
  if (!st.ok()) {
    // A write that timed out may still land (Redis hung, not down): the client is told the
    // submit failed, so the job is deleted once the store answers, or it would resume after a
    // restart.
    if (absl::IsUnavailable(st)) writer_->DeleteJob(j->id());
    return Unavailable(st);
  }
  if (!imported.empty()) {
    std::vector<IrradianceRecord> merged = job->cache->Merge(imported);
    st = store_->AppendRecords(j->id(), merged);
    if (!st.ok()) {
      // Refused, so not stored either: a restart must not resume a job the client was told
      // failed (without the records it was submitted with).
      const absl::Status del = store_->DeleteJob(j->id());
      if (!del.ok()) {
        spdlog::error(
            "job {}: refused (records not stored: {}), and deleting it failed: {} "
            "(retried)",
            j->id(), st.ToString(), del.ToString());
        writer_->DeleteJob(j->id());
      }
      return Unavailable(st);
    }
  }
  std::lock_guard<std::mutex> lock(mu_);
  const v1::Job view = View(*job);
  jobs_[j->id()] = std::move(job);
  submitting.Done();
  metrics_.jobs_submitted->Add();
  Changed();
  return view;
}

absl::StatusOr<std::string> JobManager::ReserveJobId() {
  // A store that lost its data (Redis FLUSHALL, a restart without persistence) counts from 1
  // again: skip numbers of jobs this coordinator still holds rather than replace one.
  for (int skipped = 0;; ++skipped) {
    absl::StatusOr<uint64_t> number = store_->NextJobNumber();
    if (!number.ok()) return number.status();
    const std::string id = "job-" + std::to_string(*number);
    std::lock_guard<std::mutex> lock(mu_);
    if (!jobs_.count(id) && reserved_ids_.insert(id).second) return id;
    if (skipped == 0)
      spdlog::warn("job store counter went back to {}: skipping ids in use", *number);
  }
}

absl::Status JobManager::CheckScenePath(const std::string& path, const Caller& caller) const {
  if (options_.scene_path_root.empty()) {
    if (caller.admin) return absl::OkStatus();
  } else {
    // Canonical paths, so that neither ".." nor a symlink leaves the root.
    char root[PATH_MAX], real[PATH_MAX];
    if (realpath(options_.scene_path_root.c_str(), root) != nullptr &&
        realpath(path.c_str(), real) != nullptr) {
      const std::string r = std::string(root) + "/", p = real;
      if (p.compare(0, r.size(), r) == 0) return absl::OkStatus();
    }
  }
  // The same answer whether the file exists or not.
  return absl::PermissionDeniedError("scene paths on the coordinator are not allowed here" +
                                     std::string(options_.scene_path_root.empty()
                                                     ? " (upload the scene as a bundle)"
                                                     : " outside the scene path root"));
}

absl::StatusOr<JobManager::Job*> JobManager::Find(const std::string& id,
                                                  const Caller& caller) const {
  auto it = jobs_.find(id);
  if (it == jobs_.end() || (!caller.admin && it->second->stored.job().owner() != caller.name))
    return absl::NotFoundError("no job '" + Printable(id, 64) + "'");
  return it->second.get();
}

absl::StatusOr<v1::Job> JobManager::GetJob(const std::string& id, const Caller& caller) const {
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<Job*> job = Find(id, caller);
  if (!job.ok()) return job.status();
  return View(**job);
}

std::vector<v1::Job> JobManager::ListJobs(const Caller& caller) const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<v1::Job> out;
  for (const auto& [id, job] : jobs_)
    if (caller.admin || job->stored.job().owner() == caller.name) out.push_back(View(*job));
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
  job.stored.set_finished_unix_ms(UnixMs());
  job.tiles->Clear();
  // Close the cache (records stay for snapshots and seeding) and release what only a running job
  // needs: the uploaded bundle (here and in the store), and the pixels of an image nobody can
  // fetch.
  job.cache->Close();
  if (job.stored.scene().has_bundle())
    for (v1::BundleFile& f : *job.stored.mutable_scene()->mutable_bundle()->mutable_files())
      std::string().swap(*f.mutable_content());
  if (state != v1::JOB_STATE_SUCCEEDED) decltype(job.pixels)().swap(job.pixels);
  // With the emptied bundle, which replaces the upload in the store. If this never lands the job
  // resumes after a restart.
  writer_->PutJob(job.stored);
  for (uint32_t w : job.workers) {
    auto it = workers_.find(w);
    if (it == workers_.end()) continue;
    v1::CoordinatorMessage m;
    m.mutable_job_closed()->set_job_id(j->id());
    it->second.outbox.push_back(std::move(m));
    it->second.jobs.erase(j->id());
  }
  SettleWithheld(job);
  job.tallies.clear();
  for (const auto& [w, stats] : job.worker_stats)
    if (stats.records_delivered() + stats.records_withheld() > 0)
      spdlog::info("job {}: worker {} was sent {} records ({} from its backlog), withheld {}",
                   j->id(), w, stats.records_delivered(), stats.records_backlog(),
                   stats.records_withheld() - stats.records_backlog());
  job.workers.clear();
  job.regions.clear();
  job.index_stale = true;
  job.index.Build(Bounds3(), {});  // releases the grid
  job.unfiltered.clear();
  Changed();
}

void JobManager::CountFanout(Job& job, uint32_t worker_id, Worker& worker, size_t delivered,
                             size_t withheld, size_t backlog) {
  v1::WorkerJobStats& ws = job.worker_stats[worker_id];
  ws.set_worker_id(worker_id);
  if (ws.worker_name().empty()) ws.set_worker_name(worker.name);
  ws.set_records_delivered(ws.records_delivered() + delivered);
  ws.set_records_withheld(ws.records_withheld() + withheld);
  ws.set_records_backlog(ws.records_backlog() + backlog);
  worker.records_delivered += delivered;
  worker.records_withheld += withheld;
  metrics_.records_withheld->Add(double(withheld));
  metrics_.records_backlog->Add(double(backlog));
}

void JobManager::RebuildIndex(Job& job) {
  std::vector<FanoutIndex::Entry> entries;
  job.unfiltered.clear();
  for (uint32_t id : job.workers) {
    auto wit = workers_.find(id);
    if (wit == workers_.end()) continue;
    if (!Filtered(wit->second)) {
      job.unfiltered.push_back(id);
      continue;
    }
    auto r = job.regions.find(id);
    entries.push_back({id, r == job.regions.end() ? Bounds3() : r->second.box});
  }
  job.index.Build(job.cache->bounds().box, std::move(entries));
  job.index_stale = false;
}

size_t JobManager::OutboxRoom(const Worker& w) const {
  const JobLimits& lim = options_.limits;
  const size_t held = w.outbox_bytes + w.in_flight_bytes;
  return std::min(
      lim.max_outbox_bytes - std::min(lim.max_outbox_bytes, held),
      lim.max_total_outbox_bytes - std::min(lim.max_total_outbox_bytes, total_outbox_bytes_));
}

void JobManager::TakeOutboxBytes(Worker& w, size_t bytes) {
  bytes = std::min(bytes, w.outbox_bytes);
  w.outbox_bytes -= bytes;
  total_outbox_bytes_ -= std::min(total_outbox_bytes_, bytes);
}

void JobManager::ReleaseInFlight(Worker& w) {
  total_outbox_bytes_ -= std::min(total_outbox_bytes_, w.in_flight_bytes);
  w.in_flight_bytes = 0;
}

size_t JobManager::Deliver(Job& job, uint32_t other, const std::vector<IrradianceRecord>& records) {
  auto owit = workers_.find(other);
  if (owit == workers_.end() || records.empty()) return 0;
  Worker& ow = owit->second;
  const size_t n = records.size();
  // A worker that does not keep up (or does not read) gets no more fan-out past the bound, nor
  // does a silent one: the records are an optimisation, it computes its own instead.
  if (ow.silent || n * (kFloatsPerRecord + 1) * sizeof(float) > OutboxRoom(ow)) {
    ++ow.batches_dropped;
    metrics_.fanout_batches_dropped->Add();
    return n;
  }
  const size_t bytes = QueueRecords(ow, job.stored.job().id(), records);
  metrics_.records_sent->Add(n);
  metrics_.record_bytes_sent->Add(bytes);
  v1::WorkerJobStats& os = job.worker_stats[other];
  os.set_worker_id(other);
  os.set_bytes_received(os.bytes_received() + bytes);
  CountFanout(job, other, ow, n, 0, 0);
  return n;
}

void JobManager::SettleWithheld(Job& job) {
  for (auto& [id, tally] : job.tallies) SettleWithheld(job, id, /*erase=*/false);
}

void JobManager::SettleWithheld(Job& job, uint32_t worker_id, bool erase) {
  auto t = job.tallies.find(worker_id);
  if (t == job.tallies.end()) return;
  const uint64_t withheld = Unsettled(job, t->second);
  auto wit = workers_.find(worker_id);
  if (withheld > 0 && wit != workers_.end())
    CountFanout(job, worker_id, wit->second, 0, withheld, 0);
  if (erase) {
    job.tallies.erase(t);
  } else {
    t->second = Job::Tally{job.offered_total, 0, 0};
  }
}

absl::Status JobManager::AddTileRegion(uint32_t worker_id, const v1::TileRegion& region) {
  std::unique_lock<std::mutex> lock(mu_);
  auto wit = workers_.find(worker_id);
  if (wit == workers_.end()) return absl::NotFoundError("no worker");
  Worker& w = wit->second;
  absl::StatusOr<LeaseToken> token = TokenOf(worker_id, w, region.lease_token(), "tile region");
  if (!token.ok()) return token.status();
  const bool current = w.has_lease && w.lease == *token && w.lease_job == region.job_id();
  if (!current) return NotHolder(worker_id, &w, *token, "tile region");
  auto jit = jobs_.find(region.job_id());
  if (jit == jobs_.end() || IsFinal(*jit->second))
    return absl::FailedPreconditionError("tile region for a job that ended");
  Job& job = *jit->second;
  absl::StatusOr<Bounds3> box = ParseTileRegion(region, job.cache->bounds().box);
  if (!box.ok()) {
    metrics_.regions_rejected->Add();
    return Violation(worker_id, w, std::string(box.status().message()));
  }
  Job::Region& r = job.regions[worker_id];
  if (r.lease == *token)
    return absl::FailedPreconditionError("tile region: one per lease, this one ignored");
  r.lease = *token;
  metrics_.regions_accepted->Add();
  // RegionReady after whatever reaches the region: a warm-started job's worker waits for it.
  const auto ready = [&region](Worker& to) {
    v1::CoordinatorMessage m;
    m.mutable_region_ready()->set_job_id(region.job_id());
    m.mutable_region_ready()->set_lease_token(region.lease_token());
    to.outbox.push_back(std::move(m));
    WakeWorker(to);
  };
  if (!Filtered(w) || !job.workers.count(worker_id)) {
    ready(w);
    return absl::OkStatus();
  }
  const Bounds3 old = r.box;
  r.box.Extend(*box);
  const auto same = [](const Vec3& u, const Vec3& v) {
    return u.x == v.x && u.y == v.y && u.z == v.z;
  };
  if (!old.Empty() && same(old.lo, r.box.lo) && same(old.hi, r.box.hi)) {
    ready(w);
    return absl::OkStatus();
  }
  job.index_stale = true;
  // Backlog: records that reach the grown region but not the old one were withheld (every
  // record reaching the old region was sent, by fan-out or backlog). Records merged from now on
  // are fanned out against the grown region; the ones merged so far that lie in grid cells near
  // it are scanned without the lock (at most once per lease: a scan of all 2 million records
  // under the lock held every other worker's records and leases for tens of ms, the scale
  // bench's p99 latency), then queued. Backlog order: by cell, then arrival.
  const Bounds3 grown = r.box;
  const bool share = job.stored.job().settings().share_records();
  const float a = job.cache->max_accuracy();
  const GlobalCache::Near near = job.cache->RecordsNear(grown);
  const std::string job_id = region.job_id();
  // What the outbox bound leaves room for now (collected past it, the backlog would be a copy of
  // every record in memory); the rest is dropped below.
  constexpr size_t kRecordBytes = (kFloatsPerRecord + 1) * sizeof(float);
  const size_t room = OutboxRoom(w) / kRecordBytes;
  lock.unlock();
  std::vector<IrradianceRecord> backlog;
  size_t over = 0;
  near.ForEach(
      [&](const GlobalCache::Entry& e) {
        if (e.origin == worker_id || (!share && e.origin != kSnapshotOrigin)) return false;
        return ReachesBox(e.position, e.radius, e.level, grown, a) &&
               !ReachesBox(e.position, e.radius, e.level, old, a);
      },
      [&](const IrradianceRecord& rec) {
        if (backlog.size() < room) {
          backlog.push_back(rec);
        } else {
          ++over;
        }
      });
  // Packed into messages without the lock too; only handing them over takes it.
  std::vector<v1::CoordinatorMessage> messages;
  std::vector<size_t> counts;
  std::vector<IrradianceRecord> chunk;
  for (size_t i = 0; i < backlog.size(); i += options_.sync_batch_records) {
    const size_t end = std::min(backlog.size(), i + options_.sync_batch_records);
    chunk.assign(backlog.begin() + ptrdiff_t(i), backlog.begin() + ptrdiff_t(end));
    v1::CoordinatorMessage& m = messages.emplace_back();
    m.mutable_records()->set_job_id(job_id);
    PackRecords(chunk, kSnapshotOrigin, m.mutable_records()->mutable_batch());
    counts.push_back(chunk.size());
  }
  lock.lock();
  // The worker may have left, or the job ended, meanwhile: then nobody needs the backlog.
  wit = workers_.find(worker_id);
  jit = jobs_.find(job_id);
  if (wit == workers_.end() || jit == jobs_.end() || IsFinal(*jit->second)) return absl::OkStatus();
  Worker& w2 = wit->second;
  Job& job2 = *jit->second;
  if (!job2.workers.count(worker_id)) return absl::OkStatus();
  const bool was_empty = w2.outbox.empty();
  size_t queued = 0, dropped_batches = over > 0 ? 1 : 0;
  for (size_t k = 0; k < messages.size(); ++k) {
    const size_t bytes = BatchBytes(messages[k].records().batch());
    // The backlog is fan-out too: past the outbox bounds the rest is dropped and counted, as
    // Deliver drops batches (the worker computes those records itself).
    if (bytes > OutboxRoom(w2)) {
      dropped_batches += messages.size() - k;
      break;
    }
    ++queued;
    w2.outbox.push_back(std::move(messages[k]));
    w2.outbox_bytes += bytes;
    total_outbox_bytes_ += bytes;
    v1::WorkerJobStats& ws = job2.worker_stats[worker_id];
    ws.set_bytes_received(ws.bytes_received() + bytes);
    metrics_.records_sent->Add(counts[k]);
    metrics_.record_bytes_sent->Add(bytes);
    CountFanout(job2, worker_id, w2, counts[k], 0, counts[k]);
  }
  if (was_empty && queued > 0) w2.records_queued_at = std::chrono::steady_clock::now();
  if (dropped_batches > 0) {
    w2.batches_dropped += dropped_batches;
    metrics_.fanout_batches_dropped->Add(double(dropped_batches));
  }
  ready(w2);
  Touched(&w2);
  return absl::OkStatus();
}

absl::StatusOr<v1::Job> JobManager::Cancel(const std::string& id, const Caller& caller) {
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<Job*> found = Find(id, caller);
  if (!found.ok()) return found.status();
  Job& job = **found;
  if (IsFinal(job))
    return absl::FailedPreconditionError("job '" + id + "' is already " +
                                         v1::JobState_Name(job.stored.job().state()));
  FinishJob(job, v1::JOB_STATE_CANCELLED, "cancelled by a client");
  return View(job);
}

absl::Status JobManager::Delete(const std::string& id, const Caller& caller) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    absl::StatusOr<Job*> found = Find(id, caller);
    if (!found.ok()) return found.status();
    if (!IsFinal(**found))
      return absl::FailedPreconditionError("job '" + id + "' is " +
                                           v1::JobState_Name((*found)->stored.job().state()) +
                                           ": cancel it first");
  }
  const absl::Status removed = RemoveJob(id);
  if (!removed.ok()) return removed;
  metrics_.jobs_deleted->Add();
  return absl::OkStatus();
}

// Called without mu_: the store is asked first (it may hang up to its deadline), the job leaves
// memory only once the store no longer has it. A final job never changes, so nothing is lost
// between the two.
absl::Status JobManager::RemoveJob(const std::string& id) {
  // Job-state writes queued before (the job's final state) must land first, or one would put
  // the job back into the store after the delete.
  if (!writer_->Flush(std::chrono::seconds(2))) {
    spdlog::warn("cannot delete job {}: earlier store writes are still pending", id);
    return absl::UnavailableError("job store: cannot delete job '" + id +
                                  "': " + std::to_string(writer_->pending()) +
                                  " earlier store writes are still pending (is the store up?); "
                                  "retry later");
  }
  absl::Status st = store_->DeleteJob(id);
  if (!st.ok()) {
    spdlog::warn("cannot delete job {} from the store: {}", id, st.ToString());
    // Kept in memory: retried by the next ExpireJobs. The store's own code (a fenced store's
    // FAILED_PRECONDITION is not worth retrying) and reason go to the client.
    return absl::Status(st.code(),
                        "job store: cannot delete job '" + id + "': " + std::string(st.message()));
  }
  std::lock_guard<std::mutex> lock(mu_);
  jobs_.erase(id);
  Changed();
  return absl::OkStatus();
}

int JobManager::ExpireJobs() {
  std::vector<std::string> expired;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const int64_t now_ms = UnixMs();
    std::vector<std::pair<int64_t, std::string>> finished;  // (finish time, id)
    for (const auto& [id, job] : jobs_) {
      if (!IsFinal(*job)) continue;
      if (job->stored.finished_unix_ms() == 0) job->stored.set_finished_unix_ms(now_ms);
      finished.emplace_back(job->stored.finished_unix_ms(), id);
    }
    std::sort(finished.begin(), finished.end(), std::greater<>());  // newest first
    for (size_t k = 0; k < finished.size(); ++k) {
      const bool too_old =
          options_.job_ttl.count() > 0 && now_ms - finished[k].first > options_.job_ttl.count();
      const bool too_many =
          options_.max_finished_jobs > 0 && k >= size_t(options_.max_finished_jobs);
      if (too_old || too_many) expired.push_back(finished[k].second);
    }
  }
  // The round ends when the store is unavailable: each try may wait on it (up to 2 s for
  // pending writes), and lease expiry runs on the same thread after this (a stuck store with 30
  // expired jobs held it a minute a round); the next round tries again. Another failure is that
  // job's own: the others are still removed.
  int removed = 0;
  for (const std::string& id : expired) {
    const absl::Status st = RemoveJob(id);
    if (st.ok()) {
      ++removed;
    } else if (absl::IsUnavailable(st) || absl::IsDeadlineExceeded(st)) {
      break;
    }
  }
  metrics_.jobs_expired->Add(uint64_t(removed));
  return removed;
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

absl::StatusOr<JobManager::FinishedTiles> JobManager::TilesOf(const std::string& id,
                                                              const Caller& caller,
                                                              bool succeeded_only) const {
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<Job*> found = Find(id, caller);
  if (!found.ok()) return found.status();
  const Job& job = **found;
  const v1::JobState state = job.stored.job().state();
  if (state == v1::JOB_STATE_FAILED || state == v1::JOB_STATE_CANCELLED ||
      (succeeded_only && state != v1::JOB_STATE_SUCCEEDED))
    return absl::FailedPreconditionError("job '" + id + "' has no image: it is " +
                                         v1::JobState_Name(state));
  FinishedTiles t;
  t.width = job.stored.job().width();
  t.height = job.stored.job().height();
  t.denoise = job.stored.job().settings().denoise();
  t.firefly_filter = !job.stored.job().settings().no_firefly_filter();
  t.tiles.reserve(job.pixels.size());
  for (const auto& [tile, bytes] : job.pixels) t.tiles.emplace_back(job.tiles->rect(tile), bytes);
  return t;
}

absl::StatusOr<Image> JobManager::Preview(const std::string& id, const Caller& caller) const {
  absl::StatusOr<FinishedTiles> t = TilesOf(id, caller, false);  // under mu_; the rest without
  if (!t.ok()) return t.status();
  // At most kMaxPreviewSide on the longer side: each preview pixel the mean of the finished
  // pixels of its f x f block (a 67 M-pixel job's full preview was 0.8 GB of floats, asked for
  // every second by the dashboard).
  const int f =
      std::max(1, (std::max(t->width, t->height) + kMaxPreviewSide - 1) / kMaxPreviewSide);
  const int w = (t->width + f - 1) / f, h = (t->height + f - 1) / f;
  Image image(w, h);
  std::vector<int> count(size_t(w) * size_t(h), 0);
  for (const auto& [r, bytes] : t->tiles) {
    for (int y = r.y0; y < r.y1; ++y)
      for (int x = r.x0; x < r.x1; ++x) {
        // RGB floats first (guides follow for denoised jobs); sizes were checked on the way in.
        float rgb[3];
        const size_t i = 3 * (size_t(y - r.y0) * r.width() + (x - r.x0));
        std::memcpy(rgb, bytes->data() + i * sizeof(float), sizeof rgb);
        image.at(x / f, y / f) += Vec3(rgb[0], rgb[1], rgb[2]);
        ++count[size_t(y / f) * size_t(w) + size_t(x / f)];
      }
  }
  for (size_t p = 0; p < image.pixels.size(); ++p)
    if (count[p] > 1) image.pixels[p] = image.pixels[p] / float(count[p]);
  return image;
}

absl::StatusOr<Image> JobManager::RecordMap(const std::string& id, const Caller& caller) const {
  std::vector<RecordMapPoint> points;
  std::unique_lock<std::mutex> lock(mu_);
  absl::StatusOr<Job*> found = Find(id, caller);
  if (!found.ok()) return found.status();
  const Job& job = **found;
  if (job.camera == nullptr)
    return absl::FailedPreconditionError("job '" + id + "' was stored without its camera");
  const Camera camera = *job.camera;  // the job may be removed once the lock is released
  // Copied under the lock (the record list grows under it), drawn without it. Beyond
  // kMaxRecordMapPoints an even stride through the records, so the copy stays bounded.
  const RecordLog& all = job.cache->records();
  const size_t stride = (all.size() + kMaxRecordMapPoints - 1) / kMaxRecordMapPoints;
  points.reserve(std::min(all.size(), kMaxRecordMapPoints));
  for (size_t i = 0; i < all.size(); i += std::max<size_t>(stride, 1))
    if (all[i].level == 0) points.push_back({all[i].position, all[i].origin});
  lock.unlock();
  return DrawRecordMap(camera, points);
}

absl::StatusOr<v1::Job> JobManager::SetPriority(const std::string& id, int priority,
                                                const Caller& caller) {
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<Job*> found = Find(id, caller);
  if (!found.ok()) return found.status();
  Job& job = **found;
  if (IsFinal(job))
    return absl::FailedPreconditionError("job '" + id + "' is already " +
                                         v1::JobState_Name(job.stored.job().state()));
  if (priority < 0 || priority > JobLimits::kMaxPriority)
    return absl::InvalidArgumentError("priority must be in [0, " +
                                      std::to_string(JobLimits::kMaxPriority) + "], got " +
                                      std::to_string(priority));
  job.stored.mutable_job()->set_priority(priority);
  writer_->PutJob(StateOnly(job.stored));  // off the lock, retried until the store has it
  Changed();
  return View(job);
}

absl::StatusOr<std::string> JobManager::ResultExr(const std::string& id,
                                                  const Caller& caller) const {
  absl::StatusOr<FinishedTiles> t = TilesOf(id, caller, true);  // under mu_; the rest without
  if (!t.ok()) return t.status();
  Image image(t->width, t->height);
  // The brightest samples' shares, for the firefly filter (zero where a tile carries none;
  // allocated only when one does).
  std::vector<Vec3> peak;
  AovImages guides;  // albedo and normal only, for denoised jobs
  const bool denoise = t->denoise;
  if (denoise) {
    guides = AovImages(t->width, t->height);
    guides.variance = Image();  // not carried by the tiles: the denoiser cannot judge the noise
  }
  {
    for (const auto& [r, bytes] : t->tiles) {
      std::vector<float> px(bytes->size() / sizeof(float));
      std::memcpy(px.data(), bytes->data(), px.size() * sizeof(float));
      const size_t n = size_t(r.width()) * r.height();
      // Sizes were checked when the tile came in (or was read back): guides for a denoised job,
      // then the peaks where the tile has them.
      const size_t guide_floats = denoise ? 6 * n : 0;
      const bool has_guides = denoise && px.size() >= 9 * n;
      const bool has_peaks = t->firefly_filter && px.size() == 6 * n + guide_floats;
      for (int y = r.y0; y < r.y1; ++y)
        for (int x = r.x0; x < r.x1; ++x) {
          const size_t k = size_t(y - r.y0) * r.width() + (x - r.x0), i = 3 * k;
          image.at(x, y) = Vec3(px[i], px[i + 1], px[i + 2]);
          if (has_peaks) {
            if (peak.empty()) peak.resize(image.pixels.size());
            const size_t q = 3 * n + guide_floats + 3 * k;
            peak[size_t(y) * size_t(t->width) + size_t(x)] = Vec3(px[q], px[q + 1], px[q + 2]);
          }
          if (has_guides) {
            const size_t g = 3 * n + 6 * k;
            guides.albedo.at(x, y) = Vec3(px[g], px[g + 1], px[g + 2]);
            guides.normal.at(x, y) = Vec3(px[g + 3], px[g + 4], px[g + 5]);
          }
        }
    }
  }
  // The firefly filter over the whole image, as one process applies it to its own (the tiles
  // left their pixels as rendered).
  if (!peak.empty()) SpreadFireflies(image, peak);
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

absl::StatusOr<std::string> JobManager::ExportSnapshot(const std::string& id,
                                                       const Caller& caller) const {
  Snapshot snap;
  RecordLog::View records;
  {
    std::lock_guard<std::mutex> lock(mu_);
    absl::StatusOr<Job*> found = Find(id, caller);
    if (!found.ok()) return found.status();
    snap.scene_hash = (*found)->stored.job().scene_hash();
    records = (*found)->cache->records().Snapshot();
  }
  // Copied without the lock (a job's cache may hold a GB of records: every worker's and client's
  // call waited for the copy before).
  snap.records = records.ToVector();
  return SerializeSnapshot(snap);
}

uint64_t JobManager::WaitForChange(uint64_t seen, std::chrono::milliseconds timeout) const {
  std::unique_lock<std::mutex> lock(mu_);
  changed_cv_.wait_for(lock, timeout, [&] { return version_ != seen; });
  return version_;
}

uint32_t JobManager::RegisterWorker(const std::string& name, const std::string& peer, int threads,
                                    bool reports_regions, const std::string& token) {
  std::lock_guard<std::mutex> lock(mu_);
  const uint32_t id = next_worker_++;
  Worker& w = workers_[id];
  w.reports_regions = reports_regions;
  w.name = Printable(name, options_.limits.max_name_bytes);
  w.health_key = token.empty() ? w.name : token + "/" + w.name;
  w.peer = peer;
  w.threads = threads;
  w.last_heard = std::chrono::steady_clock::now();
  Changed();
  return id;
}

void JobManager::WorkerGone(uint32_t worker, const std::string& reason) {
  std::lock_guard<std::mutex> lock(mu_);
  auto wit = workers_.find(worker);
  if (wit == workers_.end()) return;
  for (auto& [id, job] : jobs_) {
    SettleWithheld(*job, worker, /*erase=*/true);
    if (job->workers.erase(worker)) job->index_stale = true;
    if (IsFinal(*job)) continue;
    const std::vector<uint32_t> holders = job->tiles->LeaseHolders();
    metrics_.lease_lost_disconnect->Add(
        uint64_t(std::count(holders.begin(), holders.end(), worker)));
    // A worker that said it drains (stopped by its operator) ends its session with whatever it
    // was leased meanwhile: not a failure of those tiles. One that vanished is counted.
    absl::Status st = job->tiles->ReleaseWorker(
        worker, "worker " + std::to_string(worker) + " (" + wit->second.name + ") " + reason,
        /*count_failure=*/!wit->second.draining);
    if (!st.ok()) FinishJob(*job, v1::JOB_STATE_FAILED, std::string(st.message()));
  }
  // Forget the health of a name with nothing against it (bounded by live workers then).
  auto h = health_.find(wit->second.health_key);
  if (h != health_.end() && h->second.consecutive_failures == 0 &&
      h->second.quarantined_until <= std::chrono::steady_clock::now())
    health_.erase(h);
  WakeWorker(wit->second);  // its Poll returns now
  TakeOutboxBytes(wit->second, wit->second.outbox_bytes);
  ReleaseInFlight(wit->second);
  workers_.erase(wit);
  Changed();
}

void JobManager::Drain(uint32_t worker) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = workers_.find(worker);
  if (it != workers_.end()) it->second.draining = true;
}

void JobManager::Heard(uint32_t worker) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = workers_.find(worker);
  if (it == workers_.end()) return;
  it->second.last_heard = std::chrono::steady_clock::now();
  if (it->second.silent) {
    it->second.silent = false;
    Changed();  // it may get a lease again
  }
}

bool JobManager::Expelled(uint32_t worker) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = workers_.find(worker);
  return it != workers_.end() && int(it->second.violations) > options_.max_violations;
}

absl::Status JobManager::Violation(uint32_t worker_id, Worker& worker, const std::string& reason,
                                   absl::StatusCode code) {
  ++worker.violations;
  ++violations_total_;
  metrics_.worker_violations->Add();
  if (int(worker.violations) == options_.max_violations + 1) ++expelled_total_;
  v1::CoordinatorMessage m;
  m.mutable_rejected()->set_reason(reason);
  m.mutable_rejected()->set_violations(worker.violations);
  m.mutable_rejected()->set_limit(uint32_t(options_.max_violations));
  m.mutable_rejected()->set_code(int32_t(code));  // absl and gRPC share the google.rpc.Code numbers
  worker.outbox.push_back(std::move(m));
  Changed();
  return absl::Status(code, "worker " + std::to_string(worker_id) + ": " + reason);
}

absl::StatusOr<LeaseToken> JobManager::TokenOf(uint32_t worker_id, Worker& worker,
                                               const std::string& bytes, const std::string& what) {
  std::optional<LeaseToken> token = LeaseToken::FromBytes(bytes);
  if (!token)
    return Violation(worker_id, worker,
                     what + ": lease token is " + std::to_string(bytes.size()) +
                         " bytes, expected " + std::to_string(LeaseToken::kBytes),
                     absl::StatusCode::kInvalidArgument);
  return *token;
}

absl::Status JobManager::NotHolder(uint32_t worker_id, Worker* worker, const LeaseToken& token,
                                   const std::string& what) {
  if (worker == nullptr) return absl::NotFoundError("no worker " + std::to_string(worker_id));
  const bool held = std::any_of(worker->past_leases.begin(), worker->past_leases.end(),
                                [&](const auto& l) { return l.first == token; });
  if (!held) return Violation(worker_id, *worker, what + " for a lease this worker does not hold");
  // Harmless and not answered (an answer per stale message would let a worker that does not
  // read grow its outbox without bound).
  return absl::FailedPreconditionError(what + ": the lease expired (tile re-leased or done)");
}

void JobManager::ReleaseLease(Worker& worker, const LeaseToken& token) {
  if (worker.has_lease && worker.lease == token) worker.has_lease = false;
}

void JobManager::TileFailedOn(const Worker& worker) {
  constexpr size_t kMaxHealthEntries = 4096;  // names with failures (a bound against renaming)
  if (health_.size() >= kMaxHealthEntries && !health_.count(worker.health_key)) {
    const SteadyTime now = std::chrono::steady_clock::now();
    for (auto it = health_.begin(); it != health_.end();)
      it = it->second.quarantined_until <= now ? health_.erase(it) : std::next(it);
  }
  WorkerHealth& h = health_[worker.health_key];
  if (++h.consecutive_failures >= options_.quarantine_after) {
    h.consecutive_failures = 0;
    h.quarantined_until = std::chrono::steady_clock::now() + options_.quarantine_time;
    spdlog::warn("worker '{}' quarantined for {} s: {} failed tiles in a row", worker.name,
                 options_.quarantine_time.count() / 1000.0, options_.quarantine_after);
  }
}

bool JobManager::Quarantined(const Worker& worker, SteadyTime now) const {
  auto it = health_.find(worker.health_key);
  return it != health_.end() && it->second.quarantined_until > now;
}

std::vector<uint32_t> JobManager::OtherEligibleWorkers(uint32_t worker_id, SteadyTime now) const {
  std::vector<uint32_t> out;
  // One whose lease is overdue is left out: it gets no lease before it reports (has_lease), so
  // a tile that failed on every other worker would wait for it for ever (the job never ended).
  for (const auto& [id, w] : workers_)
    if (id != worker_id && !w.silent && !w.draining && !Quarantined(w, now) &&
        !(w.has_lease && w.lease_deadline < now))
      out.push_back(id);
  return out;
}

absl::Status JobManager::AddRecords(uint32_t worker, const v1::JobRecords& records) {
  if (records.batch().origins_size() > options_.limits.max_batch_records) {
    std::lock_guard<std::mutex> lock(mu_);
    auto wit = workers_.find(worker);
    if (wit == workers_.end()) return absl::NotFoundError("no worker");
    return Violation(worker, wit->second,
                     std::to_string(records.batch().origins_size()) +
                         " records in one message, over the limit of " +
                         std::to_string(options_.limits.max_batch_records));
  }
  absl::StatusOr<std::vector<IrradianceRecord>> decoded = DecodeRecords(records.batch());
  std::unique_lock<std::mutex> lock(mu_);
  auto wit = workers_.find(worker);
  if (wit == workers_.end()) return absl::NotFoundError("no worker");
  Worker& w = wit->second;
  if (!decoded.ok()) return Violation(worker, w, std::string(decoded.status().message()));
  for (IrradianceRecord& r : *decoded) r.origin = worker;  // a worker speaks for itself only
  auto it = jobs_.find(records.job_id());
  const bool holds = w.has_lease && w.lease_job == records.job_id();
  if (it == jobs_.end() || IsFinal(*it->second) || !holds) {
    // Records of a job it held a lease of, arriving after the job ended or the lease expired,
    // are harmless: dropped, not counted against the worker.
    for (const auto& [lease, job_id] : w.past_leases)
      if (job_id == records.job_id())
        return absl::FailedPreconditionError("records for job " + job_id +
                                             " after its lease or the job ended: dropped");
    return Violation(worker, w,
                     "records for job '" + Printable(records.job_id(), 64) +
                         "', which this worker holds no lease of");
  }
  Job& job = *it->second;
  // The job's record budget: a worker holding a lease could otherwise send valid records without
  // end (memory, the store, and every other worker's share). Batches in flight to the store are
  // not counted, so a job may pass the limit by a few batches.
  if (int64_t(job.cache->size() + decoded->size()) > options_.limits.max_job_records)
    return Violation(worker, w,
                     std::to_string(decoded->size()) + " more records for job " +
                         job.stored.job().id() + ", which holds " +
                         std::to_string(job.cache->size()) + ": over the record limit of " +
                         std::to_string(options_.limits.max_job_records) + " per job");
  v1::WorkerJobStats& ws = job.worker_stats[worker];
  ws.set_worker_id(worker);
  ws.set_records_sent(ws.records_sent() + decoded->size());
  ws.set_bytes_sent(ws.bytes_sent() + BatchBytes(records.batch()));
  metrics_.records_received->Add(decoded->size());
  metrics_.record_bytes_received->Add(BatchBytes(records.batch()));
  const char* problem = nullptr;
  const std::vector<IrradianceRecord> accepted = job.cache->Check(*decoded, &problem);
  metrics_.records_rejected->Add(decoded->size() - accepted.size());
  absl::Status result = absl::OkStatus();
  if (problem != nullptr)
    result = Violation(worker, w,
                       std::to_string(decoded->size() - accepted.size()) + " of " +
                           std::to_string(decoded->size()) + " records for job " +
                           records.job_id() + " refused (first: " + problem + ")");
  if (accepted.empty()) return result;
  // Stored first (without the lock), merged only then: what was merged is in the store (a store
  // failure drops the batch; records are an optimisation, workers compute their own).
  const std::string job_id = job.stored.job().id();
  lock.unlock();
  absl::Status st = store_->AppendRecords(job_id, accepted);
  if (absl::IsNotFound(st))
    st = RestoreLostJob(job_id, [&] { return store_->AppendRecords(job_id, accepted); });
  // A violation recorded above stays the answer (it is what the session's expulsion names).
  if (!result.ok()) {
    if (!st.ok()) return result;
  } else if (absl::IsNotFound(st)) {  // deleted meanwhile: stale, as a result for a closed job
    return absl::FailedPreconditionError("job '" + job_id +
                                         "' was deleted: its records are not stored");
  } else if (!st.ok()) {
    return Unavailable(st);
  }
  lock.lock();
  it = jobs_.find(job_id);
  if (it == jobs_.end()) return result;
  // Merged even if the job ended meanwhile (the record list outlives the index): it arrived
  // while the job ran, and the store has it.
  it->second->cache->Insert(accepted);
  metrics_.records_merged->Add(accepted.size());
  if (IsFinal(*it->second)) {
    Changed();
    return result;
  }
  Job& job2 = *it->second;
  if (job2.stored.job().settings().share_records()) {
    // Each receiver's records are appended to its outbox's last records message (QueueRecords):
    // no message per sender and receiver, and no copy of a shared message per receiver. The
    // filtered receivers come from the job's grid of regions: per record the workers it
    // reaches, not every worker (fanout_index.h).
    if (job2.index_stale) RebuildIndex(job2);
    job2.offered_total += accepted.size();
    auto own = job2.tallies.find(worker);
    if (own != job2.tallies.end()) own->second.own += accepted.size();
    for (uint32_t other : job2.unfiltered)
      if (other != worker) Deliver(job2, other, accepted);
    const float max_accuracy = job2.cache->max_accuracy();
    job2.deliveries.clear();
    for (size_t i = 0; i < accepted.size(); ++i) {
      job2.index.Query(accepted[i], max_accuracy, &job2.slots);
      for (uint32_t slot : job2.slots)
        if (job2.index.worker(slot) != worker) job2.deliveries.emplace_back(slot, uint32_t(i));
    }
    // Grouped by receiver, each receiver's records in batch order.
    std::sort(job2.deliveries.begin(), job2.deliveries.end());
    std::vector<IrradianceRecord> near;
    for (size_t k = 0; k < job2.deliveries.size();) {
      const uint32_t slot = job2.deliveries[k].first;
      near.clear();
      for (; k < job2.deliveries.size() && job2.deliveries[k].first == slot; ++k)
        near.push_back(accepted[job2.deliveries[k].second]);
      const uint32_t other = job2.index.worker(slot);
      const size_t handled = Deliver(job2, other, near);
      auto t = job2.tallies.find(other);
      if (t != job2.tallies.end()) t->second.handled += handled;
    }
  }
  Touched(nullptr);  // job views (records merged); receivers were woken by QueueRecords
  return result;
}

absl::StatusOr<JobManager::HeldLease> JobManager::ReleaseHeldLease(uint32_t worker_id,
                                                                   const std::string& token_bytes,
                                                                   const std::string& job_id,
                                                                   int tile,
                                                                   const std::string& what) {
  auto wit = workers_.find(worker_id);
  if (wit == workers_.end()) return absl::NotFoundError("no worker " + std::to_string(worker_id));
  Worker& w = wit->second;
  const absl::StatusOr<LeaseToken> token = TokenOf(worker_id, w, token_bytes, what);
  if (!token.ok()) return token.status();
  // A report under the worker's current lease must name that lease's job and tile. Else it is a
  // violation and the lease stays: released here, a worker could answer every lease with a
  // made-up tile and be given the next one while the scheduler still held the last for it
  // (each for the whole lease time, then failed back), one worker taking every pending tile.
  const bool current = w.has_lease && w.lease == *token;
  if (current && (job_id != w.lease_job || tile != w.lease_tile))
    return Violation(worker_id, w,
                     what + " names tile " + std::to_string(tile) + " of job '" +
                         Printable(job_id, 64) + "', but its lease is tile " +
                         std::to_string(w.lease_tile) + " of job '" + w.lease_job + "'",
                     absl::StatusCode::kInvalidArgument);
  auto it = jobs_.find(job_id);
  const TileLeaseInfo* lease = it == jobs_.end() || IsFinal(*it->second) || tile < 0 ||
                                       tile >= it->second->tiles->num_tiles()
                                   ? nullptr
                                   : it->second->tiles->Current(tile, *token);
  // Either way a report on the current lease ends it (expired, re-leased or done, it is over).
  ReleaseLease(w, *token);
  if (lease == nullptr || lease->worker != worker_id) return NotHolder(worker_id, &w, *token, what);
  return HeldLease{&w, it->second.get(), lease, *token};
}

absl::Status JobManager::RestoreLostJob(const std::string& job_id,
                                        const std::function<absl::Status()>& retry) {
  v1::StoredJob stored;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = jobs_.find(job_id);
    // A final job may be being deleted (RemoveJob asks the store first): not written back.
    if (it == jobs_.end() || IsFinal(*it->second))
      return absl::NotFoundError("job store: job '" + job_id + "' is not stored");
    stored = it->second->stored;
  }
  spdlog::warn(
      "job {}: the store does not hold this running job (its data was lost: flushed or "
      "evicted); written again",
      job_id);
  absl::Status st = store_->PutJob(stored);
  if (!st.ok()) return st;
  {
    // The job may have finished meanwhile, its final state queued (and perhaps written) before
    // this older copy landed: queued again, so the store ends with the newest.
    std::lock_guard<std::mutex> lock(mu_);
    auto it = jobs_.find(job_id);
    if (it != jobs_.end() && it->second->stored.job().state() != stored.job().state())
      writer_->PutJob(it->second->stored);
  }
  return retry();
}

absl::Status JobManager::CompleteTile(uint32_t worker, const v1::TileResult& result) {
  std::unique_lock<std::mutex> lock(mu_);
  const int tile = result.tile_index();
  absl::StatusOr<HeldLease> held =
      ReleaseHeldLease(worker, result.lease_token(), result.job_id(), tile, "tile result");
  if (!held.ok()) return held.status();
  Worker& w = *held->worker;
  Job& job = *held->job;
  const LeaseToken* token = &held->token;
  const SteadyTime lease_start = held->lease->start;
  Touched(&w);  // it may get its next lease
  // The result of the lease this worker holds: check it before it counts.
  const PixelRect& r = job.tiles->rect(tile);
  const int64_t pixels = int64_t(r.width()) * r.height();
  std::string bad;
  if (result.pixels_size() != pixels * 3) {
    bad = "tile " + std::to_string(tile) + " has " + std::to_string(result.pixels_size()) +
          " floats, expected " + std::to_string(pixels * 3);
  } else {
    for (int i = 0; i < result.pixels_size(); ++i) {
      const float v = result.pixels(i);
      if (!std::isfinite(v) || v < 0) {
        bad = "tile " + std::to_string(tile) + " pixel value " + std::to_string(i) +
              " is not finite and non-negative";
        break;
      }
    }
  }
  const bool denoise = job.stored.job().settings().denoise();
  if (bad.empty() && result.guides_size() != (denoise ? pixels * 6 : 0))
    bad = "tile " + std::to_string(tile) + " has " + std::to_string(result.guides_size()) +
          " guide floats, expected " + std::to_string(denoise ? pixels * 6 : 0);
  for (int i = 0; bad.empty() && i < result.guides_size(); ++i)
    if (!std::isfinite(result.guides(i)))
      bad = "tile " + std::to_string(tile) + " guide value " + std::to_string(i) + " is not finite";
  // Peaks: none (a worker from before the filter: that tile's fireflies stay), or one RGB a pixel
  // where the job has the filter.
  const int64_t peak_floats = pixels * PeakFloats(job.stored.job().settings());
  if (bad.empty() && result.peaks_size() != 0 && result.peaks_size() != peak_floats)
    bad = "tile " + std::to_string(tile) + " has " + std::to_string(result.peaks_size()) +
          " peak floats, expected " + std::to_string(peak_floats) + " or none";
  for (int i = 0; bad.empty() && i < result.peaks_size(); ++i)
    if (!std::isfinite(result.peaks(i)))
      bad = "tile " + std::to_string(tile) + " peak value " + std::to_string(i) + " is not finite";
  const v1::TileStats& ts = result.stats();
  if (bad.empty()) {
    // Sane stats: no counter above 1e6 per pixel and sample (an irradiance lookup or record per
    // path vertex is at most a few hundred), hits within lookups, remote within used, and render
    // time within the time since the lease was given (plus 1 s for clock granularity).
    const double spp = std::max(1, job.stored.job().settings().spp());
    const double cap = 1e6 * double(pixels) * std::max(spp, 1024.0);
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - lease_start).count();
    if (double(ts.records_computed()) > cap || double(ts.lookups()) > cap ||
        double(ts.records_used()) > cap || ts.lookup_hits() > ts.lookups() ||
        ts.remote_records_used() > ts.records_used() ||
        ts.records_received() > job.cache->size() + 1 || !std::isfinite(ts.wall_seconds()) ||
        ts.wall_seconds() < 0 || ts.wall_seconds() > elapsed + 1.0)
      bad = "tile " + std::to_string(tile) + " stats out of bounds";
  }
  if (!bad.empty()) {
    metrics_.tiles_failed->Add();
    TileFailedOn(w);
    absl::Status st = job.tiles->Requeue(
        tile, *token, "worker " + std::to_string(worker) + " sent an invalid result");
    if (!st.ok()) FinishJob(job, v1::JOB_STATE_FAILED, std::string(st.message()));
    return Violation(worker, w, bad);
  }
  std::string bytes(reinterpret_cast<const char*>(result.pixels().data()),
                    size_t(result.pixels_size()) * sizeof(float));
  bytes.append(reinterpret_cast<const char*>(result.guides().data()),
               size_t(result.guides_size()) * sizeof(float));
  bytes.append(reinterpret_cast<const char*>(result.peaks().data()),
               size_t(result.peaks_size()) * sizeof(float));
  // Stored without the lock; counted under it only if the lease is still current (it may have
  // expired, or the job ended, while the store was slow: the stored pixels are then overwritten
  // when the tile is done again, or never read).
  const std::string job_id = job.stored.job().id();
  lock.unlock();
  absl::Status st = store_->PutTile(job_id, tile, bytes);
  if (absl::IsNotFound(st))
    st = RestoreLostJob(job_id, [&] { return store_->PutTile(job_id, tile, bytes); });
  lock.lock();
  auto it = jobs_.find(job_id);
  if (it == jobs_.end() || IsFinal(*it->second) ||
      it->second->tiles->Current(tile, *token) == nullptr)
    return absl::FailedPreconditionError("tile result: the lease ended while it was stored");
  Job& done = *it->second;
  if (!st.ok()) {
    // Not stored, so not done: the tile is rendered again.
    (void)done.tiles->Requeue(tile, *token, "job store failed", false);
    Changed();
    return Unavailable(st);
  }
  st = done.tiles->Complete(tile, *token);
  if (!st.ok()) return st;
  auto wit = workers_.find(worker);
  const std::string worker_name = wit == workers_.end() ? std::string() : wit->second.name;
  if (wit != workers_.end()) health_[wit->second.health_key].consecutive_failures = 0;
  done.pixels[tile] = std::make_shared<const std::string>(std::move(bytes));
  v1::WorkerJobStats& ws = done.worker_stats[worker];
  ws.set_worker_id(worker);
  ws.set_worker_name(worker_name);
  ws.set_tiles(ws.tiles() + 1);
  ws.set_records_computed(ws.records_computed() + ts.records_computed());
  ws.set_records_received(ws.records_received() + ts.records_received());
  ws.set_remote_records_used(ws.remote_records_used() + ts.remote_records_used());
  ws.set_records_used(ws.records_used() + ts.records_used());
  ws.set_lookups(ws.lookups() + ts.lookups());
  ws.set_lookup_hits(ws.lookup_hits() + ts.lookup_hits());
  ws.set_render_seconds(ws.render_seconds() + ts.wall_seconds());
  metrics_.tiles_completed->Add();
  metrics_.records_computed->Add(ts.records_computed());
  metrics_.lookups->Add(ts.lookups());
  metrics_.lookup_hits->Add(ts.lookup_hits());
  if (done.tiles->all_done()) FinishJob(done, v1::JOB_STATE_SUCCEEDED, "");
  Touched(wit != workers_.end() ? &wit->second : nullptr);
  return absl::OkStatus();
}

absl::Status JobManager::FailTile(uint32_t worker, const v1::TileFailed& failed) {
  std::lock_guard<std::mutex> lock(mu_);
  const int tile = failed.tile_index();
  absl::StatusOr<HeldLease> held =
      ReleaseHeldLease(worker, failed.lease_token(), failed.job_id(), tile, "tile failure");
  if (!held.ok()) return held.status();
  Worker& w = *held->worker;
  Job& job = *held->job;
  const LeaseToken* token = &held->token;
  metrics_.tiles_failed->Add();
  TileFailedOn(w);
  absl::Status st = job.tiles->Requeue(
      tile, *token,
      "worker " + std::to_string(worker) + " (" + w.name + "): " + Printable(failed.reason()));
  if (!st.ok()) FinishJob(job, v1::JOB_STATE_FAILED, std::string(st.message()));
  Changed();
  return absl::OkStatus();
}

v1::GetClusterResponse JobManager::Cluster(const Caller& caller) const {
  std::lock_guard<std::mutex> lock(mu_);
  v1::GetClusterResponse out;
  const SteadyTime now = std::chrono::steady_clock::now();
  for (const auto& [id, w] : workers_) {
    v1::WorkerInfo* i = out.add_workers();
    i->set_id(id);
    i->set_name(w.name);
    if (caller.admin) i->set_peer(w.peer);
    i->set_has_lease(w.has_lease);
    auto lease_job = w.has_lease ? jobs_.find(w.lease_job) : jobs_.end();
    if (lease_job != jobs_.end() &&
        (caller.admin || lease_job->second->stored.job().owner() == caller.name)) {
      i->set_lease_job(w.lease_job);
      i->set_lease_tile(w.lease_tile);
    }
    i->set_threads(w.threads);
    for (const auto& [job_id, job] : jobs_) {
      auto s = job->worker_stats.find(id);
      if (s == job->worker_stats.end()) continue;
      i->set_records_computed(i->records_computed() + s->second.records_computed());
      i->set_records_received(i->records_received() + s->second.records_received());
    }
    auto h = health_.find(w.health_key);
    if (h != health_.end()) {
      i->set_consecutive_failures(uint32_t(h->second.consecutive_failures));
      if (h->second.quarantined_until > now) {
        i->set_quarantined(true);
        i->set_quarantine_seconds_left(
            std::chrono::duration<double>(h->second.quarantined_until - now).count());
      }
    }
    i->set_violations(w.violations);
    i->set_outbox_bytes(w.outbox_bytes + w.in_flight_bytes);
    i->set_batches_dropped(w.batches_dropped);
    i->set_seconds_since_heard(std::chrono::duration<double>(now - w.last_heard).count());
    i->set_silent(w.silent);
  }
  out.set_worker_violations(violations_total_);
  out.set_workers_disconnected(expelled_total_);
  return out;
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
  // At most half the job's record limit, the newest first (the latest job's records, each log
  // from its end), so that the job's own records still fit and the work done here, under the
  // lock, is bounded: every earlier job of the client was copied whole before.
  const size_t cap = size_t(std::max<int64_t>(0, options_.limits.max_job_records / 2));
  SeedSet seed;
  std::string from;
  for (auto src = sources.rbegin(); src != sources.rend() && seed.records().size() < cap; ++src) {
    const RecordLog& log = (*src)->cache->records();
    for (size_t i = log.size(); i-- > 0 && seed.records().size() < cap;) seed.Add(log[i]);
    from += (from.empty() ? "" : ",") + (*src)->stored.job().id();
  }
  std::vector<IrradianceRecord> records = seed.records();
  // Stamped like imported records: sent to every worker of the job when it joins.
  for (IrradianceRecord& r : records) r.origin = kSnapshotOrigin;
  const std::vector<IrradianceRecord> merged = job.cache->Merge(records);
  j->set_records_seeded(merged.size());
  j->set_seeded_from(from);
  // Written in this order (records, then the job saying it was seeded), retried until stored;
  // in batches, as records are synced, so that no one store write is larger than a batch.
  for (size_t i = 0; i < merged.size(); i += options_.sync_batch_records)
    writer_->AppendRecords(
        j->id(),
        std::vector<IrradianceRecord>(
            merged.begin() + ptrdiff_t(i),
            merged.begin() + ptrdiff_t(std::min(merged.size(), i + options_.sync_batch_records))));
  writer_->PutJob(StateOnly(job.stored));
}

void JobManager::TryAssign(uint32_t worker_id, Worker& worker,
                           std::vector<v1::CoordinatorMessage>* out) {
  // Jobs with pending tiles, highest priority first, then in submission order; the first that
  // has a tile for this worker (one that did not fail on it, while others could take those).
  std::vector<Job*> candidates;
  for (auto& [id, job] : jobs_)
    if (!IsFinal(*job) && job->tiles->has_pending()) candidates.push_back(job.get());
  std::sort(candidates.begin(), candidates.end(), [](const Job* a, const Job* b) {
    if (a->stored.job().priority() != b->stored.job().priority())
      return a->stored.job().priority() > b->stored.job().priority();
    return a->stored.sequence() < b->stored.sequence();
  });
  const SteadyTime now = std::chrono::steady_clock::now();
  const std::vector<uint32_t> others = OtherEligibleWorkers(worker_id, now);
  Job* chosen = nullptr;
  std::optional<TileLeaseInfo> lease;
  for (Job* candidate : candidates) {
    // A worker holds at most kMaxWorkerJobs jobs (it ignores the spec of one more, whose leases
    // it would then fail): no new job before one of its jobs closes.
    if (worker.jobs.size() >= kMaxWorkerJobs && !worker.jobs.count(candidate->stored.job().id()))
      continue;
    // Near its previous tile of the job: its tiles, and so its region, stay together.
    const int near = worker.lease_job == candidate->stored.job().id() ? worker.lease_tile : -1;
    lease = candidate->tiles->Lease(worker_id, now, options_.lease_time, others, near);
    if (lease) {
      chosen = candidate;
      break;
    }
  }
  if (chosen == nullptr) return;
  Job& job = *chosen;
  const std::string& id = job.stored.job().id();
  if (!job.has_started) SeedCache(job);
  if (!job.workers.count(worker_id)) {
    v1::CoordinatorMessage spec;
    spec.mutable_job_spec()->set_job_id(id);
    *spec.mutable_job_spec()->mutable_scene() = job.stored.scene();
    *spec.mutable_job_spec()->mutable_settings() = job.stored.job().settings();
    spec.mutable_job_spec()->set_warm_cache(job.stored.job().records_seeded() > 0 ||
                                            job.stored.job().records_imported() > 0);
    out->push_back(std::move(spec));
    // Late join: the job's records so far (imported ones always, others' when sharing). With
    // filtered fan-out none yet: the worker's region is empty until its first TileRegion, whose
    // backlog then brings the records that reach it.
    const bool share = job.stored.job().settings().share_records();
    const bool filtered = Filtered(worker);
    // The copy is bounded like fan-out (max_outbox_bytes, less what the outbox holds): it goes
    // out with this Poll, and a worker that does not read would hold it in its stream's writer;
    // batches past the bound are dropped and counted.
    size_t withheld = 0, dropped = 0;
    const RecordLog& all = job.cache->records();
    std::vector<IrradianceRecord> chunk;
    for (size_t i = 0; i <= all.size(); ++i) {
      if (i == all.size() || chunk.size() == options_.sync_batch_records) {
        if (!chunk.empty()) {
          v1::CoordinatorMessage m;
          m.mutable_records()->set_job_id(id);
          PackRecords(chunk, kSnapshotOrigin, m.mutable_records()->mutable_batch());
          const size_t bytes = BatchBytes(m.records().batch());
          if (bytes > OutboxRoom(worker)) {
            dropped += chunk.size();
          } else {
            // Handed to the session's writer with this Poll: counted until its next Poll.
            worker.in_flight_bytes += bytes;
            total_outbox_bytes_ += bytes;
            v1::WorkerJobStats& ws = job.worker_stats[worker_id];
            ws.set_worker_id(worker_id);
            ws.set_bytes_received(ws.bytes_received() + bytes);
            metrics_.records_sent->Add(chunk.size());
            metrics_.record_bytes_sent->Add(bytes);
            CountFanout(job, worker_id, worker, chunk.size(), 0, 0);
            out->push_back(std::move(m));
          }
          chunk.clear();
        }
        if (i == all.size()) break;
      }
      if (!share && all[i].origin != kSnapshotOrigin) continue;
      if (filtered && !RecordReachesBox(all[i], Bounds3(), 1.0f)) {
        ++withheld;
        continue;
      }
      if (dropped > 0) {  // the bound was reached: the rest is dropped unpacked
        ++dropped;
        continue;
      }
      chunk.push_back(all[i]);
    }
    if (dropped > 0) {
      const size_t batches = (dropped + options_.sync_batch_records - 1) /
                             std::max<size_t>(1, options_.sync_batch_records);
      worker.batches_dropped += batches;
      metrics_.fanout_batches_dropped->Add(double(batches));
      spdlog::warn(
          "job {}: worker {} joined late; {} of the job's records past the outbox bound "
          "({} bytes) were not sent to it",
          id, worker_id, dropped, options_.limits.max_outbox_bytes);
    }
    if (withheld > 0) CountFanout(job, worker_id, worker, 0, withheld, 0);
    job.workers.insert(worker_id);
    job.index_stale = true;
    if (filtered) {
      job.tallies[worker_id] = Job::Tally{job.offered_total, 0, 0};
      CountFanout(job, worker_id, worker, 0, 0, 0);  // its stats entry, where View adds the tally
    }
    worker.jobs.insert(id);
  }
  if (!job.has_started) {
    job.has_started = true;
    job.started = std::chrono::steady_clock::now();
  }
  if (job.stored.job().state() == v1::JOB_STATE_QUEUED) {
    job.stored.mutable_job()->set_state(v1::JOB_STATE_RUNNING);
    writer_->PutJob(StateOnly(job.stored));
  }
  v1::CoordinatorMessage m;
  v1::TileLease* l = m.mutable_lease();
  l->set_job_id(id);
  l->set_tile_index(lease->tile);
  l->set_lease_token(lease->token.Bytes());
  const PixelRect& r = job.tiles->rect(lease->tile);
  l->mutable_rect()->set_x0(r.x0);
  l->mutable_rect()->set_y0(r.y0);
  l->mutable_rect()->set_x1(r.x1);
  l->mutable_rect()->set_y1(r.y1);
  const auto wall_deadline = std::chrono::system_clock::now() + options_.lease_time;
  l->set_deadline_unix_ms(
      std::chrono::duration_cast<std::chrono::milliseconds>(wall_deadline.time_since_epoch())
          .count());
  l->set_lease_ms(int64_t(options_.lease_time.count()));
  out->push_back(std::move(m));
  worker.has_lease = true;
  worker.lease_job = id;
  worker.lease = lease->token;
  worker.lease_tile = lease->tile;
  worker.lease_deadline = lease->deadline;
  worker.past_leases.emplace_back(lease->token, id);
  if (worker.past_leases.size() > kPastLeases) worker.past_leases.pop_front();
  Touched(nullptr);  // job views; the lease goes out with this Poll
}

std::vector<v1::CoordinatorMessage> JobManager::Poll(uint32_t worker,
                                                     std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mu_);
  std::vector<v1::CoordinatorMessage> out;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  // The session's writer polls only once it has written what the last Poll gave it.
  if (auto it = workers_.find(worker); it != workers_.end()) ReleaseInFlight(it->second);
  for (;;) {
    auto it = workers_.find(worker);
    if (it == workers_.end()) return out;
    Worker& w = it->second;
    const std::shared_ptr<Wake> wake = w.wake;  // outlives the worker's erasure
    const uint64_t seen = wake->seq;
    const SteadyTime now = std::chrono::steady_clock::now();
    // Fan-out batching: a worker rendering a tile gets records only options_.fanout_linger after
    // the first of them was queued (others' batches are appended meanwhile); anything else in
    // its outbox goes at once.
    const SteadyTime linger_end = w.records_queued_at + options_.fanout_linger;
    if (!w.outbox.empty() && w.has_lease && now < linger_end && now < deadline &&
        std::all_of(w.outbox.begin(), w.outbox.end(),
                    [](const v1::CoordinatorMessage& m) { return m.has_records(); })) {
      wake->cv.wait_until(lock, std::min(deadline, linger_end), [&] { return wake->seq != seen; });
      continue;
    }
    while (!w.outbox.empty()) {
      if (w.outbox.front().has_records()) {
        // To the session's writer, which may block on a worker that does not read: counted until
        // the writer polls again (it does once all it was handed is written).
        const size_t b = std::min(w.outbox_bytes, BatchBytes(w.outbox.front().records().batch()));
        w.outbox_bytes -= b;
        w.in_flight_bytes += b;
      }
      out.push_back(std::move(w.outbox.front()));
      w.outbox.pop_front();
    }
    if (!w.has_lease && !w.draining && !w.silent && !Quarantined(w, now))
      TryAssign(worker, w, &out);
    if (!out.empty() || now >= deadline) return out;
    wake->cv.wait_until(lock, deadline, [&] { return wake->seq != seen; });
  }
}

void JobManager::ExpireLeases() {
  std::lock_guard<std::mutex> lock(mu_);
  const SteadyTime now = std::chrono::steady_clock::now();
  for (auto& [id, job] : jobs_) SettleWithheld(*job);  // Prometheus's withheld counters
  // A worker silent for 3 heartbeat periods (hung, SIGSTOPped, cut off) loses its leases now
  // rather than at the lease deadline. Not a failure of the tile: the tile did nothing wrong.
  for (auto& [wid, w] : workers_) {
    if (w.silent || now - w.last_heard <= 3 * options_.heartbeat) continue;
    w.silent = true;
    w.has_lease = false;
    // Its queued fan-out is dropped (it gets none while silent): other messages stay.
    for (auto m = w.outbox.begin(); m != w.outbox.end();) {
      if (!m->has_records()) {
        ++m;
        continue;
      }
      TakeOutboxBytes(w, BatchBytes(m->records().batch()));
      ++w.batches_dropped;
      metrics_.fanout_batches_dropped->Add();
      m = w.outbox.erase(m);
    }
    spdlog::warn("worker {} ({}) silent for {:.1f} s: its leases go to other workers", wid, w.name,
                 std::chrono::duration<double>(now - w.last_heard).count());
    for (auto& [id, job] : jobs_) {
      if (IsFinal(*job)) continue;
      const std::vector<uint32_t> holders = job->tiles->LeaseHolders();
      metrics_.lease_expired_silent->Add(uint64_t(std::count(holders.begin(), holders.end(), wid)));
      (void)job->tiles->ReleaseWorker(wid, "worker " + std::to_string(wid) + " went silent",
                                      /*count_failure=*/false);
    }
    Changed();
  }
  for (auto& [id, job] : jobs_) {
    if (IsFinal(*job)) continue;
    const size_t leased = job->tiles->LeaseHolders().size();
    absl::Status st = job->tiles->ExpireLeases(now);
    metrics_.lease_expired_deadline->Add(leased - job->tiles->LeaseHolders().size());
    if (!st.ok()) FinishJob(*job, v1::JOB_STATE_FAILED, std::string(st.message()));
  }
}

}  // namespace irfarm
