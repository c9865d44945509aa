// A hash of what irradiance records depend on in a scene: geometry, materials, lights and the
// integrator's path depth, but not the sensor (records do not depend on the view, so frames of
// a camera move share it). Snapshots carry it so a cache is only loaded into its own scene.
#pragma once

#include <cstdint>

#include "render/scene_desc.h"

namespace irfarm {

uint64_t SceneHash(const SceneDesc& desc);

}  // namespace irfarm
