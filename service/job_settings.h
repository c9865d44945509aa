// Turns a job's wire settings (v1::RenderSettings) into the renderer's RenderSettings for a
// loaded scene, checking every value; the coordinator calls it at submit (so a bad job is refused
// up front) and the worker before rendering, so both agree on what the job renders with.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "irfarm/v1/common.pb.h"
#include "render/renderer.h"
#include "render/scene_desc.h"

namespace irfarm {

constexpr int kDefaultTileSize = 32;

// Loads the scene file with the job's -D defines. Errors carry the loader's "path:line: ...".
absl::StatusOr<SceneDesc> LoadJobScene(const std::string& scene_path,
                                       const v1::RenderSettings& settings);

// The settings to render tiles of the job with `threads` threads (0 = all cores); RenderSettings
// tile_size is the job's tile edge. INVALID_ARGUMENT for out-of-range values.
absl::StatusOr<RenderSettings> MakeRenderSettings(const SceneDesc& desc,
                                                  const v1::RenderSettings& settings, int threads);

// The job's tile edge in pixels (its setting, or kDefaultTileSize).
int JobTileSize(const v1::RenderSettings& settings);

}  // namespace irfarm
