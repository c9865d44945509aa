// The render pipeline every caller shares: load (the XML and the files it names) -> settings
// (the scene's defaults and the request, validated once: render/render_request.h) -> build (the
// Embree scene and its lights). `irfarm render`, the service's workers, the benches and the tests
// call PrepareRender and then Render or RenderRect; the coordinator checks a job with the first
// two steps (LoadSceneFile, SettingsFor) without building it.
#pragma once

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "render/render_request.h"
#include "render/render_stats.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {

struct PreparedRender {
  SceneDesc desc;
  RenderSettings settings;
  std::unique_ptr<Scene> scene;
  PhaseTime load_time, build_time;  // for RenderStats::phases
};

// Loads `scene_path`, makes the settings `request` asks for, builds the scene. The first error:
// file:line for the scene (or the file it names), the setting and its range for the request.
absl::StatusOr<PreparedRender> PrepareRender(const std::string& scene_path, const LoadOptions& load,
                                             const RenderRequest& request,
                                             const SceneBuildOptions& build = {});

}  // namespace irfarm
