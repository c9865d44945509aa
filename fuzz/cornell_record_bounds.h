// The record bounds the fuzz targets check records against: those of the cornell box test scene
// (RecordBoundsForScene), built once per process.
#pragma once

#include <string>

#include "render/record_bounds.h"
#include "render/scene_loader.h"

namespace irfarm {

inline const RecordBounds& CornellRecordBounds() {
  static const RecordBounds bounds = [] {  // built once: the harness's fixed scene
    absl::StatusOr<SceneDesc> d =
        LoadSceneFile(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml", {});
    if (!d.ok()) __builtin_trap();
    return RecordBoundsForScene(*d);
  }();
  return bounds;
}

}  // namespace irfarm
