// A hash of what irradiance records depend on in a scene: geometry, materials, lights and the
// integrator's path depth, but not the sensor (records do not depend on the view, so frames of
// a camera move share it). Snapshots carry it so a cache is only loaded into its own scene.
#pragma once

#include <cstdint>

#include "render/scene_desc.h"

namespace irfarm {

uint64_t SceneHash(const SceneDesc& desc);

// What a snapshot's records were computed for: the scene (SceneHash) and the settings that change
// what a record holds. With the photon map on (caustics, the default) records leave caustics out;
// with direct_sun (the default) they leave an environment map's sun to direct light. A cache made
// with one of these off and loaded with it on counts that light twice (or the reverse, not at
// all). The defaults give SceneHash itself (snapshots of default jobs made before this check
// still load, unless the scene has image files or an environment map: SceneHash covers their
// bytes and the map's rotation since 2026-12-07).
uint64_t CacheHash(uint64_t scene_hash, bool caustics, bool direct_sun);

}  // namespace irfarm
