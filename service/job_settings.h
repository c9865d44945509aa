// A job's wire settings (v1::RenderSettings) as the renderer's RenderRequest
// (render/render_request.h), whose one validation the `irfarm render` flags share; the coordinator
// calls MakeRenderSettings at submit (so a bad job is refused up front) and the worker before
// rendering (through PrepareRender), so both agree on what the job renders with. Only the job's
// own values (its tile grid, the per-tile time limit) are checked here.
#pragma once

#include <cstddef>
#include <string>

#include "absl/status/statusor.h"
#include "irfarm/v1/common.pb.h"
#include "render/render_request.h"
#include "render/renderer.h"
#include "render/scene_desc.h"
#include "render/scene_loader.h"

namespace irfarm {

constexpr int kDefaultTileSize = 32;
// Inside a job tile the renderer's own sub-tiles (RenderSettings::tile_size) spread the tile over
// the worker's threads.
constexpr int kJobSubTileSize = 16;
// Jobs a worker's session holds at once (each a loaded scene and cache until its JobClosed): the
// worker ignores a spec past it, and the coordinator leases it no tile of another job meanwhile.
constexpr size_t kMaxWorkerJobs = 64;

// The scene loader's options for the job: its -D defines.
LoadOptions JobLoadOptions(const v1::RenderSettings& settings);

// Loads the scene file with the job's -D defines. Errors carry the loader's "path:line: ...".
absl::StatusOr<SceneDesc> LoadJobScene(const std::string& scene_path,
                                       const v1::RenderSettings& settings);

// The request a job's tiles render with on `threads` threads (0 = all cores). INVALID_ARGUMENT
// for the job's own values out of range (tile_size, tile_time_limit); the rest is checked by
// ValidateRequest when the request is used.
absl::StatusOr<RenderRequest> JobRenderRequest(const v1::RenderSettings& settings, int threads);

// The settings to render tiles of the job with: JobRenderRequest, then SettingsFor, and the
// renderer's own sub-tiles for spreading one job tile over the worker's threads.
absl::StatusOr<RenderSettings> MakeRenderSettings(const SceneDesc& desc,
                                                  const v1::RenderSettings& settings, int threads);

// The job's tile edge in pixels (its setting, or kDefaultTileSize).
int JobTileSize(const v1::RenderSettings& settings);

}  // namespace irfarm
