// `conductor`: a smooth metal, Fresnel reflectance of the complex index eta + i k (RGB, or a
// named Mitsuba material; "none" = reflectance 1) times specular_reflectance. One-sided.
#include "render/bsdfs/conductor_params.h"
#include "render/bsdfs/fresnel.h"

namespace irfarm {
namespace {

class ConductorBsdf final : public Bsdf {
 public:
  ConductorBsdf(bool mirror, const Vec3& eta, const Vec3& k, const TexturedColor& specular)
      : mirror_(mirror), eta_(eta), k_(k), specular_(specular) {}

  uint32_t Flags() const override { return kDeltaReflection; }
  Vec3 Eval(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override {
    return Vec3();
  }
  float Pdf(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override { return 0; }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float, float, float,
                    uint32_t lobes) const override {
    BsdfSample s;
    if (!(lobes & kDeltaReflection) || wo.z <= 0) return s;
    s.wi = ReflectZ(wo);
    s.lobe = kDeltaReflection;
    s.weight = specular_.Eval(ctx);
    if (!mirror_) s.weight *= FresnelConductor(wo.z, eta_, k_);
    return s;
  }

 private:
  bool mirror_;
  Vec3 eta_, k_;
  TexturedColor specular_;
};

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<ConductorBsdf>(d.Float("mirror", 1) != 0, d.Color("eta", Vec3()).value,
                                         d.Color("k", Vec3()).value,
                                         ctx.Color(d.Color("specular_reflectance", Vec3(1.0f))));
}

}  // namespace

extern const BsdfPlugin kConductorBsdf = {"conductor", ParseConductorParams, Build};

}  // namespace irfarm
