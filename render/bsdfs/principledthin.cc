// `principledthin`: Mitsuba 3's thin principled BSDF (Burley 2015's thin-surface model: leaves,
// paper, curtains, window panes), with Mitsuba's parameters, defaults and formulas. The surface
// has no inside: it is the same from both sides, so every term is evaluated with both directions
// turned to the viewer's side (v = the viewer, wo here; l = the light, wi here; cos_v > 0) and a
// light on the other side is a transmission. With st = spec_trans, dt = diff_trans / 2 (the
// parameter runs over [0, 2]), GGX roughness ax = max(1e-3, r^2 / a), ay = max(1e-3, r^2 a),
// a = sqrt(1 - 0.9 anisotropic), and h = normalize(v + l mirrored to v's side):
//   diffuse reflection (l on v's side): (1 - st)(1 - dt) base/pi lerp(fd + fr, fss, flatness)
//     cos_l, with principled's diffuse, retro-reflection and fake-subsurface terms (burley.h),
//     plus sheen (1 - st)(1 - dt) sheen F(l.h) lerp(1, base / lum(base), sheen_tint) cos_l;
//   diffuse transmission (l on the other side): (1 - st) dt base/pi |cos_l|;
//   specular reflection: st Ft D G / (4 cos_v), Ft = lerp(F, Schlick(tint R0(eta)), spec_tint),
//     F the dielectric Fresnel of eta at v.h;
//   thin specular transmission: st base (1 - F) D' G' / (4 cos_v), the reflection lobe mirrored
//     through the surface (a thin sheet does not bend light), D' G' GGX with the roughness scaled
//     by (0.65 eta - 0.35) (Burley 2015, figure 15); only where l, mirrored back, sees h's back
//     (Mitsuba's micro/macro surface test).
// There is no specular lobe at all unless spec_trans is given (Mitsuba evaluates them only then;
// with st = 0 they would be 0 anyway). Sampling as Mitsuba: the four lobes in proportion to
// st/2, st/2, (1 - st)(1 - dt) and (1 - st) dt times the four sampling rates; the specular
// lobes sample visible normals (the transmission one of the scaled roughness) and reflect, the
// transmission then mirrors z. A sampled specular direction the micro/macro test rejects is a
// failed sample (so Pdf, which leaves those directions out, is the density of Sample).
//
// For the irradiance cache the diffuse reflection lobe (with sheen and flatness) is
// kDiffuseReflection on both sides, DiffuseAlbedo its exact directional albedo from the tables
// principled uses. Diffuse transmission is kDiffuseTransmission, a non-diffuse lobe for the
// integrators: the cache's records hold the irradiance on one side, so the light coming through
// from the other side is path traced like the glossy lobes (sampled with kNonDiffuseLobes, with
// light sampling through Eval) instead of being cached.
#include <algorithm>
#include <cmath>
#include <iterator>

#include "absl/strings/str_cat.h"
#include "render/bsdfs/burley.h"
#include "render/bsdfs/fresnel.h"
#include "render/bsdfs/microfacet.h"
#include "render/bsdfs/registry.h"
#include "render/sampling.h"

namespace irfarm {
namespace {

class PrincipledThinBsdf final : public Bsdf {
 public:
  struct Params {
    TexturedColor base_color, roughness, anisotropic, spec_trans, spec_tint, sheen, sheen_tint,
        flatness, diff_trans, eta;
    // Mitsuba's sampling rates of the four lobes.
    float rate_spec_reflect = 1, rate_spec_trans = 1, rate_diff_reflect = 1, rate_diff_trans = 1;
    bool has_spec_trans = false;  // spec_trans given (and not 0): the specular lobes exist
    uint32_t flags = 0;
  };

  explicit PrincipledThinBsdf(const Params& p) : p_(p), tables_(BurleyTables()) {}

