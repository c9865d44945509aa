// RecordBounds: what an irradiance record published by a worker (or imported from a snapshot)
// may contain for a given scene, beyond IsValidRecord's finite / unit-normal / R > 0 / E >= 0:
// its position inside the scene's bounds (with a margin), its radius R at most the scene's size
// and its irradiance at most a bound derived from the scene's emitters. A record outside them
// cannot come from rendering the scene and would poison the job's cache (a record with R = 1e30
// covers every lookup), so the coordinator drops it and counts the sender, a worker drops one
// that reaches it, and `irfarm render --cache-in` refuses a snapshot holding one.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "cache/irradiance_record.h"
#include "core/math.h"
#include "render/scene_desc.h"

namespace irfarm {

struct RecordBounds {
  Bounds3 box;  // positions must lie inside (already inflated by the margin)
  float max_radius = std::numeric_limits<float>::max();      // scene units
  float max_irradiance = std::numeric_limits<float>::max();  // W/m^2, per RGB channel
};

// The scene's geometric bounds (shapes only; a unit cube around the origin for an empty scene).
Bounds3 SceneShapeBounds(const SceneDesc& desc);

// Bounds for the records of `desc`:
//  - box: the shapes' bounds inflated by 1% of their diagonal (records sit on surfaces, offset
//    by at most a ray epsilon);
//  - max_radius: the diagonal of the shapes' bounds together with the camera position, times 2.
//    The integrator clamps R to the harmonic mean of hit distances (at most the longest chord
//    of the scene) or to max_spacing_px pixel footprints at the record, which for a camera
//    outside the shapes' bounds can reach the camera distance; 2x is margin;
//  - max_irradiance: see EmitterIrradianceBound.
RecordBounds RecordBoundsForScene(const SceneDesc& desc);

// An upper bound on the indirect irradiance anywhere in the scene, in W/m^2 per channel, from
// its emitters: the direct irradiance no surface can exceed, summed over emitters (an area
// emitter of radiance L filling a whole hemisphere gives pi * L; a constant environment of
// radiance L the same; a directional emitter its irradiance; a point or spot light of intensity
// I gives I / d^2, with d at least 1e-3 of the scene's diagonal), times 100: interreflection in
// a closed scene whose albedo is at most 0.99 multiplies the direct irradiance by at most
// 1 / (1 - 0.99) = 100. An environment map is not read here, so a scene with one gets no bound
// (float max): its records are then only checked for finiteness.
float EmitterIrradianceBound(const SceneDesc& desc);

// nullptr when `r` is valid (IsValidRecord) and within `b`, else why not (a static string).
const char* RecordProblem(const RecordBounds& b, const IrradianceRecord& r);

// OK when every one of `records` (a snapshot's, named `name`) is within `b`; else
// INVALID_ARGUMENT naming the first record that is not and why ("NAME: record 12: radius larger
// than the scene"). A snapshot is as untrusted as a worker: the coordinator refuses a job whose
// snapshot fails this, and `irfarm render --cache-in` such a file.
absl::Status SnapshotRecordsProblem(const RecordBounds& b,
                                    const std::vector<IrradianceRecord>& records,
                                    const std::string& name);

}  // namespace irfarm
