// Load -> settings -> build (see pipeline.h).
#include "render/pipeline.h"

namespace irfarm {

absl::StatusOr<PreparedRender> PrepareRender(const std::string& scene_path, const LoadOptions& load,
                                             const RenderRequest& request,
                                             const SceneBuildOptions& build) {
  PreparedRender p;
  PhaseTimer load_timer("load");
  absl::StatusOr<SceneDesc> desc = LoadSceneFile(scene_path, load);
  if (!desc.ok()) return desc.status();
  p.desc = *std::move(desc);
  absl::StatusOr<RenderSettings> settings = SettingsFor(p.desc, request);
  if (!settings.ok()) return settings.status();
  p.settings = *std::move(settings);
  p.load_time = load_timer.Stop();
  PhaseTimer build_timer("build");
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(p.desc, build);
  if (!scene.ok()) return scene.status();
  p.scene = *std::move(scene);
  p.build_time = build_timer.Stop();
  return p;
}

}  // namespace irfarm
