// JobContext: per-job scene, settings and local cache of a worker (see job_context.h).
#include "worker/job_context.h"

#include <algorithm>

#include "absl/strings/ascii.h"

#include "render/pipeline.h"
#include "service/job_settings.h"
#include "service/scene_bundle.h"

namespace irfarm {

absl::StatusOr<std::unique_ptr<JobContext>> JobContext::Create(const v1::JobSpec& spec,
                                                               int threads) {
  // The id comes from the coordinator and names a directory: a "../" in it would put the bundle
  // elsewhere.
  const std::string& id = spec.job_id();
  if (id.empty() || id.size() > kMaxIdLength ||
      !std::all_of(
          id.begin(), id.end(),
          [](char ch) { return absl::ascii_isalnum(ch) || ch == '_' || ch == '-' || ch == '.'; }) ||
      id.find("..") != std::string::npos)
    return absl::InvalidArgumentError("job id '" + id.substr(0, kMaxIdLength) +
                                      "' is not 1-64 of [A-Za-z0-9_.-] (without '..')");
  std::unique_ptr<JobContext> c(new JobContext());
  c->job_id_ = id;
  c->tile_size_ = JobTileSize(spec.settings());
  std::string scene_path = spec.scene().path();
  if (spec.scene().has_bundle()) {
    absl::StatusOr<std::string> dir = MakeTempDir("irfarm-worker-", spec.job_id());
    if (!dir.ok()) return dir.status();
    c->dir_ = *dir;
    absl::StatusOr<std::string> main = WriteBundle(spec.scene().bundle(), c->dir_);
    if (!main.ok()) return main.status();
    scene_path = *main;
  }
  absl::StatusOr<RenderRequest> request = JobRenderRequest(spec.settings(), threads);
  if (!request.ok()) return request.status();
  absl::StatusOr<PreparedRender> prepared =
      PrepareRender(scene_path, JobLoadOptions(spec.settings()), *request);
  if (!prepared.ok()) return prepared.status();
  c->settings_ = prepared->settings;
  c->settings_.tile_size = kJobSubTileSize;
  // The coordinator spreads the fireflies over the assembled image (TileResult.peaks).
  c->settings_.keep_peaks = c->settings_.firefly_filter;
  c->settings_.firefly_filter = false;
  c->scene_ = std::move(prepared->scene);
  CausticMapStats caustic_stats;
  c->caustics_ = BuildCausticMap(*c->scene_, c->settings_, &caustic_stats);
  c->settings_.irrcache.caustics = c->caustics_.get();
  c->cache_ = std::make_unique<IrradianceCache>(CacheSettingsFor(*c->scene_, c->settings_));
  c->record_bounds_ = RecordBoundsForScene(prepared->desc);
  c->warm_ = spec.warm_cache();
  // Default rays: balanced once per job over the whole image, so every tile uses the same; a
  // seeded job keeps the settings' rays (its cache is mostly there already).
  if (c->warm_)
    c->settings_.irrcache.balance_record_rays = false;
  else
    c->settings_ = BalancedSettings(*c->scene_, c->settings_, c->cache_.get());
  return c;
}

JobContext::~JobContext() {
  if (!dir_.empty()) RemoveTree(dir_);
}

size_t JobContext::InsertRemote(const std::vector<IrradianceRecord>& records) {
  size_t n = 0;
  for (IrradianceRecord r : records) {
    if (RecordProblem(record_bounds_, r) != nullptr ||  // as the coordinator checks them
        remote_ >= kMaxRemoteRecords) {
      ++rejected_;
      continue;
    }
    if (r.origin == 0) r.origin = kUnknownRemoteOrigin;
    cache_->Insert(r);
    ++remote_;
    ++n;
  }
  received_since_ += n;
  return n;
}

std::vector<IrradianceRecord> JobContext::TakeNewOwnRecords(size_t max) {
  std::lock_guard<std::mutex> lock(publish_mu_);
  // The records inserted since the last call, newest first; own ones have origin 0. Secondary
  // records (level > 0) stay local: sharing them was measured on living-room (two workers,
  // bench_service_scaling, four alternating runs): 5-10% fewer records computed, but no shorter
  // job (the remote secondary records' neighbour clamping and denser lookups ate the gain) for
  // 2.5x the bytes sent.
  std::vector<IrradianceRecord> fresh;
  seen_mark_ = cache_->ForEachNewer(seen_mark_, [&](const IrradianceRecord& r) {
    if (r.origin == 0 && r.level == 0) fresh.push_back(r);
  });
  unpublished_.insert(unpublished_.end(), fresh.rbegin(), fresh.rend());
  const size_t take = std::min(unpublished_.size(), max);
  std::vector<IrradianceRecord> out(unpublished_.begin(),
                                    unpublished_.begin() + std::ptrdiff_t(take));
  unpublished_.erase(unpublished_.begin(), unpublished_.begin() + std::ptrdiff_t(take));
  return out;
}

}  // namespace irfarm
