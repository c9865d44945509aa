// `checkerboard`: color0 (default 0.4) where the fractional parts of u and v are both above 0.5
// or both not, color1 (default 0.2) elsewhere, as Mitsuba's; flat between its jumps. Read as one
// number, the other way round, as Mitsuba's eval_1.
#include <cmath>

#include "render/textures/registry.h"

namespace irfarm {
namespace {

class CheckerboardTexture final : public Texture {
 public:
  explicit CheckerboardTexture(const TextureDesc& d)
      : Texture(d.to_uv), color0_(d.color0), color1_(d.color1) {
    average_ = (color0_ + color1_) * 0.5f;
  }

  Vec3 Eval(float u, float v) const override {
    ToUv(&u, &v);
    if (!std::isfinite(u) || !std::isfinite(v)) return average_;
    return ((u - std::floor(u) > 0.5f) == (v - std::floor(v) > 0.5f)) ? color0_ : color1_;
  }

  // Mitsuba's eval_1 (a checkerboard read as opacity, a blend weight or a roughness) picks the
  // colours the other way round from its eval: color0's mean where exactly one of the fractional
  // parts is above 0.5 (checkerboard.cpp, m0 = mask.x != mask.y). Matched, as the reference.
  float EvalScalar(float u, float v) const override {
    ToUv(&u, &v);
    const auto mean = [](const Vec3& c) { return (c.x + c.y + c.z) * (1.0f / 3.0f); };
    if (!std::isfinite(u) || !std::isfinite(v)) return mean(average_);
    return mean((u - std::floor(u) > 0.5f) != (v - std::floor(v) > 0.5f) ? color0_ : color1_);
  }

  void Gradient(float, float, float* d_du, float* d_dv) const override { *d_du = *d_dv = 0; }

 private:
  Vec3 color0_, color1_;
};

absl::Status Parse(TextureParams& p, TextureDesc* d) {
  absl::StatusOr<Vec3> c0 = p.Rgb("color0", d->color0);
  if (!c0.ok()) return c0.status();
  d->color0 = *c0;
  absl::StatusOr<Vec3> c1 = p.Rgb("color1", d->color1);
  if (!c1.ok()) return c1.status();
  d->color1 = *c1;
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<Texture>> Build(const TextureDesc& d) {
  return std::unique_ptr<Texture>(std::make_unique<CheckerboardTexture>(d));
}

}  // namespace

extern const TexturePlugin kCheckerboardTexture = {"checkerboard", Parse, Build};

}  // namespace irfarm
