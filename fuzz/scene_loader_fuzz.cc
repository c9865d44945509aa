// Fuzz target: the scene XML loader (LoadSceneString) on arbitrary text, as if it were
// tests/data/scenes/cornell-box/scene.xml (so relative mesh names can reach the real meshes/).
// Any input must give a scene or a file:line error; never a crash, hang or undefined behaviour.
#include <cstddef>
#include <cstdint>
#include <string>

#include "render/scene_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string xml(reinterpret_cast<const char*>(data), size);
  const std::string path = std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml";
  absl::StatusOr<irfarm::SceneDesc> desc = irfarm::LoadSceneString(xml, path, {});
  if (!desc.ok() && desc.status().message().find(path) == std::string::npos) __builtin_trap();
  return 0;
}
