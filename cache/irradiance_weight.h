// Ward's (1988) weight and validity rule for reusing an irradiance record at a shading point.
// Kept in one place so that IrradianceCache::Lookup, its brute-force twin and the tests all apply
// exactly the same rule. Everything here is scale-free: distances only ever appear divided by the
// record's radius R_i, so a scene modelled in millimetres or kilometres behaves the same.
#pragma once

#include <algorithm>
#include <cmath>

#include "cache/irradiance_record.h"
#include "core/math.h"

namespace irfarm {

// Weights are capped at kWardMaxWeight = 1e3, i.e. all epsilon values below kWardEpsilonFloor =
// 1e-3 get the same weight. This is RADIANCE's choice (old ambient code: weight 1e3 when
// e < 1e-3). It also absorbs float noise: for two unit normals that are equal up to rounding,
// 1 - dot(n, n_i) is a few 1e-7 and sqrt of it up to ~6e-4, which would otherwise make the weight
// of an "identical" record depend on rounding.
constexpr float kWardMaxWeight = 1e3f;
constexpr float kWardEpsilonFloor = 1e-3f;  // = 1 / kWardMaxWeight

// A record whose position lies in front of the shading point (on the side its hemisphere looks
// at) by more than this fraction of the validity radius a * R_i is rejected. Relative, not
// absolute, because scenes range over 1e-3..1e4 units. With 0.05, a record on a concave surface of
// curvature radius rho is still accepted when rho >= 10 * a * R_i (height of a chord of length
// a*R_i is (a*R_i)^2 / (2 rho)), while records seen across a corner are rejected. Flat surfaces
// give a dot product of ~|x| * 1e-7 (rounding), far below the tolerance for any sane record.
constexpr float kInFrontTolerance = 0.05f;

// Ward's error estimate eps_i(x, n) = |x - x_i| / R_i + sqrt(1 - n . n_i). Dimensionless.
// n must be unit length (records' normals are, see IsValidRecord).
// (The record given by its position x_i, normal n_i and radius R_i: for copies of its fields.)
inline float WardEpsilon(const Vec3& x, const Vec3& n, const Vec3& position, const Vec3& normal,
                         float radius) {
  return Length(x - position) / radius + std::sqrt(std::max(0.0f, 1.0f - Dot(n, normal)));
}
inline float WardEpsilon(const Vec3& x, const Vec3& n, const IrradianceRecord& r) {
  return WardEpsilon(x, n, r.position, r.normal, r.radius);
}

// w_i = 1 / eps_i, capped at kWardMaxWeight (also for eps = 0).
inline float WardWeight(float eps) { return std::min(1.0f / eps, kWardMaxWeight); }

// True when x_i lies in front of x, measured along the mean normal (n + n_i) / 2 (RADIANCE's
// "behind" test), beyond kInFrontTolerance * a * R_i.
// (The record given by its position x_i, normal n_i and radius R_i: for copies of its fields.)
inline bool IsInFront(const Vec3& x, const Vec3& n, float a, const Vec3& position,
                      const Vec3& normal, float radius) {
  return Dot(position - x, (n + normal) * 0.5f) > kInFrontTolerance * a * radius;
}
inline bool IsInFront(const Vec3& x, const Vec3& n, float a, const IrradianceRecord& r) {
  return IsInFront(x, n, a, r.position, r.normal, r.radius);
}

// The weight record r gets at shading point (x, n) with accuracy a in (0, 1], or 0 if it does not
// count. It counts when
//   - n . n_i > 0: the other side of a thin surface never counts (for a <= 1 this is already
//     implied by eps >= sqrt(1 - n . n_i) >= 1, but it must not hinge on a),
//   - |x - x_i| < a * R_i (implied by eps < a; tested first because it is cheap and rejects
//     most candidates of an octree lookup),
//   - eps_i < a, i.e. Ward's w_i > 1/a with the uncapped weight,
//   - x_i is not in front of x (IsInFront),
//   - x is not beyond the record's occluder plane (IrradianceRecord::occluder).
// Any a <= 0 or NaN makes nothing count.
inline float RecordWeight(const Vec3& x, const Vec3& n, float a, const IrradianceRecord& r) {
  if (!(Dot(n, r.normal) > 0)) return 0;
  const float reach = a * r.radius;
  if (!(LengthSquared(x - r.position) < reach * reach)) return 0;
  if (Dot(x - r.position, r.occluder) > LengthSquared(r.occluder)) return 0;
  const float eps = WardEpsilon(x, n, r);
  if (!(eps < a)) return 0;
  if (IsInFront(x, n, a, r)) return 0;
  return WardWeight(eps);
}

}  // namespace irfarm
