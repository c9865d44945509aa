// `principled`: Mitsuba 3's Disney-style BSDF (Burley 2012 and 2015), with Mitsuba's parameters,
// defaults and formulas, so that Blender-exported scenes render as Mitsuba renders them. With v
// the viewer (wo here) and l the light (wi here), h the (generalized) half vector turned up, GGX
// roughness ax = max(1e-3, r^2 / a), ay = max(1e-3, r^2 a), a = sqrt(1 - 0.9 anisotropic), and
// the lobe weights brdf = (1 - metallic)(1 - spec_trans), bsdf = (1 - metallic) spec_trans:
//   diffuse (front side only): brdf base/pi lerp(fd + fr, fss, flatness) cos_l
//       fd = (1 - Fv/2)(1 - Fl/2), fr = Rr (Fl + Fv + Fl Fv (Rr - 1)), Rr = 2 r (l.h)^2,
//       F(x) = (1 - x)^5 (Schlick's weight), fss Hanrahan-Krueger's flattened retro-reflection;
//     plus sheen (1 - metallic) F(l.h) lerp(1, base / lum(base), sheen_tint) cos_l (no 1/pi,
//     as Mitsuba);
//   specular reflection: Fp D G / (4 |cos_v|), Fp blending the dielectric Fresnel with Schlick
//     terms for metallic (F0 = base) and spec_tint (F0 = tint R0(eta)); from the back only
//     bsdf times the dielectric Fresnel;
//   specular transmission: sqrt(base) bsdf (1 - F) D G |v.h l.h| / (|cos_v| (v.h + e l.h)^2);
//   clearcoat (front only): clearcoat/4 Schlick(0.04) D1(h) G(0.25) cos_l with D1 Burley's GTR1
//     of roughness lerp(0.1, 0.001, clearcoat_gloss) (Mitsuba's form: no 1/(4 cos cos)).
// eta is `eta`, or from `specular` as 2 / (1 - sqrt(0.08 specular)) - 1 (not both).
// Sampling as Mitsuba: lobe groups in proportion to brdf (cosine), clearcoat/4 (GTR1 normals)
// and 1 for the GGX lobe (visible normals), which then reflects or refracts by the Fresnel
// terms at the sampled normal; these group weights do not depend on the sampled direction, so
// Pdf is the exact density of Sample. One departure: where brdf is 0 but sheen is not (a fully
// transmissive sheened surface) the cosine lobe keeps probability 0.1 sheen, so that sheen is
// still reached by BSDF sampling (Mitsuba never samples it there).
//
// For the irradiance cache the diffuse lobe (diffuse, retro-reflection, fake subsurface and
// sheen) is kDiffuseReflection; it is not Lambertian, so DiffuseAlbedo(v) is its directional
// albedo (its integral over l), exact under uniform light: the view-dependent integrals are
// tabulated once over cos_v (see BurleyDiffuseTables) as polynomials in the roughness.
#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>

#include "render/bsdfs/burley.h"
#include "render/bsdfs/fresnel.h"
#include "render/bsdfs/microfacet.h"
#include "render/bsdfs/registry.h"
#include "render/sampling.h"

