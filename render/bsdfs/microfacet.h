// Microfacet normal distributions for the rough BSDFs: GGX (Trowbridge-Reitz) and Beckmann, with
// anisotropic roughness (alpha_u along local x, alpha_v along local y), Smith's separable
// shadowing-masking G = G1(wo) G1(wi), and sampling of the normals visible from wo, with
// pdf(m) = G1(wo, m) max(0, wo.m) D(m) / wo.z:
//   GGX: Heitz 2018, "Sampling the GGX Distribution of Visible Normals";
//   Beckmann: Heitz and d'Eon 2014 (stretch to unit roughness, sample the visible slopes, rotate
//        and unstretch back). At unit roughness and incidence theta the slope across the view
//        plane is normal (y = erfinv(2u - 1)) and the slope along it has the density
//        (1 - x tan theta) exp(-x^2) on x < cot theta, whose CDF
//        C(x) = sqrt(pi)/2 (1 + erf(x)) + tan(theta)/2 exp(-x^2) is inverted by safeguarded
//        Newton iterations in x on [-4, min(cot theta, 4)] (the mass outside is ~1e-7), in
//        single precision (core/erf.h), from a start fitted in b = erf(x) in the form of Jakob
//        2014 ("An Improved Visible Normal Sampling Routine for the Beckmann Distribution").
// G1 is Smith's: exact for GGX; for Beckmann Walter et al.'s rational fit in Eval (as Mitsuba),
// while Pdf uses the exact erf form, so that it is the sampler's density (the fit is off by up
// to ~0.4%, which a chi-square test with 10^5 samples sees).
// All directions local (z = macro-surface normal); wo must have wo.z > 0 (callers mirror it).
#pragma once

#include <algorithm>
#include <cmath>

#include "core/erf.h"
#include "core/math.h"

namespace irfarm {

enum class MicrofacetType { kBeckmann, kGgx };

class Microfacet {
 public:
  Microfacet(MicrofacetType type, float alpha_u, float alpha_v)
      : type_(type), au_(std::max(alpha_u, 1e-4f)), av_(std::max(alpha_v, 1e-4f)) {}

  MicrofacetType type() const { return type_; }

  // Distribution of normals D(m) (per steradian of m, projected: integral D(m) m.z dm = 1).
  float D(const Vec3& m) const {
    const float c2 = m.z * m.z;
    // Grazing facets (m.z below 1e-10) weigh nothing: past it c2 * c2 underflows and the
    // formulas give 0 / 0 or 0 * inf (Mitsuba zeroes them too).
    if (!(m.z > 0) || !(c2 > 1e-20f)) return 0;
    const float x = m.x / au_, y = m.y / av_;
    const float e = (x * x + y * y) / c2;  // tan^2 scaled by the roughness
    if (type_ == MicrofacetType::kBeckmann) return std::exp(-e) / (kPi * au_ * av_ * c2 * c2);
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
    // Beckmann: stretch wo to unit roughness, sample slopes there, rotate and unstretch.
    const Vec3 ws = Normalize(Vec3(au_ * wo.x, av_ * wo.y, wo.z));
    const float sin_t = std::sqrt(std::max(0.0f, ws.x * ws.x + ws.y * ws.y));
    const float cos_p = sin_t > 0 ? ws.x / sin_t : 1.0f, sin_p = sin_t > 0 ? ws.y / sin_t : 0.0f;
    float x, y;
    BeckmannVisibleSlopes(ws.z, sin_t, u1, u2, &x, &y);
    const float sx = (cos_p * x - sin_p * y) * au_, sy = (sin_p * x + cos_p * y) * av_;
    return Normalize(Vec3(-sx, -sy, 1));
  }

  // Density of Sample(wo) producing m (per steradian of m).
  float Pdf(const Vec3& wo, const Vec3& m) const {
    if (wo.z <= 0) return 0;
    const float g1 = type_ == MicrofacetType::kGgx ? G1(wo, m) : BeckmannG1Exact(wo, m);
    return g1 * std::max(0.0f, Dot(wo, m)) * D(m) / wo.z;
  }

