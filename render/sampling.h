// Sample warping and random numbers for the renderer: stratified cosine-weighted hemisphere
// directions for irradiance records (Ward's T x P strata), other standard warps, the power
// heuristic for multiple importance sampling, and a small deterministic PCG32 generator.
// Directions are LOCAL: z is the surface normal, x and y span the tangent plane (see MakeFrame).
// Header-only; depends on core/math.h only.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/math.h"

namespace irfarm {

// Direction in stratum (t, p) of a T x P cosine-weighted stratification, 0 <= t < T,
// 0 <= p < P, with u, v in [0, 1) placing the sample inside the stratum:
//   sin^2(theta) = (t + u) / T,  phi = 2 pi (p + v) / P.
// The cosine density cos(theta)/pi has CDF sin^2(theta) in theta, so equal steps in sin^2 are
// equal-probability strata (the lecture's theta_t = asin(sqrt((t - u)/T)), t = 1..T, is the same
// map with t shifted by one and u mirrored). With one sample per stratum the irradiance estimate
// is E = pi / (T P) * sum L.
inline Vec3 StratifiedCosineHemisphere(int t, int p, int T, int P, float u, float v) {
  const float sin2 = std::min((float(t) + u) / float(T), 1.0f);
  const float sin_theta = std::sqrt(sin2);
  const float cos_theta = std::sqrt(std::max(0.0f, 1.0f - sin2));
  const float phi = 2 * kPi * (float(p) + v) / float(P);
  return Vec3(sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta);
}

// Cosine-weighted hemisphere direction, pdf cos(theta) / pi per steradian.
inline Vec3 CosineHemisphere(float u, float v) {
  return StratifiedCosineHemisphere(0, 0, 1, 1, u, v);
}

// Uniform direction on the unit sphere, pdf 1 / (4 pi).
inline Vec3 UniformSphere(float u, float v) {
  const float z = 1 - 2 * u;
  const float r = std::sqrt(std::max(0.0f, 1 - z * z));
  const float phi = 2 * kPi * v;
  return Vec3(r * std::cos(phi), r * std::sin(phi), z);
}

// Uniform direction in the cone around +z with cos(theta) >= cos_max,
// pdf 1 / (2 pi (1 - cos_max)). Used to sample spherical lights.
inline Vec3 UniformCone(float u, float v, float cos_max) {
  const float cos_theta = (1 - u) + u * cos_max;
  const float sin_theta = std::sqrt(std::max(0.0f, 1 - cos_theta * cos_theta));
  const float phi = 2 * kPi * v;
  return Vec3(sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta);
}

// Uniform point on a triangle as barycentrics (b0, b1, 1 - b0 - b1), pdf 1 / area.
inline void UniformTriangle(float u, float v, float* b0, float* b1) {
  const float su = std::sqrt(u);
  *b0 = 1 - su;
  *b1 = v * su;
}

// Veach's power heuristic (beta = 2) weight for a sample drawn from f, with pf and pg the pdfs
// of f and g at it. Handles an infinite pf (delta distribution) and pf = pg = 0.
// A point of the unit disk, uniform, from (u, v) in [0, 1)^2 by Shirley and Chiu's concentric
// map (nearby (u, v) stay nearby, so stratified samples stay stratified).
inline void ConcentricDisk(float u, float v, float* x, float* y) {
  const float a = 2 * u - 1, b = 2 * v - 1;
  if (a == 0 && b == 0) {
    *x = *y = 0;
    return;
  }
  float r, phi;
  if (std::abs(a) > std::abs(b)) {
    r = a;
    phi = kPi / 4 * (b / a);
  } else {
    r = b;
    phi = kPi / 2 - kPi / 4 * (a / b);
  }
  *x = r * std::cos(phi);
  *y = r * std::sin(phi);
}

inline float PowerHeuristic(float pf, float pg) {
  if (std::isinf(pf)) return 1;
  const float f = pf * pf, g = pg * pg;
  return f + g > 0 ? f / (f + g) : 0;
}

// splitmix64's finalizer: a bijective 64-bit mix with good avalanche.
inline uint64_t MixBits(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// Order-dependent hash of two 64-bit values, to derive per-(job, pixel, sample) RNG streams:
// HashCombine(HashCombine(job, pixel), pass).
inline uint64_t HashCombine(uint64_t a, uint64_t b) {
  return MixBits(a * 0x9E3779B97F4A7C15ull ^ MixBits(b + 0x632BE59BD9B4E019ull));
}

// PCG32 (O'Neill 2014, pcg32_random_r / pcg32_srandom_r): 64-bit LCG state, 32-bit XSH-RR
// output, 2^63 selectable streams. Integer-only, so identical on every platform and compiler.
class Rng {
 public:
  Rng(uint64_t seed, uint64_t stream) : state_(0), inc_((stream << 1u) | 1u) {
    NextU32();
    state_ += seed;
    NextU32();
  }

  uint32_t NextU32() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ull + inc_;
    const uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
    const uint32_t rot = uint32_t(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
  }

  // Uniform in [0, 1), never 1: see ToUnitFloat.
  float Next() { return ToUnitFloat(NextU32()); }

  // The top 24 bits scaled by 2^-24: every value is exact in a float and the largest is
  // 1 - 2^-24 < 1 (scaling all 32 bits would round 0xFFFFFFFF up to 1.0f).
  static float ToUnitFloat(uint32_t bits) { return float(bits >> 8) * 0x1p-24f; }

 private:
  uint64_t state_;
  uint64_t inc_;  // odd; selects the stream
};

}  // namespace irfarm
