// Fresnel reflectance of smooth interfaces: dielectric (real relative index) and conductor
// (complex index eta + i k, per RGB channel), and the hemispherical (cosine-weighted) average of
// the dielectric one that plastic's internal-scattering model needs. Unpolarized light.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/math.h"

namespace irfarm {

// Reflectance of a smooth dielectric interface for |cos_i| and relative eta (transmitted side
// over incident side). Sets *cos_t (>= 0) when not total internal reflection, else 0.
inline float FresnelDielectric(float cos_i, float eta, float* cos_t) {
  const float sin2_t = (1 - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1) {
    *cos_t = 0;
    return 1;
  }
  const float ct = std::sqrt(1 - sin2_t);
  const float rs = (cos_i - eta * ct) / (cos_i + eta * ct);
  const float rp = (eta * cos_i - ct) / (eta * cos_i + ct);
  *cos_t = ct;
  return 0.5f * (rs * rs + rp * rp);
}

inline float FresnelDielectric(float cos_i, float eta) {
  float cos_t;
  return FresnelDielectric(std::abs(cos_i), eta, &cos_t);
}

// Reflectance of a conductor with complex relative index eta + i k for one channel, cos_i in
// [0, 1] (the exact unpolarized formula, e.g. Born & Wolf; pbrt's FrConductor).
inline float FresnelConductor1(float cos_i, float eta, float k) {
  const float c2 = cos_i * cos_i, s2 = 1 - c2, s4 = s2 * s2;
  const float t1 = eta * eta - k * k - s2;
  const float a2pb2 = std::sqrt(std::max(0.0f, t1 * t1 + 4 * eta * eta * k * k));
  const float a = std::sqrt(std::max(0.0f, 0.5f * (a2pb2 + t1)));
  const float t2 = a2pb2 + c2, t3 = 2 * cos_i * a;
  const float rs = (t2 - t3) / (t2 + t3);
  const float t4 = a2pb2 * c2 + s4, t5 = t3 * s2;
  const float rp = rs * (t4 - t5) / (t4 + t5);
  return 0.5f * (rs + rp);
}

inline Vec3 FresnelConductor(float cos_i, const Vec3& eta, const Vec3& k) {
  const float c = std::clamp(std::abs(cos_i), 0.0f, 1.0f);
  return Vec3(FresnelConductor1(c, eta.x, k.x), FresnelConductor1(c, eta.y, k.y),
              FresnelConductor1(c, eta.z, k.z));
}

// Cosine-weighted hemispherical average of FresnelDielectric(cos, eta) (the integral of
// F(mu) 2 mu dmu over [0, 1]) by the polynomial fits Mitsuba 3's plastic uses
// (fresnel_diffuse_reflectance): Egan and Hilgeman (1973) for eta < 1, d'Eon and Irving (2011)
// otherwise. Within 0.1-0.6% of the integral for eta in 1-2, their comments say, and 3% off at
// diamond's 2.42, where matching Mitsuba's images is what counts.
inline float DiffuseFresnelReflectance(float eta) {
  const float inv_eta = 1 / eta;
  if (eta < 1) return 0.0636f * inv_eta + (eta * (eta * -1.4399f + 0.7099f) + 0.6681f);
  const float c[6] = {0.919317f, -3.4793f, 6.75335f, -7.80989f, 4.98554f, -1.36881f};
  float r = c[5];
  for (int i = 4; i >= 0; --i) r = r * inv_eta + c[i];
  return r;
}

}  // namespace irfarm