namespace irfarm {
namespace {

// Relative-index Fresnel reflectance for a (signed) cosine from the outside (cos >= 0: eta,
// else 1 / eta), as Mitsuba's fresnel().
inline float FresnelSigned(float cos_i, float eta) {
  return FresnelDielectric(std::abs(cos_i), cos_i >= 0 ? eta : 1 / eta);
}

// Burley's GTR1 distribution of the clearcoat (isotropic, sampled by D cos).
struct Gtr1 {
  float a2;
  explicit Gtr1(float alpha) : a2(alpha * alpha) {}
  float D(const Vec3& m) const {
    const float c = m.z;
    const float d = (a2 - 1) / (kPi * std::log(a2) * (1 + (a2 - 1) * c * c));
    return d * c > 1e-20f ? d : 0.0f;
  }
  float Pdf(const Vec3& m) const { return m.z < 0 ? 0.0f : m.z * D(m); }
  Vec3 Sample(float u1, float u2) const {
    const float phi = 2 * kPi * u1;
    const float c2 = (1 - std::pow(a2, 1 - u2)) / (1 - a2);
    const float s = std::sqrt(std::max(0.0f, 1 - c2)), c = std::sqrt(std::max(0.0f, c2));
    return Vec3(std::cos(phi) * s, std::sin(phi) * s, c);
  }
};

// Smith's GGX masking with an isotropic alpha (the clearcoat's, fixed at 0.25 by Mitsuba).
inline float SmithGgx1(const Vec3& w, const Vec3& m, float alpha) {
  if (Dot(w, m) * w.z <= 0) return 0;
  if (w.z == 1) return 1;
  const float c2 = w.z * w.z, tan2 = (1 - c2) / c2;
  return 2 / (1 + std::sqrt(1 + alpha * alpha * tan2));
}

class PrincipledBsdf final : public Bsdf {
 public:
  struct Params {
    TexturedColor base_color, roughness, anisotropic, metallic, spec_trans, sheen, sheen_tint,
        flatness, spec_tint, clearcoat, clearcoat_gloss;
    float eta = 1.5f;
    float spec_rate = 1, clearcoat_rate = 1, diffuse_rate = 1;  // Mitsuba's sampling rates
    uint32_t flags = 0;
  };

  explicit PrincipledBsdf(const Params& p) : p_(p), tables_(BurleyTables()) {}

  uint32_t Flags() const override { return p_.flags; }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    const Point pt = At(ctx);
    Geometry g;
    if (!Setup(pt, wo, wi, &g)) return Vec3();
    Vec3 f;
    const float cos_l = std::abs(wi.z);
    if ((lobes & kGlossyReflection) && g.reflect && g.compat_r) {
      if (g.F > 0) {
        const Vec3 fp = PrincipledFresnel(pt, g.F, g.vh, g.front);
        f += fp * (g.D * g.G / (4 * std::abs(wo.z)));
      }
      if (pt.clearcoat > 0 && g.front) {
        const float fcc = Schlick(0.04f, g.vh, p_.eta);
        const float gcc = SmithGgx1(wo, g.h, 0.25f) * SmithGgx1(wi, g.h, 0.25f);
        f += Vec3(0.25f * pt.clearcoat * fcc * Gtr1(pt.cc_alpha).D(g.h) * gcc * cos_l);
      }
    }
    if ((lobes & kGlossyTransmission) && !g.reflect && g.compat_t && pt.bsdf > 0 && g.F < 1) {
      const float denom = g.vh + g.eta_path * g.lh;
      const float t =
          std::abs((1 - g.F) * g.D * g.G * g.vh * g.lh / (wo.z * denom * denom)) * pt.bsdf;
      f += Vec3(std::sqrt(pt.base.x), std::sqrt(pt.base.y), std::sqrt(pt.base.z)) * t;
    }
    if ((lobes & kDiffuseReflection) && g.reflect && g.front) {
      const float fl = SchlickWeight(cos_l), fv = SchlickWeight(wo.z);
      const float cd = Dot(g.h, wi);
      if (pt.brdf > 0) {
        const float rr = 2 * pt.roughness * cd * cd;
        const float fd = (1 - 0.5f * fv) * (1 - 0.5f * fl);
        const float fr = rr * (fl + fv + fl * fv * (rr - 1));
        float d = fd + fr;
        if (pt.flatness > 0) {
          const float fss90 = 0.5f * rr;
          const float fss = (1 + (fss90 - 1) * fl) * (1 + (fss90 - 1) * fv);
          const float fs = 1.25f * (fss * (1 / (cos_l + wo.z) - 0.5f) + 0.5f);
          d = d + (fs - d) * pt.flatness;
        }
        f += pt.base * (pt.brdf * cos_l * kInvPi * d);
      }
      if (pt.sheen > 0 && pt.metallic < 1)
        f += SheenColor(pt) * (pt.sheen * (1 - pt.metallic) * SchlickWeight(std::abs(cd)) * cos_l);
    }
    return f;
  }