  uint32_t Flags() const override { return p_.flags; }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    if (wo.z == 0 || wi.z == 0) return Vec3();
    const Point pt = At(ctx);
    const Vec3 v = Front(wo, wo), l = Front(wi, wo);
    const bool reflect = l.z > 0;
    const Vec3 h = Half(v, l);
    const float cos_l = std::abs(l.z);
    Vec3 f;
    if (pt.st > 0 && (lobes & (kGlossyReflection | kGlossyTransmission))) {
      const float vh = Dot(v, h), lh = Dot(l, h);
      const float F = FresnelDielectric(vh, pt.eta);
      if ((lobes & kGlossyReflection) && reflect && vh > 0 && lh > 0) {
        const Microfacet mf = Mf(pt.ax, pt.ay);
        f += ThinFresnel(pt, F, vh) * (pt.st * mf.D(h) * mf.G(v, l, h) / (4 * v.z));
      }
      if ((lobes & kGlossyTransmission) && !reflect && vh > 0 && lh < 0) {
        const Microfacet mf = Mf(pt.tax, pt.tay);
        f += pt.base * (pt.st * (1 - F) * mf.D(h) * mf.G(v, l, h) / (4 * v.z));
      }
    }
    if ((lobes & kDiffuseReflection) && reflect && pt.st < 1 && pt.dt < 1) {
      const float w = (1 - pt.st) * (1 - pt.dt);
      const float fl = SchlickWeight(cos_l), fv = SchlickWeight(v.z);
      const float cd = Dot(h, l);
      const float rr = 2 * pt.roughness * cd * cd;
      const float fd = (1 - 0.5f * fv) * (1 - 0.5f * fl);
      float d = fd + rr * (fl + fv + fl * fv * (rr - 1));
      if (pt.flatness > 0) {
        const float fss90 = 0.5f * rr;
        const float fss = (1 + (fss90 - 1) * fl) * (1 + (fss90 - 1) * fv);
        const float fs = 1.25f * (fss * (1 / (cos_l + v.z) - 0.5f) + 0.5f);
        d = d + (fs - d) * pt.flatness;
      }
      f += pt.base * (w * cos_l * kInvPi * d);
      if (pt.sheen > 0) f += SheenColor(pt) * (pt.sheen * w * SchlickWeight(std::abs(cd)) * cos_l);
    }
    if ((lobes & kDiffuseTransmission) && !reflect && pt.st < 1 && pt.dt > 0)
      f += pt.base * ((1 - pt.st) * pt.dt * kInvPi * cos_l);
    return f;
  }

