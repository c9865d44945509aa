// A record's nearest occluder, as the plane through its nearest ray hit perpendicular
// to that ray, packed into 6 bytes of the cache's record (the record stays within 64 bytes):
// the direction octahedron-encoded in two 16-bit numbers, the distance as a 16-bit logarithm
// (2^-32 .. 2^32, 0.034% steps). A lookup point beyond the plane, as seen from the record, is
// behind the occluder and does not use the record (RecordWeight).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/math.h"

namespace irfarm {

struct PackedOccluder {
  uint16_t oct_u = 0, oct_v = 0;
  uint16_t log_distance = 0;  // 0: no occluder
};

namespace occluder_detail {
inline float SignNotZero(float v) { return v >= 0 ? 1.0f : -1.0f; }
constexpr float kStepsPerOctave = 1024.0f;
constexpr int kZeroOctave = 32768;
}  // namespace occluder_detail

// v: from the record to its nearest hit (direction times distance). A zero, non-finite or
// out-of-range v packs as "no occluder".
inline PackedOccluder PackOccluder(const Vec3& v) {
  using namespace occluder_detail;
  PackedOccluder p;
  const float d = Length(v);
  if (!(d > 0) || !std::isfinite(d)) return p;
  const double code = std::round(std::log2(double(d)) * kStepsPerOctave) + kZeroOctave;
  if (!(code >= 1 && code <= 65535)) return p;
  const Vec3 n = v / d;
  const float l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  float u = n.x / l1, w = n.y / l1;
  if (n.z < 0) {
    const float ou = (1 - std::abs(w)) * SignNotZero(u);
    const float ow = (1 - std::abs(u)) * SignNotZero(w);
    u = ou;
    w = ow;
  }
  const auto q = [](float s) {
    return uint16_t(std::lround(std::clamp(s * 0.5f + 0.5f, 0.0f, 1.0f) * 65535.0f));
  };
  p.oct_u = q(u);
  p.oct_v = q(w);
  p.log_distance = uint16_t(code);
  return p;
}

// The vector PackOccluder packed (zero: none).
inline Vec3 UnpackOccluder(const PackedOccluder& p) {
  using namespace occluder_detail;
  if (p.log_distance == 0) return Vec3();
  float u = p.oct_u / 65535.0f * 2 - 1, w = p.oct_v / 65535.0f * 2 - 1;
  const float z = 1 - std::abs(u) - std::abs(w);
  if (z < 0) {
    const float ou = (1 - std::abs(w)) * SignNotZero(u);
    const float ow = (1 - std::abs(u)) * SignNotZero(w);
    u = ou;
    w = ow;
  }
  const float d = std::exp2((float(p.log_distance) - kZeroOctave) / kStepsPerOctave);
  return Normalize(Vec3(u, w, z)) * d;
}

}  // namespace irfarm
