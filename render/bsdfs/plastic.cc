// `plastic`: Mitsuba 3's smooth plastic. A smooth dielectric coating (relative index eta) over a
// diffuse base, with the light that the coating reflects back down scattered again (Mitsuba's
// internal-scattering model):
//   specular: mirror reflection with weight F(cos_o) * specular_reflectance (delta lobe);
//   diffuse:  f cos = Base * (1 - F(cos_o)) (1 - F(cos_i)) cos_i / (pi eta^2),
// Base from plastic_params.h with internal = the hemispherical average of F for light inside
// (index 1 / eta). One-sided. Lobes are sampled in proportion to F(cos_o) specular_weight and
// (1 - F(cos_o)) (1 - specular_weight), as Mitsuba does.
// For the irradiance cache, the diffuse lobe's albedo takes (1 - F(cos_i)) as its
// cosine-weighted average 1 - Fdr(eta) (exact for uniform incident light).
#include "render/bsdfs/fresnel.h"
#include "render/bsdfs/plastic_params.h"
#include "render/sampling.h"

namespace irfarm {
namespace {

class PlasticBsdf final : public Bsdf {
 public:
  explicit PlasticBsdf(const PlasticParams& p)
      : p_(p),
        inv_eta2_(1 / (p.eta * p.eta)),
        fdr_int_(DiffuseFresnelReflectance(1 / p.eta)),
        fdr_ext_(DiffuseFresnelReflectance(p.eta)) {}

  uint32_t Flags() const override { return kDeltaReflection | kDiffuseReflection; }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    if (!(lobes & kDiffuseReflection) || wo.z <= 0 || wi.z <= 0) return Vec3();
    const float fo = FresnelDielectric(wo.z, p_.eta), fi = FresnelDielectric(wi.z, p_.eta);
    return p_.Base(ctx, fdr_int_) * (inv_eta2_ * (1 - fo) * (1 - fi) * wi.z * kInvPi);
  }

  float Pdf(const BsdfContext&, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    if (!(lobes & kDiffuseReflection) || wo.z <= 0 || wi.z <= 0) return 0;
    return (1 - ProbSpecular(wo, lobes)) * wi.z * kInvPi;
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                    uint32_t lobes) const override {
    BsdfSample s;
    if (wo.z <= 0 || !(lobes & (kDiffuseReflection | kDeltaReflection))) return s;
    const float fo = FresnelDielectric(wo.z, p_.eta);
    const float ps = ProbSpecular(wo, lobes);
    if (u1 < ps) {
      s.wi = ReflectZ(wo);
      s.lobe = kDeltaReflection;
      s.weight = p_.specular.Eval(ctx) * (fo / ps);
      s.delta_prob = ps;
      return s;
    }
    s.wi = CosineHemisphere(u2, u3);
    if (s.wi.z <= 0) return s;
    const float fi = FresnelDielectric(s.wi.z, p_.eta);
    s.pdf = (1 - ps) * s.wi.z * kInvPi;
    s.lobe = kDiffuseReflection;
    s.weight = p_.Base(ctx, fdr_int_) * (inv_eta2_ * (1 - fo) * (1 - fi) / (1 - ps));
    return s;
  }

  Vec3 DiffuseAlbedo(const BsdfContext& ctx, const Vec3& wo) const override {
    if (wo.z <= 0) return Vec3();
    const float fo = FresnelDielectric(wo.z, p_.eta);
    return p_.Base(ctx, fdr_int_) * (inv_eta2_ * (1 - fo) * (1 - fdr_ext_));
  }

 private:
  float ProbSpecular(const Vec3& wo, uint32_t lobes) const {
    if (!(lobes & kDiffuseReflection)) return 1;
    if (!(lobes & kDeltaReflection)) return 0;
    const float fo = FresnelDielectric(wo.z, p_.eta);
    const float s = fo * p_.specular_weight, d = (1 - fo) * (1 - p_.specular_weight);
    return s + d > 0 ? s / (s + d) : 0;
  }

  PlasticParams p_;
  float inv_eta2_, fdr_int_, fdr_ext_;
};

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<PlasticBsdf>(PlasticParams(d, ctx));
}

}  // namespace

extern const BsdfPlugin kPlasticBsdf = {"plastic", ParsePlasticParams, Build};

}  // namespace irfarm
