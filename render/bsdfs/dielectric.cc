// `dielectric`: smooth glass. Fresnel reflection and refraction, int_ior behind the surface
// (wo.z < 0 is inside), ext_ior in front. Refracted radiance is scaled by 1 / eta^2 (solid
// angle compression), as Mitsuba 3 does for radiance. The lobe is chosen with probability F.
#include <cmath>

#include "render/bsdfs/fresnel.h"
#include "render/bsdfs/registry.h"

namespace irfarm {
namespace {

class DielectricBsdf final : public Bsdf {
 public:
  DielectricBsdf(float eta, const TexturedColor& reflect, const TexturedColor& transmit)
      : eta_(eta), reflect_(reflect), transmit_(transmit) {}

  uint32_t Flags() const override { return kDeltaReflection | kDeltaTransmission; }
  Vec3 Eval(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override {
    return Vec3();
  }
  float Pdf(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override { return 0; }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float, float,
                    uint32_t lobes) const override {
    BsdfSample s;
    const float c = wo.z;
    const float eta = c >= 0 ? eta_ : 1 / eta_;  // transmitted over incident
    float cos_t;
    const float f = FresnelDielectric(std::abs(c), eta, &cos_t);
    const bool has_r = (lobes & kDeltaReflection) != 0, has_t = (lobes & kDeltaTransmission) != 0;
    if (!has_r && !has_t) return s;
    // With one lobe masked out, the other is taken always and weighted by its probability.
    const bool reflect = has_r && (!has_t || u1 < f);
    if (reflect) {
      s.wi = ReflectZ(wo);
      s.weight = reflect_.Eval(ctx) * (has_t ? 1.0f : f);
      s.lobe = kDeltaReflection;
      s.delta_prob = has_t ? f : 1.0f;
    } else {
      const float sign = c >= 0 ? 1.0f : -1.0f;
      s.wi = Normalize(-wo / eta + Vec3(0, 0, sign * (std::abs(c) / eta - cos_t)));
      s.weight = transmit_.Eval(ctx) * ((has_r ? 1.0f : 1 - f) / (eta * eta));
      s.lobe = kDeltaTransmission;
      s.delta_prob = has_r ? 1 - f : 1.0f;
      s.eta = eta;
    }
    return s;
  }

 private:
  float eta_;
  TexturedColor reflect_, transmit_;
};

absl::Status Parse(BsdfParams& p) {
  absl::StatusOr<float> int_ior = p.Ior("int_ior", 1.5046f);  // bk7
  if (!int_ior.ok()) return int_ior.status();
  absl::StatusOr<float> ext_ior = p.Ior("ext_ior", 1.000277f);  // air
  if (!ext_ior.ok()) return ext_ior.status();
  if (absl::Status s = p.Color("specular_reflectance", Vec3(1.0f)).status(); !s.ok()) return s;
  return p.Color("specular_transmittance", Vec3(1.0f)).status();
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<DielectricBsdf>(
      d.Float("int_ior", 1.5046f) / d.Float("ext_ior", 1.000277f),
      ctx.Color(d.Color("specular_reflectance", Vec3(1.0f))),
      ctx.Color(d.Color("specular_transmittance", Vec3(1.0f))));
}

}  // namespace

extern const BsdfPlugin kDielectricBsdf = {"dielectric", Parse, Build};

}  // namespace irfarm