 private:
  // Smith's Beckmann masking, exact: 1 / (1 + Lambda(a)), a = 1 / (alpha tan theta),
  // Lambda(a) = (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2, within 1e-7 with core/erf.h.
  float BeckmannG1Exact(const Vec3& w, const Vec3& m) const {
    if (Dot(w, m) * w.z <= 0) return 0;
    const float xy2 = w.x * w.x * au_ * au_ + w.y * w.y * av_ * av_;
    if (xy2 <= 0) return 1;
    const float a = std::abs(w.z) / std::sqrt(xy2);
    if (a > 9) return 1;  // Lambda < 1e-36
    const float lambda = 0.5f * (std::exp(-a * a) / (a * kSqrtPi) - Erfc(a));
    return 1 / (1 + std::max(0.0f, lambda));
  }

  // Visible slopes of the unit-roughness Beckmann surface for incidence (cos_t, sin_t), the
  // view plane being x (see the file comment): C(x) = target by safeguarded Newton steps on
  // (-4, cot theta], each one exp (C and C' share exp(-x^2), and so does erf), from a start
  // b = erf(x0) = hi - (1 + hi) (1 - u)^p(theta), p a cubic in theta fitted by least squares to
  // the exact inverse over 60 angles (the form is Jakob's; bench/fit_beckmann_start.py).
  static void BeckmannVisibleSlopes(float cos_t, float sin_t, float u1, float u2, float* x,
                                    float* y) {
    const float ua = std::clamp(u1, 1e-6f, 1 - 1e-6f);
    const float ub = std::clamp(u2, 1e-6f, 1 - 1e-6f);
    *y = ErfInv(2 * ub - 1);
    if (!(sin_t > 1e-4f)) {  // normal incidence: both slopes normal
      *x = ErfInv(2 * ua - 1);
      return;
    }
    const float tan_t = sin_t / cos_t, cot_t = cos_t / sin_t;
    // C(x) / (sqrt(pi) / 2) = 1 + erf(x) + tan(theta) / sqrt(pi) exp(-x^2), with its e = exp(-x^2).
    const float k = tan_t / kSqrtPi;
    const auto cdf = [k](float v, float e) {
      const float erfc_abs = ScaledErfc(std::abs(v)) * e;
      return (v >= 0 ? 2 - erfc_abs : erfc_abs) + k * e;
    };
    float lo = -4, hi = std::min(cot_t, 4.0f);
    const float e_hi = std::exp(-hi * hi), erf_hi = 1 - ScaledErfc(hi) * e_hi;
    const float total = cdf(hi, e_hi), target = ua * total;
    const float theta = std::atan2(sin_t, cos_t);
    const float p =
        1.01692885f + theta * (-0.9451713f + theta * (0.49495843f - 0.08252777f * theta));
    float v = std::clamp(ErfInv(std::clamp(erf_hi - (1 + erf_hi) * std::exp(p * std::log(1 - ua)),
                                           -1 + 1e-7f, 1 - 1e-7f)),
                         lo, hi);
    for (int i = 0; i < 24; ++i) {
      const float e = std::exp(-v * v);
      const float f = cdf(v, e) - target;
      if (std::abs(f) < 1e-5f * total) break;
      (f > 0 ? hi : lo) = v;
      // dC/dx / (sqrt(pi) / 2) = 2 / sqrt(pi) (1 - x tan(theta)) exp(-x^2).
      const float d = 2 / kSqrtPi * (1 - v * tan_t) * e;
      float next = d > 0 ? v - f / d : 0.5f * (lo + hi);
      if (!(next > lo && next < hi)) next = 0.5f * (lo + hi);
      v = next;
    }
    *x = v;
  }

  MicrofacetType type_;
  float au_, av_;
};

}  // namespace irfarm
