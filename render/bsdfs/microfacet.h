// Microfacet normal distributions for the rough BSDFs: GGX (Trowbridge-Reitz) and Beckmann, with
// anisotropic roughness (alpha_u along local x, alpha_v along local y), Smith's separable
// shadowing-masking G = G1(wo) G1(wi), and normal sampling:
//   GGX: visible normals (Heitz 2018, "Sampling the GGX Distribution of Visible Normals"),
//        pdf(m) = G1(wo, m) max(0, wo.m) D(m) / wo.z;
//   Beckmann: D(m) cos(theta_m) (pdf D(m) m.z), simpler and exact; less efficient at grazing
//        wo than visible-normal sampling, which only changes noise, not the expected value.
// All directions local (z = macro-surface normal); wo must have wo.z > 0 (callers mirror it).
#pragma once

#include <algorithm>
#include <cmath>

#include "cache/math.h"

namespace irfarm {

enum class MicrofacetType { kBeckmann, kGgx };

class Microfacet {
 public:
  Microfacet(MicrofacetType type, float alpha_u, float alpha_v)
      : type_(type), au_(std::max(alpha_u, 1e-4f)), av_(std::max(alpha_v, 1e-4f)) {}

  MicrofacetType type() const { return type_; }
  bool visible_sampling() const { return type_ == MicrofacetType::kGgx; }

  // Distribution of normals D(m) (per steradian of m, projected: integral D(m) m.z dm = 1).
  float D(const Vec3& m) const {
    if (m.z <= 0) return 0;
    const float c2 = m.z * m.z;
    const float x = m.x / au_, y = m.y / av_;
    const float e = (x * x + y * y) / c2;  // tan^2 scaled by the roughness
    if (type_ == MicrofacetType::kBeckmann)
      return std::exp(-e) / (kPi * au_ * av_ * c2 * c2);
    const float t = 1 + e;
    return 1 / (kPi * au_ * av_ * c2 * c2 * t * t);
  }

  // Smith's masking of w for facets m (0 when w sees m's back).
  float G1(const Vec3& w, const Vec3& m) const {
    if (Dot(w, m) * w.z <= 0) return 0;
    const float xy2 = w.x * w.x * au_ * au_ + w.y * w.y * av_ * av_;
    if (xy2 <= 0) return 1;
    const float tan2a2 = xy2 / (w.z * w.z);  // (alpha tan theta)^2
    if (type_ == MicrofacetType::kGgx) return 2 / (1 + std::sqrt(1 + tan2a2));
    const float a = 1 / std::sqrt(tan2a2);  // Beckmann: rational fit (Walter et al. 2007)
    if (a >= 1.6f) return 1;
    return (3.535f * a + 2.181f * a * a) / (1 + 2.276f * a + 2.577f * a * a);
  }

  float G(const Vec3& wo, const Vec3& wi, const Vec3& m) const { return G1(wo, m) * G1(wi, m); }

  // Samples a normal m for viewer direction wo (wo.z > 0).
  Vec3 Sample(const Vec3& wo, float u1, float u2) const {
    if (type_ == MicrofacetType::kGgx) {
      const Vec3 vh = Normalize(Vec3(au_ * wo.x, av_ * wo.y, wo.z));
      const float len2 = vh.x * vh.x + vh.y * vh.y;
      const Vec3 t1 = len2 > 0 ? Vec3(-vh.y, vh.x, 0) / std::sqrt(len2) : Vec3(1, 0, 0);
      const Vec3 t2 = Cross(vh, t1);
      const float r = std::sqrt(u1), phi = 2 * kPi * u2;
      const float p1 = r * std::cos(phi);
      float p2 = r * std::sin(phi);
      const float s = 0.5f * (1 + vh.z);
      p2 = (1 - s) * std::sqrt(std::max(0.0f, 1 - p1 * p1)) + s * p2;
      const Vec3 nh = t1 * p1 + t2 * p2 + vh * std::sqrt(std::max(0.0f, 1 - p1 * p1 - p2 * p2));
      return Normalize(Vec3(au_ * nh.x, av_ * nh.y, std::max(1e-6f, nh.z)));
    }
    // Beckmann, D(m) cos(theta_m): phi from the anisotropic ellipse, then tan^2.
    float phi = std::atan(av_ / au_ * std::tan(2 * kPi * u2 + 0.5f * kPi));
    if (u2 > 0.5f) phi += kPi;
    const float cp = std::cos(phi), sp = std::sin(phi);
    const float inv_a2 = cp * cp / (au_ * au_) + sp * sp / (av_ * av_);
    const float tan2 = -std::log(std::max(1e-12f, 1 - u1)) / inv_a2;
    const float cos_t = 1 / std::sqrt(1 + tan2);
    const float sin_t = std::sqrt(std::max(0.0f, 1 - cos_t * cos_t));
    return Vec3(sin_t * cp, sin_t * sp, cos_t);
  }

  // Density of Sample(wo) producing m (per steradian of m).
  float Pdf(const Vec3& wo, const Vec3& m) const {
    if (type_ == MicrofacetType::kGgx) {
      if (wo.z <= 0) return 0;
      return G1(wo, m) * std::max(0.0f, Dot(wo, m)) * D(m) / wo.z;
    }
    return D(m) * std::max(0.0f, m.z);
  }

 private:
  MicrofacetType type_;
  float au_, av_;
};

}  // namespace irfarm