  float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    const Point pt = At(ctx);
    Geometry g;
    if (!Setup(pt, wo, wi, &g)) return 0;
    const Probs pr = LobeProbs(pt, g.front, lobes);
    float pdf = 0;
    if (g.reflect && g.front && pr.diffuse > 0) pdf += pr.diffuse * std::abs(wi.z) * kInvPi;
    if (g.reflect && g.compat_r) {
      const float jac = 1 / (4 * std::abs(g.lh));
      if (pr.spec > 0)
        pdf += pr.spec * ReflectProb(pt, g.F, g.front, lobes) * Mf(pt).Pdf(Up(wo), g.h) * jac;
      if (pr.clearcoat > 0) pdf += pr.clearcoat * Gtr1(pt.cc_alpha).Pdf(g.h) * jac;
    }
    if (!g.reflect && g.compat_t && pr.spec > 0) {
      const float denom = g.vh + g.eta_path * g.lh;
      const float jac = std::abs(g.eta_path * g.eta_path * g.lh / (denom * denom));
      pdf += pr.spec * (1 - ReflectProb(pt, g.F, g.front, lobes)) * Mf(pt).Pdf(Up(wo), g.h) * jac;
    }
    return pdf;
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                    uint32_t lobes) const override {
    BsdfSample s;
    if (wo.z == 0) return s;
    const Point pt = At(ctx);
    const bool front = wo.z > 0;
    const Probs pr = LobeProbs(pt, front, lobes);
    if (u1 < pr.diffuse) {
      s.wi = CosineHemisphere(u2, u3);
      s.lobe = kDiffuseReflection;
    } else if (u1 < pr.diffuse + pr.clearcoat) {
      const Vec3 m = Gtr1(pt.cc_alpha).Sample(u2, u3);
      s.wi = m * (2 * Dot(wo, m)) - wo;
      s.lobe = kGlossyReflection;
    } else {
      if (!(pr.spec > 0)) return s;
      // u1 rescaled to [0, 1) within the specular group decides reflection or refraction.
      const float u = std::min((u1 - pr.diffuse - pr.clearcoat) / pr.spec, 0x1.fffffep-1f);
      const Vec3 m = Mf(pt).Sample(Up(wo), u2, u3);
      const float c = Dot(wo, m);
      const float e = c >= 0 ? p_.eta : 1 / p_.eta;
      float cos_t;
      const float F = FresnelDielectric(std::abs(c), e, &cos_t);
      if (u < ReflectProb(pt, F, front, lobes)) {
        s.wi = m * (2 * c) - wo;
        s.lobe = kGlossyReflection;
      } else {
        if (F >= 1) return s;  // total internal reflection: no refraction
        const Vec3 m_side = c > 0 ? m : -m;
        s.wi = -wo / e + m_side * (std::abs(c) / e - cos_t);
        s.lobe = kGlossyTransmission;
        s.eta = front ? p_.eta : 1 / p_.eta;
      }
    }
    const bool want_reflect = s.lobe != kGlossyTransmission;
    if (s.wi.z == 0 || ((s.wi.z * wo.z > 0) != want_reflect)) {
      s.lobe = 0;
      return s;
    }
    return Weighed(ctx, wo, s, lobes);
  }

