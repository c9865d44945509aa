// Region test and region validation of the filtered fan-out (see fanout_region.h).
#include "coordinator/fanout_region.h"

#include <algorithm>
#include <cmath>

namespace irfarm {

bool RecordReachesBox(const IrradianceRecord& r, const Bounds3& box, float max_accuracy) {
  return ReachesBox(r.position, r.radius, r.level, box, max_accuracy);
}

bool ReachesBox(const Vec3& position, float radius, int level, const Bounds3& box,
                float max_accuracy) {
  if (level > 0) return true;
  if (box.Empty()) return false;
  // Squared distance from p_i to the box (0 inside), against (a_max R_i)^2, in double so that
  // scenes at large coordinates do not lose the comparison to rounding.
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double p = position[k];
    const double d = std::max({double(box.lo[k]) - p, 0.0, p - double(box.hi[k])});
    d2 += d * d;
  }
  const double reach = double(max_accuracy) * double(radius);
  // 1e-6 relative slack: the worker's box and the record come from float arithmetic.
  return d2 <= reach * reach * (1 + 1e-6);
}

absl::StatusOr<Bounds3> ParseTileRegion(const v1::TileRegion& region, const Bounds3& scene_box) {
  const float v[6] = {region.min_x(), region.min_y(), region.min_z(),
                      region.max_x(), region.max_y(), region.max_z()};
  for (float f : v)
    if (!std::isfinite(f)) return absl::InvalidArgumentError("tile region: coordinate not finite");
  Bounds3 b;
  b.lo = Vec3(v[0], v[1], v[2]);
  b.hi = Vec3(v[3], v[4], v[5]);
  if (b.Empty()) return absl::InvalidArgumentError("tile region: min > max");
  b.lo = Max(b.lo, scene_box.lo);
  b.hi = Min(b.hi, scene_box.hi);
  if (b.Empty()) return absl::InvalidArgumentError("tile region: outside the scene's bounds");
  return b;
}

}  // namespace irfarm
