// Four floats processed side by side: SSE2 where the compiler targets it (every x86-64), a plain
// loop over the lanes elsewhere. The same operations either way (SSE does not fuse multiply-adds,
// and its sqrt and division are correctly rounded as the scalar ones are), so both builds give
// the same bits. Masks are Float4s whose lanes are all ones (true) or all zeros (false), as SSE's
// comparisons make them.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace irfarm {

struct Float4 {
#if defined(__SSE2__)
  __m128 v;
  Float4() : v(_mm_setzero_ps()) {}
  explicit Float4(__m128 x) : v(x) {}
  explicit Float4(float x) : v(_mm_set1_ps(x)) {}
  static Float4 Load(const float* p) { return Float4(_mm_loadu_ps(p)); }
  void Store(float* p) const { _mm_storeu_ps(p, v); }
#else
  float v[4];
  Float4() : v{0, 0, 0, 0} {}
  explicit Float4(float x) : v{x, x, x, x} {}
  static Float4 Load(const float* p) {
    Float4 r;
    for (int k = 0; k < 4; ++k) r.v[k] = p[k];
    return r;
  }
  void Store(float* p) const {
    for (int k = 0; k < 4; ++k) p[k] = v[k];
  }
#endif
};

#if defined(__SSE2__)
inline Float4 operator+(Float4 a, Float4 b) { return Float4(_mm_add_ps(a.v, b.v)); }
inline Float4 operator-(Float4 a, Float4 b) { return Float4(_mm_sub_ps(a.v, b.v)); }
inline Float4 operator*(Float4 a, Float4 b) { return Float4(_mm_mul_ps(a.v, b.v)); }
inline Float4 operator/(Float4 a, Float4 b) { return Float4(_mm_div_ps(a.v, b.v)); }
inline Float4 Sqrt(Float4 a) { return Float4(_mm_sqrt_ps(a.v)); }
inline Float4 Min(Float4 a, Float4 b) { return Float4(_mm_min_ps(a.v, b.v)); }
inline Float4 Max(Float4 a, Float4 b) { return Float4(_mm_max_ps(a.v, b.v)); }
inline Float4 Abs(Float4 a) {
  return Float4(_mm_and_ps(a.v, _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff))));
}
// Comparisons (false where either side is NaN).
inline Float4 operator<=(Float4 a, Float4 b) { return Float4(_mm_cmple_ps(a.v, b.v)); }
inline Float4 operator>=(Float4 a, Float4 b) { return Float4(_mm_cmpge_ps(a.v, b.v)); }
inline Float4 operator>(Float4 a, Float4 b) { return Float4(_mm_cmpgt_ps(a.v, b.v)); }
inline Float4 operator&(Float4 a, Float4 b) { return Float4(_mm_and_ps(a.v, b.v)); }
inline Float4 operator|(Float4 a, Float4 b) { return Float4(_mm_or_ps(a.v, b.v)); }
// Lanes of `mask` take a, the others b.
inline Float4 Select(Float4 mask, Float4 a, Float4 b) {
  return Float4(_mm_or_ps(_mm_and_ps(mask.v, a.v), _mm_andnot_ps(mask.v, b.v)));
}
#else
namespace float4_detail {
template <typename F>
inline Float4 Map(Float4 a, Float4 b, F f) {
  Float4 r;
  for (int k = 0; k < 4; ++k) r.v[k] = f(a.v[k], b.v[k]);
  return r;
}
inline float Mask(bool on) {
  const uint32_t bits = on ? 0xffffffffu : 0u;
  float f;
  std::memcpy(&f, &bits, sizeof(f));
  return f;
}
inline uint32_t Bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof(u));
  return u;
}
inline float FromBits(uint32_t u) {
  float f;
  std::memcpy(&f, &u, sizeof(f));
  return f;
}
}  // namespace float4_detail
inline Float4 operator+(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return x + y; });
}
inline Float4 operator-(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return x - y; });
}
inline Float4 operator*(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return x * y; });
}
inline Float4 operator/(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return x / y; });
}
inline Float4 Sqrt(Float4 a) {
  return float4_detail::Map(a, a, [](float x, float) { return std::sqrt(x); });
}
// As SSE's minps and maxps: the second operand where either is NaN.
inline Float4 Min(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return x < y ? x : y; });
}
inline Float4 Max(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return x > y ? x : y; });
}
inline Float4 Abs(Float4 a) {
  return float4_detail::Map(a, a, [](float x, float) { return std::fabs(x); });
}
inline Float4 operator<=(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return float4_detail::Mask(x <= y); });
}
inline Float4 operator>=(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return float4_detail::Mask(x >= y); });
}
inline Float4 operator>(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) { return float4_detail::Mask(x > y); });
}
inline Float4 operator&(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) {
    return float4_detail::FromBits(float4_detail::Bits(x) & float4_detail::Bits(y));
  });
}
inline Float4 operator|(Float4 a, Float4 b) {
  return float4_detail::Map(a, b, [](float x, float y) {
    return float4_detail::FromBits(float4_detail::Bits(x) | float4_detail::Bits(y));
  });
}
inline Float4 Select(Float4 mask, Float4 a, Float4 b) {
  Float4 r;
  for (int k = 0; k < 4; ++k) {
    const uint32_t m = float4_detail::Bits(mask.v[k]);
    r.v[k] = float4_detail::FromBits((m & float4_detail::Bits(a.v[k])) |
                                     (~m & float4_detail::Bits(b.v[k])));
  }
  return r;
}
#endif

}  // namespace irfarm
