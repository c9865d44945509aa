// `mask`: an opacity-masked BSDF (Mitsuba 3). With probability `opacity` (rgb/float or a
// bitmap, read as a grey value, default 0.5) the nested BSDF scatters; otherwise the ray passes
// straight through (the null lobe: wi = -wo, weight 1). Eval and Pdf are opacity times the
// nested ones. Shadow rays pass through stochastically with the same probability, and through
// the nested BSDF's own pass-through where the mask is opaque (see Scene::Occluded), and the
// integrators do not count a pass-through as a scattering vertex for MIS.
#include "render/bsdfs/registry.h"

namespace irfarm {
namespace {

class MaskBsdf final : public Bsdf {
 public:
  MaskBsdf(const TexturedColor& opacity, const Bsdf* nested) : opacity_(opacity), nested_(nested) {}

  uint32_t Flags() const override { return nested_->Flags() | kNullTransmission; }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    return nested_->Eval(ctx, wo, wi, lobes) * Opacity(ctx);
  }
  float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    return nested_->Pdf(ctx, wo, wi, lobes) * Opacity(ctx);
  }
  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                    uint32_t lobes) const override {
    const float a = Opacity(ctx);
    const bool null_ok = (lobes & kNullTransmission) != 0;
    if (null_ok && u1 >= a) {  // pass through
      BsdfSample s;
      s.wi = -wo;
      s.weight = Vec3(1.0f);
      s.lobe = kNullTransmission;
      s.delta_prob = 1 - a;
      return s;
    }
    // The nested BSDF, u1 rescaled to [0, 1). Without the null lobe, weight by the opacity.
    const float u = null_ok ? (a > 0 ? u1 / a : 0.0f) : u1;
    BsdfSample s = nested_->Sample(ctx, wo, std::min(u, 0x1.fffffep-1f), u2, u3, lobes);
    s.pdf *= a;
    if (null_ok) s.delta_prob *= a;
    if (!null_ok) s.weight *= a;
    return s;
  }
  Vec3 DiffuseAlbedo(const BsdfContext& ctx, const Vec3& wo) const override {
    return nested_->DiffuseAlbedo(ctx, wo) * Opacity(ctx);
  }
  // Through the mask's hole, or through the nested BSDF where it lets light straight through
  // (Mitsuba's 1 - opacity (1 - nested)): Sample passes through the nested null lobe as well.
  float PassThrough(const BsdfContext& ctx, float cos_theta, bool front,
                    bool delta_light) const override {
    const float a = Opacity(ctx);
    return 1 - a + a * nested_->PassThrough(ctx, cos_theta, front, delta_light);
  }
  Vec3 ShadingNormal(const BsdfContext& ctx, const Vec3& wo) const override {
    return nested_->ShadingNormal(ctx, wo);
  }

 private:
  float Opacity(const BsdfContext& ctx) const {
    return std::clamp(opacity_.EvalScalar(ctx), 0.0f, 1.0f);
  }
  TexturedColor opacity_;
  const Bsdf* nested_;
};

absl::Status Parse(BsdfParams& p) {
  if (absl::Status s = p.Color("opacity", Vec3(0.5f)).status(); !s.ok()) return s;
  absl::StatusOr<std::vector<int>> nested = p.NestedBsdfs();
  if (!nested.ok()) return nested.status();
  if (nested->size() != 1) return p.Error("", "mask needs exactly one nested bsdf");
  return absl::OkStatus();
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<MaskBsdf>(ctx.Color(d.Color("opacity", Vec3(0.5f))),
                                    ctx.Nested(d.nested.at(0)));
}

}  // namespace

extern const BsdfPlugin kMaskBsdf = {"mask", Parse, Build};

}  // namespace irfarm
