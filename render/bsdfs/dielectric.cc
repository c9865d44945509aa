// `dielectric`: smooth glass. Fresnel reflection and refraction, int_ior behind the surface
// (wo.z < 0 is inside), ext_ior in front. Refracted radiance is scaled by 1 / eta^2 (solid
// angle compression), as Mitsuba 3 does for radiance. The lobe is chosen with probability F.
#include <cmath>

#include "render/bsdfs/dielectric_params.h"
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

absl::Status Parse(BsdfParams& p) { return ParseDielectricParams(p); }

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  const DielectricParams params(d, ctx);
  return std::make_unique<DielectricBsdf>(params.eta, params.reflect, params.transmit);
}

}  // namespace

extern const BsdfPlugin kDielectricBsdf = {"dielectric", Parse, Build};

}  // namespace irfarm
