// Wire settings -> RenderRequest -> RenderSettings (see job_settings.h).
#include "service/job_settings.h"

namespace irfarm {

LoadOptions JobLoadOptions(const v1::RenderSettings& settings) {
  LoadOptions options;
  for (const auto& [name, value] : settings.defines()) options.defines[name] = value;
  return options;
}

absl::StatusOr<SceneDesc> LoadJobScene(const std::string& scene_path,
                                       const v1::RenderSettings& settings) {
  return LoadSceneFile(scene_path, JobLoadOptions(settings));
}

int JobTileSize(const v1::RenderSettings& settings) {
  return settings.tile_size() > 0 ? settings.tile_size() : kDefaultTileSize;
}

absl::StatusOr<RenderRequest> JobRenderRequest(const v1::RenderSettings& settings, int threads) {
  if (settings.tile_size() < 0 || settings.tile_size() > 4096 ||
      (settings.tile_size() > 0 && settings.tile_size() < 4))
    return absl::InvalidArgumentError("tile_size must be 0 (default) or in [4, 4096]");
  if (!(settings.tile_time_limit() >= 0 && settings.tile_time_limit() <= 1e6))
    return absl::InvalidArgumentError("tile_time_limit must be in [0, 1e6] seconds");
  RenderRequest r;
  r.integrator = settings.integrator();
  r.spp = settings.spp();
  r.accuracy = settings.accuracy();
  r.record_rays = settings.record_rays();
  r.seed = settings.seed();
  r.threads = threads;
  r.overture = !settings.no_overture();
  r.caustics = !settings.no_caustics();
  r.firefly_filter = !settings.no_firefly_filter();
  r.target_error = settings.target_error();
  r.time_limit = settings.tile_time_limit();
  // The tiles carry the denoiser's guides; the coordinator denoises the assembled image, so the
  // tiles themselves are rendered as for any image (splatted, the integrator as asked).
  r.aovs = settings.denoise();
  return r;
}

absl::StatusOr<RenderSettings> MakeRenderSettings(const SceneDesc& desc,
                                                  const v1::RenderSettings& settings, int threads) {
  absl::StatusOr<RenderRequest> request = JobRenderRequest(settings, threads);
  if (!request.ok()) return request.status();
  absl::StatusOr<RenderSettings> s = SettingsFor(desc, *request);
  if (!s.ok()) return s.status();
  s->tile_size = kJobSubTileSize;
  return s;
}

}  // namespace irfarm
