// `bumpmap`: Mitsuba 3's bump mapping. One nested scalar texture (a bitmap; its luminance) is a
// height field h(u, v); `scale` (default 1) multiplies it. The surface is displaced along the
// shading normal by scale h: the tangents become dp/du + n scale dh/du and dp/dv + n scale
// dh/dv (their normal components replaced, as Mitsuba), the perturbed normal is their cross
// product (turned to the shading normal's side), and the nested BSDF is evaluated in that frame
// with s along dp/du (see perturbed_frame.h for the rest). dh/du and dh/dv are the bilinear
// texture's exact derivatives in texture units (texels times resolution), as Mitsuba's
// eval_1_grad; a constant or nearest-filtered texture has none (no bump).
#include "render/bsdfs/perturbed_frame.h"

namespace irfarm {
namespace {

class BumpMapBsdf final : public PerturbedFrameBsdf {
 public:
  BumpMapBsdf(const Texture* height, float scale, const Bsdf* nested, bool flip, bool shadowing)
      : PerturbedFrameBsdf(nested, shadowing), height_(height), scale_(scale), flip_(flip) {}

 protected:
  LocalFrame Frame(const BsdfContext& ctx, const Vec3& wo) const override {
    Vec3 dpdu, dpdv;
    LocalTangents(ctx, &dpdu, &dpdv);
    float gu = 0, gv = 0;
    if (height_) height_->Gradient(ctx.u, ctx.v, &gu, &gv);
    const Vec3 du(dpdu.x, dpdu.y, scale_ * gu), dv(dpdv.x, dpdv.y, scale_ * gv);
    Vec3 n = Cross(du, dv);
    if (!(LengthSquared(n) > 0)) n = Vec3(0, 0, 1);
    n = Normalize(n);
    if (n.z < 0) n = -n;
    if (flip_) n = FlipInvalid(n, wo);
    return FrameAround(n, dpdu);
  }

 private:
  const Texture* height_;  // owned by the Scene; nullptr for a constant
  float scale_;
  bool flip_;
};

absl::Status Parse(BsdfParams& p) {
  if (absl::Status s = p.Float("scale", 1.0f).status(); !s.ok()) return s;
  absl::StatusOr<std::vector<ColorParam>> tex = p.NestedTextures();
  if (!tex.ok()) return tex.status();
  if (tex->size() != 1) return p.Error("", "bumpmap needs exactly one nested texture");
  p.desc().colors["height"] = tex->front();
  return ParsePerturbedFrameParams(p, "bumpmap");
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<BumpMapBsdf>(ctx.Color(d.Color("height", Vec3(0.0f))).texture,
                                       d.Float("scale", 1), ctx.Nested(d.nested.at(0)),
                                       d.Float("flip_invalid_normals", 1) != 0,
                                       d.Float("use_shadowing_function", 1) != 0);
}

}  // namespace

extern const BsdfPlugin kBumpMapBsdf = {"bumpmap", Parse, Build};

}  // namespace irfarm