  float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    if (wo.z == 0 || wi.z == 0) return 0;
    const Point pt = At(ctx);
    const Probs pr = LobeProbs(pt, lobes);
    const Vec3 v = Front(wo, wo), l = Front(wi, wo);
    const float cos_l = std::abs(l.z);
    float pdf = 0;
    if (l.z > 0) {
      pdf += pr.diff_reflect * cos_l * kInvPi;
    } else {
      pdf += pr.diff_trans * cos_l * kInvPi;
    }
    if (pr.spec_reflect > 0 || pr.spec_trans > 0) {
      const Vec3 h = Half(v, l);
      const float vh = Dot(v, h), lh = Dot(l, h);
      // d(h)/d(l) of the reflection, for the mirrored l too: 1 / (4 |l_mirrored.h|).
      const float jac = 1 / (4 * std::abs(Dot(Vec3(l.x, l.y, cos_l), h)));
      if (l.z > 0 && vh > 0 && lh > 0 && pr.spec_reflect > 0)
        pdf += pr.spec_reflect * Mf(pt.ax, pt.ay).Pdf(v, h) * jac;
      if (l.z < 0 && vh > 0 && lh < 0 && pr.spec_trans > 0)
        pdf += pr.spec_trans * Mf(pt.tax, pt.tay).Pdf(v, h) * jac;
    }
    return pdf;
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                    uint32_t lobes) const override {
    BsdfSample s;
    if (wo.z == 0) return s;
    const Point pt = At(ctx);
    const Probs pr = LobeProbs(pt, lobes);
    const Vec3 v = Front(wo, wo);
    Vec3 l;
    if (u1 < pr.spec_reflect) {
      const Vec3 m = Mf(pt.ax, pt.ay).Sample(v, u2, u3);
      l = m * (2 * Dot(v, m)) - v;
      if (!(l.z > 0)) return s;
      s.lobe = kGlossyReflection;
    } else if (u1 < pr.spec_reflect + pr.spec_trans) {
      const Vec3 m = Mf(pt.tax, pt.tay).Sample(v, u2, u3);
      l = m * (2 * Dot(v, m)) - v;
      l.z = -l.z;                                    // straight through the sheet
      if (!(l.z < 0) || !(Dot(l, m) < 0)) return s;  // the micro/macro surface test
      s.lobe = kGlossyTransmission;
    } else if (u1 < pr.spec_reflect + pr.spec_trans + pr.diff_reflect) {
      l = CosineHemisphere(u2, u3);
      s.lobe = kDiffuseReflection;
    } else {
      if (!(pr.diff_trans > 0)) return s;
      l = -CosineHemisphere(u2, u3);
      s.lobe = kDiffuseTransmission;
    }
    s.wi = wo.z > 0 ? l : -l;
    return Weighed(ctx, wo, s, lobes);
  }

  Vec3 DiffuseAlbedo(const BsdfContext& ctx, const Vec3& wo) const override {
    if (wo.z == 0) return Vec3();
    const Point pt = At(ctx);
    if (!(pt.st < 1 && pt.dt < 1)) return Vec3();
    const float w = (1 - pt.st) * (1 - pt.dt), r = pt.roughness, mu = std::abs(wo.z);
    const auto poly = [&](const std::array<float, BurleyDiffuseTables::kSize>* t) {
      return BurleyDiffuseTables::Lookup(t[0], mu) + r * BurleyDiffuseTables::Lookup(t[1], mu) +
             r * r * BurleyDiffuseTables::Lookup(t[2], mu);
    };
    const float d = poly(tables_.dr), fs = poly(tables_.ss);
    Vec3 a = pt.base * (w * (d + (fs - d) * pt.flatness));
    if (pt.sheen > 0)
      a += SheenColor(pt) * (pt.sheen * w * BurleyDiffuseTables::Lookup(tables_.sheen, mu));
    return a;
  }

 private:
  // The parameters at one surface point.
  struct Point {
    Vec3 base;
    float roughness, st, dt, spec_tint, sheen, sheen_tint, flatness, eta;
    float ax, ay;    // GGX roughness of the specular reflection
    float tax, tay;  // and of the thin transmission (scaled roughness)
  };
  struct Probs {
    float spec_reflect = 0, spec_trans = 0, diff_reflect = 0, diff_trans = 0;  // sum 1 or 0
  };

  // w turned to the side of `viewer` (the sheet's two sides are alike).
  static Vec3 Front(const Vec3& w, const Vec3& viewer) { return viewer.z > 0 ? w : -w; }
  // The half vector of v and l mirrored to v's side (v.z > 0).
  static Vec3 Half(const Vec3& v, const Vec3& l) {
    const Vec3 h = v + Vec3(l.x, l.y, std::abs(l.z));
    return LengthSquared(h) > 0 ? Normalize(h) : Vec3(0, 0, 1);
  }
  static Microfacet Mf(float ax, float ay) { return Microfacet(MicrofacetType::kGgx, ax, ay); }

  // Mitsuba's calc_dist_params.
  static void GgxAlphas(float roughness, float anisotropic, float* ax, float* ay) {
    const float r2 = roughness * roughness;
    const float aspect = std::sqrt(std::max(0.0f, 1 - 0.9f * anisotropic));
    *ax = std::max(1e-3f, r2 / aspect);
    *ay = std::max(1e-3f, r2 * aspect);
  }

