// A texture: a colour over a surface's (u, v), as one of Mitsuba 3's texture plugins
// (render/textures/: bitmap, checkerboard; TextureDesc::type), each after its to_uv transform of
// (u, v). BSDFs hold the Scene's textures through this interface (TexturedColor, bumpmap).
#pragma once

#include <array>
#include <memory>

#include "absl/status/statusor.h"
#include "core/math.h"
#include "render/scene_desc.h"

namespace irfarm {

class Texture {
 public:
  virtual ~Texture() = default;
  // The colour at surface coordinates (u, v); the texture's average where they are not finite.
  virtual Vec3 Eval(float u, float v) const = 0;
  // A scalar parameter (roughness, opacity, weight) read from the texture, as Mitsuba's eval_1:
  // the mean of the channels (what its rgb constants give, and so its checkerboard); a bitmap
  // overrides it with the luminance.
  virtual float EvalScalar(float u, float v) const {
    const Vec3 c = Eval(u, v);
    return (c.x + c.y + c.z) * (1.0f / 3.0f);
  }
  // Derivatives of the luminance of Eval with respect to u and v, as Mitsuba's eval_1_grad (bump
  // mapping); 0 where the texture is flat.
  virtual void Gradient(float u, float v, float* d_du, float* d_dv) const = 0;
  Vec3 Average() const { return average_; }

 protected:
  explicit Texture(const std::array<float, 6>& to_uv) : to_uv_(to_uv) {}
  void ToUv(float* u, float* v) const {
    const float x = *u, y = *v;
    *u = to_uv_[0] * x + to_uv_[1] * y + to_uv_[2];
    *v = to_uv_[3] * x + to_uv_[4] * y + to_uv_[5];
  }
  std::array<float, 6> to_uv_;
  Vec3 average_;
};

// The texture `desc` describes, made by its plugin (render/textures/registry.h); a file that
// cannot be read is an error at desc.loc.
absl::StatusOr<std::unique_ptr<Texture>> LoadTexture(const TextureDesc& desc);

}  // namespace irfarm
