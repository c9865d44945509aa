// One irradiance-cache record (Ward 1988): the indirect irradiance E at point x with normal n,
// computed from a stratified cosine-weighted hemisphere of rays, and R, the harmonic mean of
// those rays' hit distances (1/R = (1/N) sum 1/d_j), clamped by the integrator so that no record
// is infinitely large or small. Units: scene units for x and R; E in W/m^2 per RGB channel.
#pragma once

#include <cstdint>

#include "core/math.h"

namespace irfarm {

struct IrradianceRecord {
  Vec3 position;        // x_i, world space
  Vec3 normal;          // n_i, unit, facing the side of the surface the record belongs to
  Vec3 irradiance;      // E_i (RGB), indirect only
  float radius = 0;     // R_i (harmonic mean distance, clamped), > 0
  uint32_t origin = 0;  // who computed it (0 = this process; worker ids in the service)
  // Cache level (RADIANCE's ambient level): 0 = made for a camera path; 1 = a secondary record,
  // made with fewer rays for the rays of another record. A lookup at level l uses records of
  // level <= l only, so the coarser secondary records never shade what the camera sees.
  uint8_t level = 0;
  // From x_i to the nearest hit of its rays (zero: none; IrrcacheSettings::occluder_plane). A
  // lookup point beyond the plane through that hit, perpendicular to it, is behind the occluder
  // as seen from x_i and does not use the record (RecordWeight): a record next to a thin
  // partition does not reach the partition's other side. Kept in the cache in 6 bytes
  // (cache/occluder_plane.h), as 3 floats in snapshots (version 2) and on the wire
  // (RecordBatch.occluders); a record from a version-1 snapshot or from a sender without them has
  // none (its validity radius alone bounds it).
  Vec3 occluder;
};

// True when every field (the occluder too) is finite, the normal has unit length (within 1e-3), R >
// 0 and E >= 0. Records read back from disk or the wire are checked with this before use.
inline bool IsValidRecord(const IrradianceRecord& r) {
  if (!IsFinite(r.position) || !IsFinite(r.normal) || !IsFinite(r.irradiance) ||
      !IsFinite(r.occluder))
    return false;
  if (!(r.radius > 0) || !std::isfinite(r.radius)) return false;
  if (std::abs(Length(r.normal) - 1.0f) > 1e-3f) return false;
  return r.irradiance.x >= 0 && r.irradiance.y >= 0 && r.irradiance.z >= 0;
}

}  // namespace irfarm
