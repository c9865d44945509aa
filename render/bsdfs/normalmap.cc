// `normalmap`: Mitsuba 3's normal mapping. The `normalmap` texture (a bitmap, or a constant rgb)
// holds tangent-space normals with components in [0, 1] mapped to [-1, 1]: x along dp/du, y
// along n x dp/du, z along the shading normal. The nested BSDF is evaluated in the frame of
// that normal, whose s axis is dp/du made orthogonal to it (see perturbed_frame.h for the rest).
#include "render/bsdfs/perturbed_frame.h"

namespace irfarm {
namespace {

class NormalMapBsdf final : public PerturbedFrameBsdf {
 public:
  NormalMapBsdf(const TexturedColor& map, const Bsdf* nested, bool flip, bool shadowing)
      : PerturbedFrameBsdf(nested, shadowing), map_(map), flip_(flip) {}

 protected:
  LocalFrame Frame(const BsdfContext& ctx, const Vec3& wo) const override {
    Vec3 dpdu, dpdv;
    LocalTangents(ctx, &dpdu, &dpdv);
    // The tangent frame Mitsuba's map is expressed in: s = dp/du projected, t = n x s.
    const LocalFrame tangent = FrameAround(Vec3(0, 0, 1), dpdu);
    const Vec3 m = map_.Eval(ctx) * 2.0f - Vec3(1.0f);
    Vec3 n = tangent.FromFrame(m);
    if (!(LengthSquared(n) > 0)) n = Vec3(0, 0, 1);
    n = Normalize(n);
    if (flip_) n = FlipInvalid(n, wo);
    return FrameAround(n, tangent.s);
  }

 private:
  TexturedColor map_;
  bool flip_;
};

absl::Status Parse(BsdfParams& p) {
  if (!p.Has("normalmap")) return p.Error("", "normalmap needs a 'normalmap' texture");
  if (absl::Status s = p.Color("normalmap", Vec3(0.5f, 0.5f, 1.0f)).status(); !s.ok()) return s;
  return ParsePerturbedFrameParams(p, "normalmap");
}

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  return std::make_unique<NormalMapBsdf>(
      ctx.Color(d.Color("normalmap", Vec3(0.5f, 0.5f, 1.0f))), ctx.Nested(d.nested.at(0)),
      d.Float("flip_invalid_normals", 1) != 0, d.Float("use_shadowing_function", 1) != 0);
}

}  // namespace

extern const BsdfPlugin kNormalMapBsdf = {"normalmap", Parse, Build};

}  // namespace irfarm
