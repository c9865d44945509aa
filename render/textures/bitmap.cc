// `bitmap` (see bitmap.h): the image, its lookups and the plugin.
#include "render/textures/bitmap.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "render/textures/registry.h"

namespace irfarm {
namespace {

// The mean texel from per-channel sums over `texels` texels (0 for an empty image).
Vec3 AverageOf(const double sum[3], size_t texels) {
  const double n = double(std::max<size_t>(1, texels));
  return Vec3(float(sum[0] / n), float(sum[1] / n), float(sum[2] / n));
}

}  // namespace

absl::StatusOr<std::unique_ptr<BitmapTexture>> BitmapTexture::Load(const TextureDesc& desc,
                                                                   bool finite_only) {
  Image floats;
  ByteImage bytes;
  const absl::Status read = ReadTextureImage(desc.filename, desc.raw, &floats, &bytes);
  if (!read.ok())
    return absl::InvalidArgumentError(desc.loc.ToString() + ": " + std::string(read.message()));
  std::unique_ptr<BitmapTexture> t(new BitmapTexture(desc));
  t->bilinear_ = desc.filter_type != "nearest";
  t->wrap_ = desc.wrap_mode == "mirror" ? 1 : (desc.wrap_mode == "clamp" ? 2 : 0);
  if (bytes.rgb.empty()) {
    t->width_ = floats.width;
    t->height_ = floats.height;
    t->image_ = std::move(floats);
    double sum[3] = {0, 0, 0};
    for (size_t i = 0; i < t->image_.pixels.size(); ++i) {
      const Vec3& p = t->image_.pixels[i];
      // A NaN or infinite texel (a half-float sky's clipped sun) in an environment map would make
      // its whole sampling table NaN: a black image, silently.
      if (finite_only && !IsFinite(p)) {
        const size_t w = size_t(std::max(1, t->width_));
        return absl::InvalidArgumentError(
            absl::StrCat(desc.loc.ToString(), ": ", desc.filename, ": texel (", i % w, ", ", i / w,
                         ") is not finite (NaN or infinity); clamp it in the image"));
      }
      for (int c = 0; c < 3; ++c) sum[c] += double(p[c]);
    }
    t->average_ = AverageOf(sum, size_t(t->width_) * size_t(t->height_));
    return t;
  }
  // 8-bit: the bytes as read, decoded through the table on lookup.
  for (int i = 0; i < 256; ++i)
    t->decode_[size_t(i)] = desc.raw ? i / 255.0f : SrgbToLinear(i / 255.0f);
  t->width_ = bytes.width;
  t->height_ = bytes.height;
  t->bytes_ = std::move(bytes.rgb);
  // The mean from each channel's histogram of bytes: one pass of counts, no decoding per texel.
  std::array<std::array<uint64_t, 256>, 3> counts{};
  for (size_t i = 0; i < t->bytes_.size(); i += 3)
    for (int c = 0; c < 3; ++c) ++counts[size_t(c)][t->bytes_[i + size_t(c)]];
  double sum[3] = {0, 0, 0};
  for (int c = 0; c < 3; ++c)
    for (int b = 0; b < 256; ++b)
      sum[c] += double(counts[size_t(c)][size_t(b)]) * double(t->decode_[size_t(b)]);
  t->average_ = AverageOf(sum, size_t(t->width_) * size_t(t->height_));
  return t;
}

int BitmapTexture::Wrap(int i, int n) const {
  // Most lookups land inside the image: no integer division for them.
  if (static_cast<unsigned>(i) < static_cast<unsigned>(n)) return i;
  switch (wrap_) {
    case 1: {  // mirror
      int m = i % (2 * n);
      if (m < 0) m += 2 * n;
      return m < n ? m : 2 * n - 1 - m;
    }
    case 2:
      return std::clamp(i, 0, n - 1);
    default:
      return WrapRepeat(i, n);
  }
}

int BitmapTexture::WrapRepeat(int i, int n) {
  const int m = i % n;
  return m < 0 ? m + n : m;
}

Vec3 BitmapTexture::Bilinear(int x0, int x1, int y0, int y1, float tx, float ty) const {
  return (Texel(x0, y0) * (1 - tx) + Texel(x1, y0) * tx) * (1 - ty) +
         (Texel(x0, y1) * (1 - tx) + Texel(x1, y1) * tx) * ty;
}

Vec3 BitmapTexture::Eval(float u, float v) const {
  ToUv(&u, &v);
  if (!std::isfinite(u) || !std::isfinite(v)) return average_;
  const int w = width_, h = height_;
  if (!bilinear_) {
    const int x = Wrap(int(std::floor(u * w)), w), y = Wrap(int(std::floor(v * h)), h);
    return Texel(x, y);
  }
  const float fx = u * w - 0.5f, fy = v * h - 0.5f;
  const float x0f = std::floor(fx), y0f = std::floor(fy);
  const float tx = fx - x0f, ty = fy - y0f;
  const int x0 = Wrap(int(x0f), w), x1 = Wrap(int(x0f) + 1, w);
  const int y0 = Wrap(int(y0f), h), y1 = Wrap(int(y0f) + 1, h);
  return Bilinear(x0, x1, y0, y1, tx, ty);
}

Vec3 BitmapTexture::EvalLatLong(float u, float v) const {
  const int w = width_, h = height_;
  if (!std::isfinite(u) || !std::isfinite(v) || w <= 0 || h <= 0) return average_;
  const float fx = u * float(w) - 0.5f, fy = std::clamp(v, 0.0f, 1.0f) * float(h - 1);
  const float x0f = std::floor(fx), y0f = std::floor(fy);
  const float tx = fx - x0f, ty = fy - y0f;
  const int x0 = WrapRepeat(int(x0f), w), x1 = WrapRepeat(int(x0f) + 1, w);
  const int y0 = std::clamp(int(y0f), 0, h - 1), y1 = std::min(y0 + 1, h - 1);
  return Bilinear(x0, x1, y0, y1, tx, ty);
}

void BitmapTexture::Gradient(float u, float v, float* d_du, float* d_dv) const {
  *d_du = *d_dv = 0;
  ToUv(&u, &v);
  const int w = width_, h = height_;
  if (!bilinear_ || !std::isfinite(u) || !std::isfinite(v)) return;
  const float fx = u * w - 0.5f, fy = v * h - 0.5f;
  const float x0f = std::floor(fx), y0f = std::floor(fy);
  const float tx = fx - x0f, ty = fy - y0f;
  const int x0 = Wrap(int(x0f), w), x1 = Wrap(int(x0f) + 1, w);
  const int y0 = Wrap(int(y0f), h), y1 = Wrap(int(y0f) + 1, h);
  // Mitsuba's luminance weights (its RGB variants).
  const auto lum = [&](int x, int y) {
    const Vec3 c = Texel(x, y);
    return 0.212671f * c.x + 0.715160f * c.y + 0.072169f * c.z;
  };
  const float f00 = lum(x0, y0), f10 = lum(x1, y0), f01 = lum(x0, y1), f11 = lum(x1, y1);
  // With respect to the transformed (u', v'), then by the chain rule to the surface's (u, v).
  const float g_u = float(w) * ((f10 - f00) * (1 - ty) + (f11 - f01) * ty);
  const float g_v = float(h) * ((f01 - f00) * (1 - tx) + (f11 - f10) * tx);
  *d_du = g_u * to_uv_[0] + g_v * to_uv_[3];
  *d_dv = g_u * to_uv_[1] + g_v * to_uv_[4];
}

namespace {

absl::Status Parse(TextureParams& p, TextureDesc* d) {
  absl::StatusOr<std::string> filename = p.File("filename");
  if (!filename.ok()) return filename.status();
  d->filename = *filename;
  absl::StatusOr<std::string> filter = p.String("filter_type", "bilinear");
  if (!filter.ok()) return filter.status();
  if (*filter != "bilinear" && *filter != "nearest") {
    return p.Error("filter_type", absl::StrCat("unknown filter_type '", *filter,
                                               "' (supported: bilinear, nearest)"));
  }
  d->filter_type = *filter;
  absl::StatusOr<std::string> wrap = p.String("wrap_mode", "repeat");
  if (!wrap.ok()) return wrap.status();
  if (*wrap != "repeat" && *wrap != "mirror" && *wrap != "clamp") {
    return p.Error("wrap_mode", absl::StrCat("unknown wrap_mode '", *wrap,
                                             "' (supported: repeat, mirror, clamp)"));
  }
  d->wrap_mode = *wrap;
  absl::StatusOr<bool> raw = p.Bool("raw", false);
  if (!raw.ok()) return raw.status();
  d->raw = *raw;
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<Texture>> Build(const TextureDesc& d) {
  absl::StatusOr<std::unique_ptr<BitmapTexture>> t = BitmapTexture::Load(d);
  if (!t.ok()) return t.status();
  return std::unique_ptr<Texture>(*std::move(t));
}

}  // namespace

extern const TexturePlugin kBitmapTexture = {"bitmap", Parse, Build};

}  // namespace irfarm
