// `blendbsdf`: a linear blend of two nested BSDFs (Mitsuba 3): (1 - weight) first + weight
// second, `weight` a number or a texture read as a grey value (default 0.5), clamped to [0, 1].
// Eval, Pdf, DiffuseAlbedo and the pass-through probability blend the same way. Sample picks a
// component with probability proportional to its blend weight among the components that have a
// lobe the call allows; a smooth direction is then weighted by the blended Eval over the
// blended Pdf (so Sample's pdf is Pdf's, as MIS needs), a delta one as Mitsuba weighs it (below).
#include "render/bsdfs/registry.h"

namespace irfarm {
namespace {

class BlendBsdf final : public Bsdf {
 public:
  BlendBsdf(const TexturedColor& weight, const Bsdf* a, const Bsdf* b)
      : weight_(weight), nested_{a, b} {}

  uint32_t Flags() const override {
    const uint32_t a = nested_[0]->Flags(), b = nested_[1]->Flags();
    return ((a | b) & ~uint32_t(kTwoSidedFlag)) | (a & b & kTwoSidedFlag);
  }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    const float w = Weight(ctx);
    return nested_[0]->Eval(ctx, wo, wi, lobes) * (1 - w) +
           nested_[1]->Eval(ctx, wo, wi, lobes) * w;
  }

  float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    float p[2];
    Choice(ctx, lobes, p);
    float pdf = 0;
    for (int i = 0; i < 2; ++i)
      if (p[i] > 0) pdf += p[i] * nested_[i]->Pdf(ctx, wo, wi, lobes);
    return pdf;
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                    uint32_t lobes) const override {
    float p[2];
    const float w = Choice(ctx, lobes, p);
    if (!(p[0] + p[1] > 0)) return BsdfSample{};
    const int i = u1 < p[0] ? 0 : 1;
    const float u = std::min(i == 0 ? u1 / p[0] : (u1 - p[0]) / p[1], 0x1.fffffep-1f);
    BsdfSample s = nested_[i]->Sample(ctx, wo, u, u2, u3, lobes);
    if (IsBlack(s.weight)) return s;
    const float blend = i == 0 ? 1 - w : w;
    if (s.IsDelta()) {
      // Mitsuba's blendbsdf mixes the delta lobe's probability with the other component's
      // density (all its lobes) at the delta direction: weight (b_i f_i + b_j f_j) / (b_i P_i +
      // b_j p_j). That differs from the delta lobe alone only where the other component
      // reflects into the same direction (a diffuse with a mirror or glass): Mitsuba's images
      // are the reference, so it is done the same way; the expected value then matches
      // whatever lobes this call may sample (p[i] is this call's choice of component).
      const Bsdf& other = *nested_[1 - i];
      const Vec3 f_other = other.Eval(ctx, wo, s.wi, kAllLobes);
      const float p_other = other.Pdf(ctx, wo, s.wi, kAllLobes);
      const float denom = blend * s.delta_prob + (1 - blend) * p_other;
      if (!(denom > 0)) return BsdfSample{};
      s.weight =
          (s.weight * (blend * s.delta_prob) + f_other * (1 - blend)) * (blend / (p[i] * denom));
      s.delta_prob = denom;
      return s;
    }
    s.pdf = Pdf(ctx, wo, s.wi, lobes);
    if (!(s.pdf > 0)) return BsdfSample{};
    s.weight = Eval(ctx, wo, s.wi, lobes) / s.pdf;
    return s;
  }

  Vec3 DiffuseAlbedo(const BsdfContext& ctx, const Vec3& wo) const override {
    const float w = Weight(ctx);
    return nested_[0]->DiffuseAlbedo(ctx, wo) * (1 - w) + nested_[1]->DiffuseAlbedo(ctx, wo) * w;
  }
  Vec3 ShadingNormal(const BsdfContext& ctx, const Vec3& wo) const override {
    return nested_[nested_[0]->HasDiffuse() ? 0 : 1]->ShadingNormal(ctx, wo);
  }
  float PassThrough(const BsdfContext& ctx, float cos_theta, bool front,
                    bool delta_light) const override {
    const float w = Weight(ctx);
    return nested_[0]->PassThrough(ctx, cos_theta, front, delta_light) * (1 - w) +
           nested_[1]->PassThrough(ctx, cos_theta, front, delta_light) * w;
  }

 private:
  float Weight(const BsdfContext& ctx) const {
    return std::clamp(weight_.EvalScalar(ctx), 0.0f, 1.0f);
  }
  // The probabilities of sampling each component under `lobes`; returns the blend weight.
  float Choice(const BsdfContext& ctx, uint32_t lobes, float p[2]) const {
    const float w = Weight(ctx);
    const uint32_t allowed = lobes & ~uint32_t(kTwoSidedFlag);
    const float a = (nested_[0]->Flags() & allowed) ? 1 - w : 0.0f;
    const float b = (nested_[1]->Flags() & allowed) ? w : 0.0f;
    const float sum = a + b;
    p[0] = sum > 0 ? a / sum : 0.0f;
    p[1] = sum > 0 ? b / sum : 0.0f;
    return w;
  }
  TexturedColor weight_;
  const Bsdf* nested_[2];
};

absl::Status Parse(BsdfParams& p) {
  if (absl::Status s = p.Color("weight", Vec3(0.5f)).status(); !s.ok()) return s;
  absl::StatusOr<std::vector<int>> nested = p.NestedBsdfs();
  if (!nested.ok()) return nested.status();
  if (nested->size() != 2) return p.Error("", "blendbsdf needs exactly two nested bsdfs");
  return absl::OkStatus();
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<BlendBsdf>(ctx.Color(d.Color("weight", Vec3(0.5f))),
                                     ctx.Nested(d.nested.at(0)), ctx.Nested(d.nested.at(1)));
}

}  // namespace

extern const BsdfPlugin kBlendBsdf = {"blendbsdf", Parse, Build};

}  // namespace irfarm