  Point At(const BsdfContext& ctx) const {
    Point pt;
    pt.base = p_.base_color.Eval(ctx);
    pt.roughness = p_.roughness.EvalScalar(ctx);
    pt.st = p_.has_spec_trans ? p_.spec_trans.EvalScalar(ctx) : 0.0f;
    pt.dt = 0.5f * p_.diff_trans.EvalScalar(ctx);
    pt.spec_tint = p_.spec_tint.EvalScalar(ctx);
    pt.sheen = p_.sheen.EvalScalar(ctx);
    pt.sheen_tint = p_.sheen_tint.EvalScalar(ctx);
    pt.flatness = p_.flatness.EvalScalar(ctx);
    pt.eta = p_.eta.EvalScalar(ctx);
    const float anisotropic = p_.anisotropic.EvalScalar(ctx);
    GgxAlphas(pt.roughness, anisotropic, &pt.ax, &pt.ay);
    GgxAlphas((0.65f * pt.eta - 0.35f) * pt.roughness, anisotropic, &pt.tax, &pt.tay);
    return pt;
  }

  // Mitsuba's thin_fresnel: the dielectric Fresnel blended towards a Schlick term tinted by
  // base_color (normalized by its luminance) by spec_tint.
  static Vec3 ThinFresnel(const Point& pt, float F, float cos_i) {
    if (!(pt.spec_tint > 0)) return Vec3(F);
    const float r0 = (pt.eta - 1) * (pt.eta - 1) / ((pt.eta + 1) * (pt.eta + 1));
    const Vec3 fs = Schlick(Tint(pt.base) * r0, cos_i, pt.eta);
    return Vec3(F) + (fs - Vec3(F)) * pt.spec_tint;
  }

  static Vec3 Tint(const Vec3& base) {
    const float lum = MitsubaLuminance(base);
    return lum > 0 ? base / lum : Vec3(1.0f);
  }
  static Vec3 SheenColor(const Point& pt) {
    if (!(pt.sheen_tint > 0)) return Vec3(1.0f);
    return Vec3(1.0f) + (Tint(pt.base) - Vec3(1.0f)) * pt.sheen_tint;
  }

  // Mitsuba's lobe probabilities with its sampling rates, restricted to `lobes`.
  Probs LobeProbs(const Point& pt, uint32_t lobes) const {
    Probs p;
    if (lobes & kGlossyReflection) p.spec_reflect = 0.5f * pt.st * p_.rate_spec_reflect;
    if (lobes & kGlossyTransmission) p.spec_trans = 0.5f * pt.st * p_.rate_spec_trans;
    if (lobes & kDiffuseReflection)
      p.diff_reflect = (1 - pt.st) * (1 - pt.dt) * p_.rate_diff_reflect;
    if (lobes & kDiffuseTransmission) p.diff_trans = (1 - pt.st) * pt.dt * p_.rate_diff_trans;
    const float total = p.spec_reflect + p.spec_trans + p.diff_reflect + p.diff_trans;
    if (!(total > 0)) return Probs();
    p.spec_reflect /= total;
    p.spec_trans /= total;
    p.diff_reflect /= total;
    p.diff_trans /= total;
    return p;
  }

  Params p_;
  const BurleyDiffuseTables& tables_;
};

// Mitsuba 3's principledthin parameters (all may be textures), their defaults and the range a
// constant value must lie in (Mitsuba documents them; outside, the lobe weights go negative).
struct ThinParam {
  const char* name;
  float def, lo, hi;
};
constexpr float kInf = 1e30f;
constexpr ThinParam kThinParams[] = {
    {"roughness", 0.5f, 0, 1}, {"anisotropic", 0, 0, 1}, {"spec_trans", 0, 0, 1},
    {"spec_tint", 0, 0, 1},    {"sheen", 0, 0, kInf},    {"sheen_tint", 0, 0, 1},
    {"flatness", 0, 0, 1},     {"diff_trans", 0, 0, 2},  {"eta", 1.5f, 1e-3f, kInf},
};
constexpr const char* kRates[] = {
    "specular_reflectance_sampling_rate", "specular_transmittance_sampling_rate",
    "diffuse_reflectance_sampling_rate", "diffuse_transmittance_sampling_rate"};

