// `roughdielectric`: rough glass (Walter et al. 2007 as in Mitsuba 3): microfacet reflection
// and refraction through a GGX or Beckmann surface, int_ior behind the surface. With
// e = relative index (transmitted over incident, from wo's side) and m the generalized half
// vector (wo + e wi, turned to the upper hemisphere):
//   reflection:   f cos = F D G / (4 |cos_o|) * specular_reflectance
//   transmission: f cos = (1 - F) D G |wo.m| |wi.m| / (|cos_o| (wo.m + e wi.m)^2)
//                 * specular_transmittance   (radiance: Mitsuba's 1/e^2 scaling cancels e^2)
// Normals are sampled for wo mirrored into the upper hemisphere; the lobe with probability F.
#include <cmath>

#include "render/bsdfs/dielectric_params.h"
#include "render/bsdfs/fresnel.h"
#include "render/bsdfs/microfacet_params.h"

namespace irfarm {
namespace {

class RoughDielectricBsdf final : public Bsdf {
 public:
  RoughDielectricBsdf(const MicrofacetParams& dist, float eta, const TexturedColor& reflect,
                      const TexturedColor& transmit)
      : dist_(dist), eta_(eta), reflect_(reflect), transmit_(transmit) {}

  uint32_t Flags() const override { return kGlossyReflection | kGlossyTransmission; }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    Geometry g;
    if (!Setup(wo, wi, lobes, &g)) return Vec3();
    const Microfacet mf = dist_.At(ctx);
    const float d = mf.D(g.m);
    if (!(d > 0)) return Vec3();
    const float G = mf.G(Up(wo), Up(wi) * (g.reflect ? 1.0f : -1.0f), g.m);
    const float f = FresnelDielectric(g.dot_o, g.e);
    if (g.reflect) return reflect_.Eval(ctx) * (f * d * G / (4 * std::abs(wo.z)));
    const float denom = g.dot_o + g.e * g.dot_i;
    return transmit_.Eval(ctx) *
           ((1 - f) * d * G * std::abs(g.dot_o * g.dot_i) / (std::abs(wo.z) * denom * denom));
  }

  float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    Geometry g;
    if (!Setup(wo, wi, lobes, &g)) return 0;
    const Microfacet mf = dist_.At(ctx);
    const float pm = mf.Pdf(Up(wo), g.m);
    const float f = FresnelDielectric(g.dot_o, g.e);
    const bool both = (lobes & kGlossyReflection) && (lobes & kGlossyTransmission);
    if (g.reflect) return pm * (both ? f : 1.0f) / (4 * std::abs(g.dot_i));
    const float denom = g.dot_o + g.e * g.dot_i;
    return pm * (both ? 1 - f : 1.0f) * g.e * g.e * std::abs(g.dot_i) / (denom * denom);
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                    uint32_t lobes) const override {
    BsdfSample s;
    const bool has_r = (lobes & kGlossyReflection) != 0, has_t = (lobes & kGlossyTransmission) != 0;
    if ((!has_r && !has_t) || wo.z == 0) return s;
    const Microfacet mf = dist_.At(ctx);
    const Vec3 m = mf.Sample(Up(wo), u2, u3);
    const float c = Dot(wo, m);
    const float e = c > 0 ? eta_ : 1 / eta_;
    float cos_t;
    const float f = FresnelDielectric(std::abs(c), e, &cos_t);
    const bool reflect = has_r && (!has_t || u1 < f);
    if (reflect) {
      s.wi = m * (2 * c) - wo;
      s.lobe = kGlossyReflection;
    } else {
      if (f >= 1) return s;  // total internal reflection: no transmission
      const Vec3 mf_side = c > 0 ? m : -m;
      s.wi = -wo / e + mf_side * (std::abs(c) / e - cos_t);
      s.lobe = kGlossyTransmission;
      s.eta = wo.z > 0 ? eta_ : 1 / eta_;
    }
    // A reflection below the surface or a refraction that stays on wo's side is a microfacet
    // sample the macro surface does not allow: failed.
    if ((s.wi.z * wo.z > 0) != reflect) {
      s.lobe = 0;
      return s;
    }
    return Weighed(ctx, wo, s, lobes);
  }

 private:
  struct Geometry {
    bool reflect;
    float e;             // transmitted over incident index, from wo's side
    Vec3 m;              // generalized half vector, upper hemisphere
    float dot_o, dot_i;  // wo.m, wi.m
  };
  static Vec3 Up(const Vec3& w) { return w.z >= 0 ? w : -w; }

  bool Setup(const Vec3& wo, const Vec3& wi, uint32_t lobes, Geometry* g) const {
    if (wo.z == 0 || wi.z == 0) return false;
    g->reflect = wo.z * wi.z > 0;
    if (g->reflect && !(lobes & kGlossyReflection)) return false;
    if (!g->reflect && !(lobes & kGlossyTransmission)) return false;
    g->e = wo.z > 0 ? eta_ : 1 / eta_;
    Vec3 m = g->reflect ? wo + wi : wo + wi * g->e;
    if (!(LengthSquared(m) > 0)) return false;
    m = Normalize(m);
    if (m.z < 0) m = -m;
    g->m = m;
    g->dot_o = Dot(wo, m);
    g->dot_i = Dot(wi, m);
    // Both directions must be on the sides of the microfacet their macro side implies.
    if (g->dot_o * wo.z <= 0 || g->dot_i * wi.z <= 0) return false;
    return true;
  }

  MicrofacetParams dist_;
  float eta_;
  TexturedColor reflect_, transmit_;
};

absl::Status Parse(BsdfParams& p) {
  if (absl::Status s = ParseMicrofacetParams(p); !s.ok()) return s;
  return ParseDielectricParams(p, /*rough=*/true);
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  const DielectricParams params(d, ctx);
  return std::make_unique<RoughDielectricBsdf>(MicrofacetParams(d, ctx), params.eta, params.reflect,
                                               params.transmit);
}

}  // namespace

extern const BsdfPlugin kRoughDielectricBsdf = {"roughdielectric", Parse, Build};

}  // namespace irfarm
