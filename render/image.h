// Float RGB images and their files: linear EXR (OpenEXR) in and out, sRGB PNG previews out,
// 8-bit images in (stb_image) for textures, and the error metrics we compare images with.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/math.h"

namespace irfarm {

struct Image {
  int width = 0, height = 0;
  std::vector<Vec3> pixels;  // row 0 = top row
  Image() = default;
  Image(int w, int h) : width(w), height(h), pixels(size_t(w) * h) {}
  Vec3& at(int x, int y) { return pixels[size_t(y) * width + x]; }
  const Vec3& at(int x, int y) const { return pixels[size_t(y) * width + x]; }
};

// An extra layer of an EXR file: channels "name.C" for each C of `channels` (1 to 3 names, taken
// from the image's x, y, z in order), the OpenEXR layer convention tools such as exrheader show.
struct ExrLayer {
  std::string name;
  std::vector<std::string> channels;
  const Image* image = nullptr;  // same size as the main image
};

// Writes linear float RGB (channels R, G, B), and any `layers`, to `path` through a temporary
// file renamed into place.
absl::Status WriteExr(const Image& image, const std::string& path,
                      const std::vector<ExrLayer>& layers = {});
// An EXR's colour: the R, G, B channels of one layer (names classified by their last part, in any
// case, as Mitsuba's read_exr does: "diffuse.r"), else a Y channel as grey; INVALID_ARGUMENT when
// it has neither. With max_texels > 0, a larger image is refused from its header.
absl::StatusOr<Image> ReadExr(const std::string& path, uint64_t max_texels = 0);
// Reads channels "layer.C" for C in `channels` (1 to 3) into x, y, z; an error if one is missing.
absl::StatusOr<Image> ReadExrLayer(const std::string& path, const std::string& layer,
                                   const std::vector<std::string>& channels);
// 8-bit sRGB preview of clip(exposure * linear, 0, 1); exposure <= 0 picks the reference
// images' rule: 2^floor(log2(0.5 / p98 luminance)).
absl::Status WritePng(const Image& image, const std::string& path, float exposure = 0);
// The same PNG as file bytes in memory (the coordinator's dashboard preview).
absl::StatusOr<std::string> EncodePng(const Image& image, float exposure = 0);
// An 8-bit RGB image as a PNG, JPEG, BMP, TGA, ... file stores it: 3 bytes per pixel, row-major
// from the top row, the values as stored (sRGB-encoded unless a texture says `raw`).
struct ByteImage {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
};
// Reads a texture's image file: EXR and Radiance .hdr as linear floats into `*floats` (`*bytes`
// left empty), a 16-bit PNG as floats too (decoded from sRGB unless `raw`), any other format
// stb_image reads (8-bit PNG, JPEG, ...) as its bytes into `*bytes` (`*floats` left empty),
// never widened to floats (a 6-megapixel JPEG would take 72 MB).
absl::Status ReadTextureImage(const std::string& path, bool raw, Image* floats, ByteImage* bytes);

float SrgbToLinear(float v);
float LinearToSrgb(float v);

struct ImageError {
  double relmse = 0;  // mean over pixels and channels of (x-r)^2 / (r^2 + 0.01)
  double rmse = 0;
  Vec3 mean_test, mean_ref;
  long nonfinite = 0;  // non-finite pixels in the test image
};
// The images must have equal size (checked by the caller).
ImageError CompareImages(const Image& test, const Image& ref);
// Averages blocks of `factor` x `factor` pixels (sizes must divide).
Image Downsample(const Image& image, int factor);
// The image with `border` more pixels on each side, mirrored about its edge pixels (as numpy's
// pad mode "reflect": the column left of x = 0 is x = 1), reflected again where the image is
// narrower than the border; and the inverse, the rectangle of `size` at (x0, y0).
Image PadMirrored(const Image& image, int border);
Image Crop(const Image& image, int x0, int y0, int width, int height);

}  // namespace irfarm