absl::Status Parse(BsdfParams& p) {
  if (absl::Status s = p.Color("base_color", Vec3(0.5f)).status(); !s.ok()) return s;
  for (const ThinParam& t : kThinParams) {
    const bool given = p.Has(t.name);
    absl::StatusOr<ColorParam> c = p.Color(t.name, Vec3(t.def));
    if (!c.ok()) return c.status();
    if (!given) {
      p.desc().colors.erase(t.name);  // BsdfDesc::Given tells Mitsuba's "has" flags apart
      continue;
    }
    if (c->texture >= 0) continue;
    for (const float x : {c->value.x, c->value.y, c->value.z}) {
      if (!(x >= t.lo && x <= t.hi)) {
        return p.Error(t.name,
                       t.hi < kInf
                           ? absl::StrCat(t.name, " must be in [", t.lo, ", ", t.hi, "], not ", x)
                           : absl::StrCat(t.name, " must be at least ", t.lo, ", not ", x));
      }
    }
  }
  for (const char* rate : kRates) {
    absl::StatusOr<float> r = p.Float(rate, 1.0f);
    if (!r.ok()) return r.status();
    if (!(*r >= 0)) return p.Error(rate, "sampling rates must be non-negative");
  }
  return absl::OkStatus();
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  PrincipledThinBsdf::Params p;
  p.base_color = ctx.Color(d.Color("base_color", Vec3(0.5f)));
  TexturedColor* const fields[] = {&p.roughness, &p.anisotropic, &p.spec_trans,
                                   &p.spec_tint, &p.sheen,       &p.sheen_tint,
                                   &p.flatness,  &p.diff_trans,  &p.eta};
  static_assert(std::size(fields) == std::size(kThinParams));
  for (size_t i = 0; i < std::size(kThinParams); ++i)
    *fields[i] = ctx.Color(d.Color(kThinParams[i].name, Vec3(kThinParams[i].def)));
  p.rate_spec_reflect = d.Float(kRates[0], 1);
  p.rate_spec_trans = d.Float(kRates[1], 1);
  p.rate_diff_reflect = d.Float(kRates[2], 1);
  p.rate_diff_trans = d.Float(kRates[3], 1);
  p.has_spec_trans = d.Given("spec_trans");
  // The lobes that can exist anywhere on the surface: a constant spec_trans 1 has no diffuse
  // lobes (the irradiance cache then places no records on it).
  const ColorParam st = d.Color("spec_trans", Vec3(0.0f)), dt = d.Color("diff_trans", Vec3(0.0f));
  const float st_mean = (st.value.x + st.value.y + st.value.z) / 3;
  const float dt_mean = (dt.value.x + dt.value.y + dt.value.z) / 3;
  const bool all_specular = p.has_spec_trans && st.texture < 0 && st_mean >= 1;
  const bool all_diff_trans = dt.texture < 0 && dt_mean >= 2;
  p.flags = kTwoSidedFlag;
  if (!all_specular && !all_diff_trans) p.flags |= kDiffuseReflection;
  if (!all_specular && d.Given("diff_trans")) p.flags |= kDiffuseTransmission;
  if (p.has_spec_trans) p.flags |= kGlossyReflection | kGlossyTransmission;
  return std::make_unique<PrincipledThinBsdf>(p);
}

}  // namespace

extern const BsdfPlugin kPrincipledThinBsdf = {"principledthin", Parse, Build};

}  // namespace irfarm
