// `diffuse`: Lambertian reflection, reflectance rgb or bitmap (default 0.5). One-sided: black
// when seen from the back (wo.z <= 0) unless wrapped in `twosided`.
#include "render/bsdfs/registry.h"
#include "render/sampling.h"

namespace irfarm {
namespace {

class DiffuseBsdf final : public Bsdf {
 public:
  explicit DiffuseBsdf(const TexturedColor& reflectance) : reflectance_(reflectance) {}

  uint32_t Flags() const override { return kDiffuseReflection; }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    if (!(lobes & kDiffuseReflection) || wo.z <= 0 || wi.z <= 0) return Vec3();
    return reflectance_.Eval(ctx) * (wi.z * kInvPi);
  }

  float Pdf(const BsdfContext&, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    if (!(lobes & kDiffuseReflection) || wo.z <= 0 || wi.z <= 0) return 0;
    return wi.z * kInvPi;
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float /*u1*/, float u2, float u3,
                    uint32_t lobes) const override {
    BsdfSample s;
    if (!(lobes & kDiffuseReflection) || wo.z <= 0) return s;
    s.wi = CosineHemisphere(u2, u3);
    s.pdf = s.wi.z * kInvPi;
    if (!(s.pdf > 0)) return s;
    s.weight = reflectance_.Eval(ctx);
    s.lobe = kDiffuseReflection;
    return s;
  }

  Vec3 DiffuseAlbedo(const BsdfContext& ctx, const Vec3& wo) const override {
    return wo.z > 0 ? reflectance_.Eval(ctx) : Vec3();
  }

 private:
  TexturedColor reflectance_;
};

absl::Status Parse(BsdfParams& p) { return p.Color("reflectance", Vec3(0.5f)).status(); }

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<DiffuseBsdf>(ctx.Color(d.Color("reflectance", Vec3(0.5f))));
}

}  // namespace

extern const BsdfPlugin kDiffuseBsdf = {"diffuse", Parse, Build};

}  // namespace irfarm