  Vec3 DiffuseAlbedo(const BsdfContext& ctx, const Vec3& wo) const override {
    if (wo.z <= 0) return Vec3();
    const Point pt = At(ctx);
    Vec3 a;
    const float r = pt.roughness, mu = wo.z;
    if (pt.brdf > 0) {
      const auto poly = [&](const std::array<float, BurleyDiffuseTables::kSize>* t) {
        return BurleyDiffuseTables::Lookup(t[0], mu) + r * BurleyDiffuseTables::Lookup(t[1], mu) +
               r * r * BurleyDiffuseTables::Lookup(t[2], mu);
      };
      const float d = poly(tables_.dr), fs = poly(tables_.ss);
      a += pt.base * (pt.brdf * (d + (fs - d) * pt.flatness));
    }
    if (pt.sheen > 0 && pt.metallic < 1)
      a += SheenColor(pt) *
           (pt.sheen * (1 - pt.metallic) * BurleyDiffuseTables::Lookup(tables_.sheen, mu));
    return a;
  }

 private:
  // The parameters at one surface point.
  struct Point {
    Vec3 base;
    float roughness, metallic, spec_trans, sheen, sheen_tint, flatness, spec_tint, clearcoat;
    float ax, ay, cc_alpha, brdf, bsdf;
  };
  struct Geometry {
    bool reflect, front, compat_r, compat_t;
    float eta_path;  // transmitted over incident index along the path from v
    Vec3 h;          // half vector, upper hemisphere
    float vh, lh, F, D, G;
  };
  struct Probs {
    float diffuse = 0, clearcoat = 0, spec = 0;  // normalized group probabilities
  };

  static Vec3 Up(const Vec3& w) { return w.z >= 0 ? w : -w; }

  Point At(const BsdfContext& ctx) const {
    Point pt;
    pt.base = p_.base_color.Eval(ctx);
    pt.roughness = p_.roughness.EvalScalar(ctx);
    pt.metallic = p_.metallic.EvalScalar(ctx);
    pt.spec_trans = p_.spec_trans.EvalScalar(ctx);
    pt.sheen = p_.sheen.EvalScalar(ctx);
    pt.sheen_tint = p_.sheen_tint.EvalScalar(ctx);
    pt.flatness = p_.flatness.EvalScalar(ctx);
    pt.spec_tint = p_.spec_tint.EvalScalar(ctx);
    pt.clearcoat = p_.clearcoat.EvalScalar(ctx);
    const float anisotropic = p_.anisotropic.EvalScalar(ctx);
    const float r2 = pt.roughness * pt.roughness;
    const float aspect = std::sqrt(std::max(0.0f, 1 - 0.9f * anisotropic));
    pt.ax = std::max(1e-3f, r2 / aspect);
    pt.ay = std::max(1e-3f, r2 * aspect);
    pt.cc_alpha = 0.1f + (0.001f - 0.1f) * p_.clearcoat_gloss.EvalScalar(ctx);
    pt.brdf = (1 - pt.metallic) * (1 - pt.spec_trans);
    pt.bsdf = (1 - pt.metallic) * pt.spec_trans;
    return pt;
  }

  static Microfacet Mf(const Point& pt) { return Microfacet(MicrofacetType::kGgx, pt.ax, pt.ay); }

  bool Setup(const Point& pt, const Vec3& v, const Vec3& l, Geometry* g) const {
    if (v.z == 0 || l.z == 0) return false;
    g->reflect = v.z * l.z > 0;
    g->front = v.z > 0;
    g->eta_path = g->front ? p_.eta : 1 / p_.eta;
    Vec3 h = g->reflect ? v + l : v + l * g->eta_path;
    if (!(LengthSquared(h) > 0)) return false;
    h = Normalize(h);
    if (h.z < 0) h = -h;
    g->h = h;
    g->vh = Dot(v, h);
    g->lh = Dot(l, h);
    const float side = v.z > 0 ? 1.0f : -1.0f;  // h on v's side of the macro surface
    g->compat_r = g->vh * side > 0 && g->lh * side > 0;
    g->compat_t = g->vh * side > 0 && g->lh * side < 0;
    g->F = FresnelSigned(g->vh, p_.eta);
    const Microfacet mf = Mf(pt);
    g->D = mf.D(h);
    g->G = mf.G1(v, h) * mf.G1(l, h);
    return true;
  }

