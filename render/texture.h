// Bitmap textures: 8-bit sRGB images decoded to linear on load (unless `raw`), or linear EXR;
// looked up at (u, v) with column u*w, row v*h (row 0 = top), texel centres at half-integers,
// bilinear or nearest filtering and repeat / mirror / clamp wrapping, as Mitsuba 3 does.
#pragma once

#include "absl/status/statusor.h"
#include "render/image.h"
#include "render/scene_desc.h"

namespace irfarm {

class Texture {
 public:
  static absl::StatusOr<Texture> Load(const TextureDesc& desc);
  Vec3 Eval(float u, float v) const;
  // Derivatives of the luminance of Eval with respect to u and v (bilinear filtering; 0 with
  // nearest), as Mitsuba's eval_1_grad (bump mapping).
  void Gradient(float u, float v, float* d_du, float* d_dv) const;
  Vec3 Average() const { return average_; }

 private:
  int Wrap(int i, int n) const;
  Image image_;
  bool bilinear_ = true;
  int wrap_ = 0;  // 0 repeat, 1 mirror, 2 clamp
  Vec3 average_;
};

}  // namespace irfarm
