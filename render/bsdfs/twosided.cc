// `twosided`: the nested BSDF on both sides (Mitsuba 3: one nested bsdf for both sides, or two,
// front then back). Seen from the back, both directions are mirrored through the surface and the
// back BSDF answers. Nested BSDFs must not transmit (Mitsuba refuses them too).
#include "absl/strings/str_cat.h"
#include "render/bsdfs/registry.h"

namespace irfarm {
namespace {

inline Vec3 FlipZ(const Vec3& w) { return Vec3(w.x, w.y, -w.z); }

class TwoSidedBsdf final : public Bsdf {
 public:
  TwoSidedBsdf(const Bsdf* front, const Bsdf* back) : front_(front), back_(back) {}

  uint32_t Flags() const override { return front_->Flags() | back_->Flags() | kTwoSidedFlag; }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    return wo.z >= 0 ? front_->Eval(ctx, wo, wi, lobes)
                     : back_->Eval(ctx, FlipZ(wo), FlipZ(wi), lobes);
  }

  float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    return wo.z >= 0 ? front_->Pdf(ctx, wo, wi, lobes)
                     : back_->Pdf(ctx, FlipZ(wo), FlipZ(wi), lobes);
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                    uint32_t lobes) const override {
    if (wo.z >= 0) return front_->Sample(ctx, wo, u1, u2, u3, lobes);
    BsdfSample s = back_->Sample(ctx, FlipZ(wo), u1, u2, u3, lobes);
    s.wi = FlipZ(s.wi);
    return s;
  }

  Vec3 DiffuseAlbedo(const BsdfContext& ctx, const Vec3& wo) const override {
    return wo.z >= 0 ? front_->DiffuseAlbedo(ctx, wo) : back_->DiffuseAlbedo(ctx, FlipZ(wo));
  }

  // The side the shadow ray meets answers, as Sample's side does for paths (a mask on one side
  // only lets light through from that side).
  float PassThrough(const BsdfContext& ctx, float cos_theta, bool front,
                    bool delta_light) const override {
    return front ? front_->PassThrough(ctx, cos_theta, true, delta_light)
                 : back_->PassThrough(ctx, cos_theta, true, delta_light);
  }

  Vec3 ShadingNormal(const BsdfContext& ctx, const Vec3& wo) const override {
    return wo.z >= 0 ? front_->ShadingNormal(ctx, wo) : FlipZ(back_->ShadingNormal(ctx, FlipZ(wo)));
  }

 private:
  const Bsdf* front_;
  const Bsdf* back_;
};

absl::Status Parse(BsdfParams& p) {
  absl::StatusOr<std::vector<int>> nested = p.NestedBsdfs();
  if (!nested.ok()) return nested.status();
  if (nested->empty() || nested->size() > 2)
    return p.Error("", "twosided needs one nested bsdf (both sides) or two (front, back)");
  for (const int i : *nested) {
    const std::string& t = p.Nested(i).type;
    const auto st = p.Nested(i).colors.find("spec_trans");  // principled's transmission
    const bool transmits =
        st != p.Nested(i).colors.end() && (st->second.texture >= 0 || !IsBlack(st->second.value));
    if (t == "dielectric" || t == "thindielectric" || t == "roughdielectric" || t == "twosided" ||
        t == "principledthin" || (t == "principled" && transmits))
      return p.Error(
          "", absl::StrCat("twosided can only wrap a bsdf without transmission, not '", t, "'"));
  }
  return absl::OkStatus();
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  const Bsdf* front = ctx.Nested(d.nested.at(0));
  const Bsdf* back = d.nested.size() > 1 ? ctx.Nested(d.nested[1]) : front;
  return std::make_unique<TwoSidedBsdf>(front, back);
}

}  // namespace

extern const BsdfPlugin kTwoSidedBsdf = {"twosided", Parse, Build};

}  // namespace irfarm