  // Mitsuba's principled_fresnel: from the front, the dielectric Fresnel blended with Schlick
  // terms for metallic (towards base_color) and spec_tint; from the back only bsdf F.
  Vec3 PrincipledFresnel(const Point& pt, float F, float cos_i, bool front) const {
    if (!front) return Vec3(pt.bsdf * F);
    Vec3 fs;
    if (pt.metallic > 0) fs += Schlick(pt.base, cos_i, p_.eta) * pt.metallic;
    if (pt.spec_tint > 0) {
      const float lum = MitsubaLuminance(pt.base);
      const Vec3 tint = lum > 0 ? pt.base / lum : Vec3(1.0f);
      const float eta_it = cos_i >= 0 ? p_.eta : 1 / p_.eta;
      const float r0 = (eta_it - 1) * (eta_it - 1) / ((eta_it + 1) * (eta_it + 1));
      fs += Schlick(tint * r0, cos_i, p_.eta) * ((1 - pt.metallic) * pt.spec_tint);
    }
    return Vec3((1 - pt.metallic) * (1 - pt.spec_tint) * F) + fs;
  }

  static Vec3 SheenColor(const Point& pt) {
    if (!(pt.sheen_tint > 0)) return Vec3(1.0f);
    const float lum = MitsubaLuminance(pt.base);
    const Vec3 tint = lum > 0 ? pt.base / lum : Vec3(1.0f);
    return Vec3(1.0f) + (tint - Vec3(1.0f)) * pt.sheen_tint;
  }

  // Lobe-group probabilities (Mitsuba's, with its sampling rates), restricted to `lobes`.
  Probs LobeProbs(const Point& pt, bool front, uint32_t lobes) const {
    Probs p;
    const bool refl = (lobes & kGlossyReflection) != 0, trans = (lobes & kGlossyTransmission) != 0;
    if (front) {
      if (lobes & kDiffuseReflection) {
        const bool sheen = pt.sheen > 0 && pt.metallic < 1;
        // The sheen lives in the diffuse lobe: sample it even where brdf is 0.
        p.diffuse = std::max(pt.brdf, sheen ? 0.1f * pt.sheen : 0.0f) * p_.diffuse_rate;
      }
      if (refl) p.clearcoat = 0.25f * pt.clearcoat * p_.clearcoat_rate;
      if (refl || (trans && pt.bsdf > 0)) p.spec = p_.spec_rate;
    } else if (pt.bsdf > 0 && (refl || trans)) {
      p.spec = 1;
    }
    const float total = p.diffuse + p.clearcoat + p.spec;
    if (!(total > 0)) return Probs();
    p.diffuse /= total;
    p.clearcoat /= total;
    p.spec /= total;
    return p;
  }

  // Within the GGX group: the probability of reflecting at a normal whose Fresnel is F.
  static float ReflectProb(const Point& pt, float F, bool front, uint32_t lobes) {
    const bool refl = (lobes & kGlossyReflection) != 0, trans = (lobes & kGlossyTransmission) != 0;
    if (!trans) return 1;
    if (!refl) return 0;
    return front ? 1 - pt.bsdf * (1 - F) : F;
  }

  Params p_;
  const BurleyDiffuseTables& tables_;
};

// Mitsuba 3's principled parameters that may be textures, with their defaults.
struct TexturedParam {
  const char* name;
  float def;
};
constexpr TexturedParam kScalars[] = {
    {"roughness", 0.5f}, {"anisotropic", 0.0f},     {"metallic", 0.0f}, {"spec_trans", 0.0f},
    {"sheen", 0.0f},     {"sheen_tint", 0.0f},      {"flatness", 0.0f}, {"spec_tint", 0.0f},
    {"clearcoat", 0.0f}, {"clearcoat_gloss", 0.0f},
};

