// Materials of the scene subset and how light scatters off them. Directions point away from the
// surface (wo towards the viewer, wi towards the light). `n` is the shading normal of the hit as
// the geometry defines it (front side = the side it points to).
//   diffuse: Lambertian, one-sided unless twosided (from the back it is black and blocks).
//   conductor: perfect mirror, specular_reflectance; one-sided unless twosided.
//   dielectric: smooth glass, Fresnel reflection/refraction; int_ior behind the normal.
//   thindielectric: Fresnel reflection with interreflection, straight transmission.
#pragma once

#include <cmath>

#include "render/scene_desc.h"
#include "render/texture.h"

namespace irfarm {

struct Material {
  BsdfType type = BsdfType::kDiffuse;
  bool twosided = false;
  Vec3 reflectance{0.5f, 0.5f, 0.5f};
  const Texture* texture = nullptr;  // owned by the Scene
  Vec3 specular_reflectance{1, 1, 1};
  Vec3 specular_transmittance{1, 1, 1};
  float eta = 1.5f;  // int_ior / ext_ior

  bool IsDelta() const { return type != BsdfType::kDiffuse; }
  Vec3 Albedo(float u, float v) const { return texture ? texture->Eval(u, v) : reflectance; }
};

struct BsdfSample {
  Vec3 wi;
  Vec3 weight;    // f * |cos| / pdf
  float pdf = 0;  // solid-angle pdf; 0 for delta lobes
  bool delta = false;
  float eta = 1;  // relative index crossed (for Russian roulette), 1 if no refraction
};

// Fresnel reflectance of a smooth dielectric interface for |cos_i| and relative eta
// (transmitted side over incident side). Sets *cos_t (>= 0) when not total internal reflection.
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

inline Vec3 Reflect(const Vec3& wo, const Vec3& n) { return n * (2 * Dot(wo, n)) - wo; }

// Orients the shading normal for material `m` seen from wo. Returns false when the surface is
// one-sided and seen from the back: it is black there and light does not pass.
inline bool FacingNormal(const Material& m, const Vec3& n, const Vec3& wo, Vec3* nf) {
  const float c = Dot(wo, n);
  if (m.type == BsdfType::kDielectric || m.type == BsdfType::kThinDielectric || m.twosided) {
    *nf = c >= 0 ? n : -n;
    return true;
  }
  *nf = n;
  return c > 0;
}

// Samples a delta material (conductor, dielectric, thindielectric) with the random number u.
// `n` is the raw shading normal; the caller has already checked one-sidedness.
inline BsdfSample SampleDelta(const Material& m, const Vec3& n, const Vec3& wo, float u) {
  BsdfSample s;
  s.delta = true;
  const float c = Dot(wo, n);
  const Vec3 nf = c >= 0 ? n : -n;
  if (m.type == BsdfType::kConductor) {
    s.wi = Reflect(wo, nf);
    s.weight = m.specular_reflectance;
    return s;
  }
  const float eta = c >= 0 ? m.eta : 1 / m.eta;  // transmitted over incident
  float cos_t;
  const float f = FresnelDielectric(std::abs(c), eta, &cos_t);
  if (m.type == BsdfType::kThinDielectric) {
    const float r = f < 1 ? f + (1 - f) * (1 - f) * f / (1 - f * f) : 1.0f;
    if (u < r) {
      s.wi = Reflect(wo, nf);
      s.weight = m.specular_reflectance;
    } else {
      s.wi = -wo;
      s.weight = m.specular_transmittance;
    }
    return s;
  }
  if (u < f) {
    s.wi = Reflect(wo, nf);
    s.weight = m.specular_reflectance;
  } else {
    // Refraction; radiance is scaled by (eta_i / eta_t)^2 = 1 / eta^2 (solid angle compression).
    s.wi = Normalize(-wo / eta + nf * (std::abs(c) / eta - cos_t));
    s.weight = m.specular_transmittance / (eta * eta);
    s.eta = eta;
  }
  return s;
}

}  // namespace irfarm
