// `roughconductor`: a rough metal, Cook-Torrance microfacet reflection with GGX or Beckmann
// normals (microfacet.h), conductor Fresnel of eta + i k (RGB or a named material, see
// conductor_params.h), Smith shadowing; f cos = F D G / (4 cos_o) * specular_reflectance.
// Single scattering, like Mitsuba 3 (energy is lost at high roughness). One-sided.
#include "render/bsdfs/conductor_params.h"
#include "render/bsdfs/fresnel.h"
#include "render/bsdfs/microfacet_params.h"

namespace irfarm {
namespace {

class RoughConductorBsdf final : public Bsdf {
 public:
  RoughConductorBsdf(const MicrofacetParams& dist, bool mirror, const Vec3& eta, const Vec3& k,
                     const TexturedColor& specular)
      : dist_(dist), mirror_(mirror), eta_(eta), k_(k), specular_(specular) {}

  uint32_t Flags() const override { return kGlossyReflection; }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    if (!(lobes & kGlossyReflection) || wo.z <= 0 || wi.z <= 0) return Vec3();
    const Vec3 m = Normalize(wo + wi);
    const Microfacet mf = dist_.At(ctx);
    const float d = mf.D(m);
    if (!(d > 0)) return Vec3();
    return Fresnel(Dot(wo, m)) * specular_.Eval(ctx) * (d * mf.G(wo, wi, m) / (4 * wo.z));
  }

  float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    if (!(lobes & kGlossyReflection) || wo.z <= 0 || wi.z <= 0) return 0;
    const Vec3 m = Normalize(wo + wi);
    const float dot = Dot(wo, m);
    if (dot <= 0) return 0;
    return dist_.At(ctx).Pdf(wo, m) / (4 * dot);
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float, float u2, float u3,
                    uint32_t lobes) const override {
    BsdfSample s;
    if (!(lobes & kGlossyReflection) || wo.z <= 0) return s;
    const Microfacet mf = dist_.At(ctx);
    const Vec3 m = mf.Sample(wo, u2, u3);
    const float dot = Dot(wo, m);
    if (dot <= 0) return s;
    s.wi = m * (2 * dot) - wo;
    if (s.wi.z <= 0) return s;
    s.pdf = mf.Pdf(wo, m) / (4 * dot);
    if (!(s.pdf > 0)) return s;
    s.lobe = kGlossyReflection;
    s.weight = Eval(ctx, wo, s.wi, lobes) / s.pdf;
    return s;
  }

 private:
  Vec3 Fresnel(float cos_i) const {
    return mirror_ ? Vec3(1.0f) : FresnelConductor(cos_i, eta_, k_);
  }
  MicrofacetParams dist_;
  bool mirror_;
  Vec3 eta_, k_;
  TexturedColor specular_;
};

absl::Status Parse(BsdfParams& p) {
  if (absl::Status s = ParseMicrofacetParams(p); !s.ok()) return s;
  return ParseConductorParams(p);
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<RoughConductorBsdf>(
      MicrofacetParams(d, ctx), d.Float("mirror", 1) != 0, d.Color("eta", Vec3()).value,
      d.Color("k", Vec3()).value, ctx.Color(d.Color("specular_reflectance", Vec3(1.0f))));
}

}  // namespace

extern const BsdfPlugin kRoughConductorBsdf = {"roughconductor", Parse, Build};

}  // namespace irfarm
