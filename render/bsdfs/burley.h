// Burley's (Disney) shading terms shared by `principled` and `principledthin`, in Mitsuba 3's
// forms: Schlick's weight and approximation, Mitsuba's luminance, and the tabulated directional
// albedo of the diffuse lobe (diffuse + retro-reflection, fake subsurface, sheen) that both
// report to the irradiance cache as DiffuseAlbedo. The tables are built once, on first use.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

#include "core/math.h"
#include "render/sampling.h"

namespace irfarm {

// Schlick's weight (1 - c)^5, c clamped to [0, 1].
inline float SchlickWeight(float c) {
  const float m = std::clamp(1 - c, 0.0f, 1.0f);
  return m * m * m * m * m;
}

// Mitsuba's calc_schlick: Schlick's approximation towards 1 from f0, with the transmitted
// angle's cosine when the light comes from the optically denser side (eta_it < 1).
template <typename T>
T Schlick(const T& f0, float cos_i, float eta) {
  const float eta_it = cos_i >= 0 ? eta : 1 / eta;
  float w;
  if (eta_it > 1) {
    w = SchlickWeight(std::abs(cos_i));
  } else {
    const float cos_t2 = 1 - (1 - cos_i * cos_i) / (eta_it * eta_it);
    w = SchlickWeight(std::sqrt(std::max(0.0f, cos_t2)));
  }
  return f0 * (1 - w) + T(1.0f) * w;
}

// Mitsuba's luminance of linear sRGB (its RGB variants).
inline float MitsubaLuminance(const Vec3& c) {
  return 0.212671f * c.x + 0.715160f * c.y + 0.072169f * c.z;
}

// Directional albedo of the diffuse lobe per unit weight, tabulated over cos_v. The diffuse,
// retro-reflection and fake-subsurface terms are quadratic in the roughness r, so each is
// stored as three coefficients: albedo = c0 + r c1 + r^2 c2 (all with the 1/pi of the lobe).
// Sheen's table is its integral of F(l.h) cos_l. Midpoint quadrature over the cosine-weighted
// hemisphere (64 x 64 cells): the integrands are smooth, error below 1e-3.
struct BurleyDiffuseTables {
  static constexpr int kSize = 64;
  std::array<float, kSize> dr[3], ss[3], sheen;

  BurleyDiffuseTables() {
    constexpr int kQ = 64;
    for (int k = 0; k < kSize; ++k) {
      const float mu = std::max(1e-4f, float(k) / (kSize - 1));
      const Vec3 v(std::sqrt(1 - mu * mu), 0, mu);
      const float fv = SchlickWeight(mu);
      double a[3] = {0, 0, 0}, b[3] = {0, 0, 0}, s = 0;
      for (int i = 0; i < kQ; ++i)
        for (int j = 0; j < kQ; ++j) {
          const Vec3 l = CosineHemisphere((float(i) + 0.5f) / kQ, (float(j) + 0.5f) / kQ);
          // Estimator of integral g cos_l dl: pi g (cosine-weighted samples); with the 1/pi of
          // the diffuse lobe: g.
          const float fl = SchlickWeight(l.z);
          const Vec3 h = Normalize(v + l);
          const float cd2 = Dot(h, l) * Dot(h, l);
          a[0] += (1 - 0.5f * fv) * (1 - 0.5f * fl);
          a[1] += 2 * cd2 * (fl + fv - fl * fv);
          a[2] += 4 * cd2 * cd2 * fl * fv;
          const float kk = 1.25f * (1 / (l.z + mu) - 0.5f);
          b[0] += 0.625f + kk * (1 - fl) * (1 - fv);
          b[1] += kk * cd2 * (fl * (1 - fv) + fv * (1 - fl));
          b[2] += kk * cd2 * cd2 * fl * fv;
          s += kPi * SchlickWeight(std::abs(Dot(h, l)));
        }
      for (int c = 0; c < 3; ++c) {
        dr[c][size_t(k)] = float(a[c] / (kQ * kQ));
        ss[c][size_t(k)] = float(b[c] / (kQ * kQ));
      }
      sheen[size_t(k)] = float(s / (kQ * kQ));
    }
  }

  static float Lookup(const std::array<float, kSize>& t, float mu) {
    const float x = std::clamp(mu, 0.0f, 1.0f) * (kSize - 1);
    const int i = std::min(int(x), kSize - 2);
    const float f = x - float(i);
    return t[size_t(i)] * (1 - f) + t[size_t(i) + 1] * f;
  }
};

// Immutable after its first construction (thread-safe static initialisation).
inline const BurleyDiffuseTables& BurleyTables() {
  static const BurleyDiffuseTables tables;
  return tables;
}

}  // namespace irfarm
