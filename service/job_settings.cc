// Wire settings -> RenderSettings (see job_settings.h).
#include "service/job_settings.h"

#include "render/scene_loader.h"

namespace irfarm {

absl::StatusOr<SceneDesc> LoadJobScene(const std::string& scene_path,
                                       const v1::RenderSettings& settings) {
  LoadOptions options;
  for (const auto& [name, value] : settings.defines()) options.defines[name] = value;
  return LoadSceneFile(scene_path, options);
}

int JobTileSize(const v1::RenderSettings& settings) {
  return settings.tile_size() > 0 ? settings.tile_size() : kDefaultTileSize;
}

absl::StatusOr<RenderSettings> MakeRenderSettings(const SceneDesc& desc,
                                                  const v1::RenderSettings& settings, int threads) {
  const std::string integrator = settings.integrator().empty() ? "irrcache" : settings.integrator();
  if (integrator != "irrcache" && integrator != "path")
    return absl::InvalidArgumentError("unknown integrator '" + integrator +
                                      "' (supported: irrcache, path)");
  if (settings.spp() < 0 || settings.spp() > 1 << 20)
    return absl::InvalidArgumentError("spp out of range: " + std::to_string(settings.spp()));
  if (settings.accuracy() < 0 || settings.accuracy() > 1 ||
      settings.accuracy() != settings.accuracy())
    return absl::InvalidArgumentError("accuracy must be in (0, 1]");
  if (settings.record_rays() < 0 || settings.record_rays() > 1 << 20)
    return absl::InvalidArgumentError("record_rays out of range");
  if (settings.tile_size() < 0 || settings.tile_size() > 4096 ||
      (settings.tile_size() > 0 && settings.tile_size() < 4))
    return absl::InvalidArgumentError("tile_size must be 0 (default) or in [4, 4096]");
  if (!(settings.target_error() >= 0 && settings.target_error() <= 1))
    return absl::InvalidArgumentError("target_error must be in [0, 1]");
  if (!(settings.tile_time_limit() >= 0 && settings.tile_time_limit() <= 1e6))
    return absl::InvalidArgumentError("tile_time_limit must be in [0, 1e6] seconds");
  absl::StatusOr<RenderSettings> s = SettingsForScene(desc, integrator);
  if (!s.ok()) return s.status();
  if (settings.spp() > 0) s->spp = settings.spp();
  if (settings.accuracy() > 0) s->irrcache.accuracy = settings.accuracy();
  if (settings.record_rays() > 0) {
    s->irrcache.record_rays = settings.record_rays();
    s->irrcache.balance_record_rays = false;  // the job's rays, as asked
  }
  s->seed = settings.seed();
  s->threads = threads;
  s->overture = !settings.no_overture();
  s->caustics = !settings.no_caustics();
  if (settings.target_error() > 0) {
    s->target_error = settings.target_error();
    s->adaptive = true;
  }
  s->time_limit = settings.tile_time_limit();
  s->aovs = settings.denoise();  // the tiles carry the denoiser's guides
  // Inside a job tile the renderer's own sub-tiles spread the tile over the worker's threads.
  s->tile_size = 16;
  return s;
}

}  // namespace irfarm