absl::Status Parse(BsdfParams& p) {
  if (absl::Status s = p.Color("base_color", Vec3(0.5f)).status(); !s.ok()) return s;
  for (const TexturedParam& t : kScalars) {
    const bool given = p.Has(t.name);
    absl::StatusOr<ColorParam> c = p.Color(t.name, Vec3(t.def));
    if (!c.ok()) return c.status();
    if (!given) p.desc().colors.erase(t.name);  // BsdfDesc::Given tells Mitsuba's "has" flags apart
  }
  if (p.Has("eta") && p.Has("specular"))
    return p.Error("specular", "principled takes either eta or specular, not both");
  if (p.Has("eta")) {
    absl::StatusOr<float> eta = p.Float("eta", 1.5f);
    if (!eta.ok()) return eta.status();
    if (!(*eta > 0)) return p.Error("eta", "eta must be positive");
  } else {
    absl::StatusOr<float> spec = p.Float("specular", 0.5f);
    if (!spec.ok()) return spec.status();
    if (!(*spec >= 0 && 0.08f * *spec < 1))
      return p.Error("specular", "specular must be in [0, 12.5)");
  }
  for (const char* rate : {"main_specular_sampling_rate", "clearcoat_sampling_rate",
                           "diffuse_reflectance_sampling_rate"}) {
    absl::StatusOr<float> r = p.Float(rate, 1.0f);
    if (!r.ok()) return r.status();
    if (!(*r >= 0)) return p.Error(rate, "sampling rates must be non-negative");
  }
  return absl::OkStatus();
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  PrincipledBsdf::Params p;
  p.base_color = ctx.Color(d.Color("base_color", Vec3(0.5f)));
  TexturedColor* const fields[] = {&p.roughness, &p.anisotropic,    &p.metallic, &p.spec_trans,
                                   &p.sheen,     &p.sheen_tint,     &p.flatness, &p.spec_tint,
                                   &p.clearcoat, &p.clearcoat_gloss};
  for (size_t i = 0; i < std::size(kScalars); ++i)
    *fields[i] = ctx.Color(d.Color(kScalars[i].name, Vec3(kScalars[i].def)));
  const bool has_spec_trans = d.Given("spec_trans");
  if (d.floats.count("eta")) {
    p.eta = d.Float("eta", 1.5f);
    if (has_spec_trans && p.eta == 1) p.eta = 1.001f;  // Mitsuba: eta 1 cannot refract
  } else {
    float spec = d.Float("specular", 0.5f);
    if (has_spec_trans && spec == 0) spec = 1e-3f;
    p.eta = 2 / (1 - std::sqrt(0.08f * spec)) - 1;
  }
  p.spec_rate = d.Float("main_specular_sampling_rate", 1);
  p.clearcoat_rate = d.Float("clearcoat_sampling_rate", 1);
  p.diffuse_rate = d.Float("diffuse_reflectance_sampling_rate", 1);
  // Lobes that can exist anywhere on the surface (a constant metallic 1 has no diffuse lobe,
  // so the irradiance cache places no records on it).
  const auto constant = [&](const char* name, float def, float* value) {
    const ColorParam c = d.Color(name, Vec3(def));
    *value = (c.value.x + c.value.y + c.value.z) / 3;
    return c.texture < 0;
  };
  float metallic, spec_trans, sheen;
  const bool metal = constant("metallic", 0, &metallic) && metallic >= 1;
  const bool all_trans = constant("spec_trans", 0, &spec_trans) && spec_trans >= 1;
  const bool no_sheen = constant("sheen", 0, &sheen) && sheen <= 0;
  p.flags = kGlossyReflection;
  if (!metal && (!all_trans || !no_sheen)) p.flags |= kDiffuseReflection;
  if (!metal && has_spec_trans) p.flags |= kGlossyTransmission;
  return std::make_unique<PrincipledBsdf>(p);
}

}  // namespace

extern const BsdfPlugin kPrincipledBsdf = {"principled", Parse, Build};

}  // namespace irfarm
