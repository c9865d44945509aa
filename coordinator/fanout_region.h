// Filtered record fan-out (issue 11): which of a job's records a worker can look up, judged from
// the region its tiles see. Each worker reports, per lease, the box of its tile's first camera
// hits (v1::TileRegion, worker/tile_region.h); the coordinator keeps the union of a worker's boxes
// per job and sends it a record only when the record can reach that union: a record at p_i with
// radius R_i counts in Ward's weight only for lookups within max_accuracy * R_i of p_i
// (cache/irradiance_cache.h), so a record farther than that from every point of the box is
// never used by a first-hit lookup of those tiles. Records of level > 0 (secondary records,
// looked up at hemisphere-ray hits anywhere) always pass. Worker-sent boxes are untrusted:
// ParseTileRegion checks and clips them.
#pragma once

#include "absl/status/statusor.h"
#include "cache/irradiance_record.h"
#include "core/math.h"
#include "irfarm/v1/worker.pb.h"

namespace irfarm {

// True when record `r` can be used by a lookup at level 0 somewhere in `box` at accuracy at most
// `max_accuracy` (always for level > 0 records; never for an empty box).
bool RecordReachesBox(const IrradianceRecord& r, const Bounds3& box, float max_accuracy);
// The same from the record's position, radius and level alone.
bool ReachesBox(const Vec3& position, float radius, int level, const Bounds3& box,
                float max_accuracy);

// The box of `region`, clipped to `scene_box` (the job's RecordBounds box). INVALID_ARGUMENT
// when a coordinate is not finite, min > max on an axis, or the box misses the scene.
absl::StatusOr<Bounds3> ParseTileRegion(const v1::TileRegion& region, const Bounds3& scene_box);

}  // namespace irfarm
