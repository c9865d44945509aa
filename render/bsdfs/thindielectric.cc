// `thindielectric`: a thin pane of glass. Fresnel reflection including the interreflections
// inside the pane, R' = R + (1 - R)^2 R / (1 - R^2); the rest passes straight through.
#include <cmath>

#include "render/bsdfs/fresnel.h"
#include "render/bsdfs/registry.h"

namespace irfarm {
namespace {

class ThinDielectricBsdf final : public Bsdf {
 public:
  ThinDielectricBsdf(float eta, const TexturedColor& reflect, const TexturedColor& transmit)
      : eta_(eta), reflect_(reflect), transmit_(transmit) {}

  uint32_t Flags() const override { return kDeltaReflection | kDeltaTransmission; }
  Vec3 Eval(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override {
    return Vec3();
  }
  float Pdf(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override { return 0; }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float, float,
                    uint32_t lobes) const override {
    BsdfSample s;
    const float eta = wo.z >= 0 ? eta_ : 1 / eta_;
    float cos_t;
    const float f = FresnelDielectric(std::abs(wo.z), eta, &cos_t);
    const float r = f < 1 ? f + (1 - f) * (1 - f) * f / (1 - f * f) : 1.0f;
    const bool has_r = (lobes & kDeltaReflection) != 0, has_t = (lobes & kDeltaTransmission) != 0;
    if (!has_r && !has_t) return s;
    if (has_r && (!has_t || u1 < r)) {
      s.wi = ReflectZ(wo);
      s.weight = reflect_.Eval(ctx) * (has_t ? 1.0f : r);
      s.lobe = kDeltaReflection;
      s.delta_prob = has_t ? r : 1.0f;
    } else {
      s.wi = -wo;
      s.weight = transmit_.Eval(ctx) * (has_r ? 1.0f : 1 - r);
      s.lobe = kDeltaTransmission;
      s.delta_prob = has_r ? 1 - r : 1.0f;
    }
    return s;
  }

 private:
  float eta_;
  TexturedColor reflect_, transmit_;
};

absl::Status Parse(BsdfParams& p) {
  absl::StatusOr<float> int_ior = p.Ior("int_ior", 1.5046f);
  if (!int_ior.ok()) return int_ior.status();
  absl::StatusOr<float> ext_ior = p.Ior("ext_ior", 1.000277f);
  if (!ext_ior.ok()) return ext_ior.status();
  if (absl::Status s = p.Color("specular_reflectance", Vec3(1.0f)).status(); !s.ok()) return s;
  return p.Color("specular_transmittance", Vec3(1.0f)).status();
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<ThinDielectricBsdf>(
      d.Float("int_ior", 1.5046f) / d.Float("ext_ior", 1.000277f),
      ctx.Color(d.Color("specular_reflectance", Vec3(1.0f))),
      ctx.Color(d.Color("specular_transmittance", Vec3(1.0f))));
}

}  // namespace

extern const BsdfPlugin kThinDielectricBsdf = {"thindielectric", Parse, Build};

}  // namespace irfarm
