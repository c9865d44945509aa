// `bitmap`: an image texture. 8-bit images are kept as their bytes, 3 per texel, decoded through a
// 256-entry table (sRGB to linear, or /255 when `raw`): the same floats as decoding the whole
// image on load, in a quarter of the memory, so lookups miss the CPU caches less. Linear EXR and
// .hdr images are kept as floats. Looked up at (u, v) with column u*w, row v*h (row 0 = top),
// texel centres at half-integers, bilinear or nearest filtering (filter_type) and repeat, mirror
// or clamp wrapping (wrap_mode). The envmap emitter reads its image as one (EvalLatLong).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "render/image.h"
#include "render/texture.h"

namespace irfarm {

class BitmapTexture final : public Texture {
 public:
  // `finite_only`: a float image with a NaN or infinite texel is refused, naming the texel (an
  // environment map: one such texel made its sampling table, and so the whole image, black). A
  // surface texture keeps them: the samples they poison are counted and left out of the image
  // (RenderCounters::nonfinite_samples; DirectLightTest.NanTexelIsCountedAndKeptOutOfTheImage).
  static absl::StatusOr<std::unique_ptr<BitmapTexture>> Load(const TextureDesc& desc,
                                                             bool finite_only = false);
  Vec3 Eval(float u, float v) const override;
  // Mitsuba's bitmap eval_1: the luminance of a colour image (a grey one's value).
  float EvalScalar(float u, float v) const override { return Luminance(Eval(u, v)); }
  // Bilinear filtering only (0 with nearest).
  void Gradient(float u, float v, float* d_du, float* d_dv) const override;
  // An environment map's radiance at (u, v) (u = phi / 2 pi, v = theta / pi), as Mitsuba 3's
  // envmap emitter looks it up: bilinear, column u*w - 0.5 wrapping around, but row v*(h-1)
  // clamped, so row 0 lies at the pole v = 0 and row h-1 at v = 1 (not at half-integers as a
  // bitmap's rows). Measured with mitsuba 3.9.1 (scalar_rgb) on a map with one lit texel: its
  // radiance peaks at u = (i + 0.5) / w and v = j / (h - 1). For a 1.5-degree sun drawn into a
  // 512 x 256 map 40 degrees up, the bitmap convention put the sun 0.16 degrees low, and its
  // shadows' edges a third of a pixel off the reference's (make_room 907). The transform to_uv is
  // not applied (an envmap has none).
  Vec3 EvalLatLong(float u, float v) const;

 private:
  explicit BitmapTexture(const TextureDesc& desc) : Texture(desc.to_uv) {}
  // Texel (x, y), both in range, as linear RGB.
  Vec3 Texel(int x, int y) const {
    if (!bytes_.empty()) {
      const uint8_t* b = &bytes_[3 * (size_t(y) * size_t(width_) + size_t(x))];
      return Vec3(decode_[b[0]], decode_[b[1]], decode_[b[2]]);
    }
    return image_.at(x, y);
  }
  int Wrap(int i, int n) const;
  static int WrapRepeat(int i, int n);  // i modulo n, in [0, n)
  // The bilinear blend of texels (x0 | x1, y0 | y1) with weights tx, ty towards x1, y1.
  Vec3 Bilinear(int x0, int x1, int y0, int y1, float tx, float ty) const;
  Image image_;                      // float texels (EXR, .hdr); empty for 8-bit images
  std::vector<uint8_t> bytes_;       // 8-bit images: RGB bytes, row-major
  std::array<float, 256> decode_{};  // byte -> linear value
  int width_ = 0, height_ = 0;
  bool bilinear_ = true;
  int wrap_ = 0;  // 0 repeat, 1 mirror, 2 clamp
};

}  // namespace irfarm
