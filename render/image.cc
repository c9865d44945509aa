// EXR through OpenEXR's RGBA-free channel API (three FLOAT channels R, G, B), PNG through
// stb_image_write, LDR reading through stb_image.
#include "render/image.h"

#include <stb_image.h>
#include <stb_image_write.h>

#include <ImathBox.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <half.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <map>

namespace irfarm {

absl::Status WriteExr(const Image& image, const std::string& path,
                      const std::vector<ExrLayer>& layers) {
  std::vector<ExrLayer> all = {{"", {"R", "G", "B"}, &image}};
  for (const ExrLayer& l : layers) {
    if (!l.image || l.image->width != image.width || l.image->height != image.height ||
        l.channels.empty() || l.channels.size() > 3 || l.name.empty())
      return absl::InternalError(path + ": EXR layer '" + l.name + "' is malformed");
    all.push_back(l);
  }
  const std::string tmp = path + ".tmp";
  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    Imf::FrameBuffer fb;
    const size_t xs = sizeof(Vec3), ys = sizeof(Vec3) * image.width;
    for (const ExrLayer& l : all) {
      char* base = const_cast<char*>(reinterpret_cast<const char*>(l.image->pixels.data()));
      for (size_t c = 0; c < l.channels.size(); ++c) {
        const std::string name = l.name.empty() ? l.channels[c] : l.name + "." + l.channels[c];
        header.channels().insert(name, Imf::Channel(Imf::FLOAT));
        fb.insert(name, Imf::Slice(Imf::FLOAT, base + 4 * c, xs, ys));
      }
    }
    Imf::OutputFile file(tmp.c_str(), header);
    file.setFrameBuffer(fb);
    file.writePixels(image.height);
  } catch (const std::exception& e) {
    std::remove(tmp.c_str());
    return absl::InternalError(path + ": cannot write EXR: " + e.what());
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    return absl::InternalError(path + ": cannot rename " + tmp + " into place");
  return absl::OkStatus();
}

namespace {

// Reads up to three float channels of an open EXR (`names`, in order) into an Image's R, G and B;
// channels left out read as 0. Throws as OpenEXR does.
Image ReadChannels(Imf::InputFile& file, const std::vector<std::string>& names) {
  const Imath::Box2i dw = file.header().dataWindow();
  const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
  Image image(w, h);
  Imf::FrameBuffer fb;
  char* base = reinterpret_cast<char*>(image.pixels.data()) -
               (size_t(dw.min.x) + size_t(dw.min.y) * w) * sizeof(Vec3);
  const size_t xs = sizeof(Vec3), ys = sizeof(Vec3) * w;
  for (size_t c = 0; c < names.size() && c < 3; ++c)
    fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + 4 * c, xs, ys, 1, 1, 0.0));
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  return image;
}

// A texture image larger than `cap` texels (ReadTextureImage, ReadExr's max_texels).
absl::Status TooLarge(const std::string& path, uint64_t w, uint64_t h, uint64_t cap) {
  return absl::InvalidArgumentError(path + ": image of " + std::to_string(w) + " x " +
                                    std::to_string(h) + " texels is larger than the " +
                                    std::to_string(cap) + " texels a texture may have");
}

}  // namespace

absl::StatusOr<Image> ReadExr(const std::string& path, uint64_t max_texels) {
  try {
    Imf::InputFile file(path.c_str());
    if (max_texels > 0) {  // from the header, before anything is allocated
      const Imath::Box2i dw = file.header().dataWindow();
      const uint64_t w = uint64_t(int64_t(dw.max.x) - dw.min.x + 1),
                     h = uint64_t(int64_t(dw.max.y) - dw.min.y + 1);
      if (w * h > max_texels) return TooLarge(path, w, h, max_texels);
    }
    // Channels are classified as Mitsuba's read_exr does, by the part of their name after the
    // last '.', in any case: "R", "diffuse.r" and "B" are colour channels. Taken: an R, G and B
    // of one layer (the unnamed layer first, then layers in name order), else a Y (luminance, as
    // grey); else the file is refused (read as black before).
    std::map<std::string, std::array<std::string, 4>> layers;  // layer -> R, G, B, Y names
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
      const std::string name = it.name();
      const size_t dot = name.rfind('.');
      const std::string layer = dot == std::string::npos ? "" : name.substr(0, dot);
      std::string suffix = dot == std::string::npos ? name : name.substr(dot + 1);
      for (char& c : suffix) c = char(std::tolower(static_cast<unsigned char>(c)));
      const int k = suffix == "r"   ? 0
                    : suffix == "g" ? 1
                    : suffix == "b" ? 2
                    : suffix == "y" ? 3
                                    : -1;
      if (k >= 0 && layers[layer][size_t(k)].empty()) layers[layer][size_t(k)] = name;
    }
    for (const auto& [layer, names] : layers)
      if (!names[0].empty() && !names[1].empty() && !names[2].empty())
        return ReadChannels(file, {names[0], names[1], names[2]});
    for (const auto& [layer, names] : layers)
      if (!names[3].empty()) return ReadChannels(file, {names[3], names[3], names[3]});
    std::string all;
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it)
      all += std::string(all.empty() ? "" : ", ") + it.name();
    return absl::InvalidArgumentError(path + ": EXR has no R, G, B or Y channels (it has: " + all +
                                      ")");
  } catch (const std::exception& e) {
    return absl::InvalidArgumentError(path + ": cannot read EXR: " + e.what());
  }
}

absl::StatusOr<Image> ReadExrLayer(const std::string& path, const std::string& layer,
                                   const std::vector<std::string>& channels) {
  try {
    Imf::InputFile file(path.c_str());
    std::vector<std::string> names;
    for (size_t c = 0; c < channels.size() && c < 3; ++c) {
      names.push_back(layer + "." + channels[c]);
      if (!file.header().channels().findChannel(names.back()))
        return absl::NotFoundError(path + ": no EXR channel '" + names.back() + "'");
    }
    return ReadChannels(file, names);
  } catch (const std::exception& e) {
    return absl::InvalidArgumentError(path + ": cannot read EXR: " + e.what());
  }
}

float SrgbToLinear(float v) {
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}
float LinearToSrgb(float v) {
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

namespace {

// 8-bit sRGB of `image` at `exposure` (<= 0: the one that maps the 98th luminance percentile to
// about 0.5, a power of two), as WritePng and EncodePng store it.
std::vector<unsigned char> ToneMapToSrgb8(const Image& image, float exposure) {
  if (exposure <= 0) {
    std::vector<float> lum;
    lum.reserve(image.pixels.size());
    for (const Vec3& p : image.pixels)
      if (IsFinite(p)) lum.push_back(Luminance(p));
    float p98 = 0;
    if (!lum.empty()) {
      const size_t k = std::min(lum.size() - 1, size_t(0.98 * lum.size()));
      std::nth_element(lum.begin(), lum.begin() + k, lum.end());
      p98 = lum[k];
    }
    exposure = p98 > 0 ? std::exp2(std::floor(std::log2(0.5f / p98))) : 1.0f;
  }
  std::vector<unsigned char> rgb(image.pixels.size() * 3);
  for (size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      float v = image.pixels[i][c] * exposure;
      v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
      rgb[3 * i + c] = static_cast<unsigned char>(std::lround(LinearToSrgb(v) * 255.0f));
    }
  return rgb;
}

void AppendBytes(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
}

}  // namespace

absl::StatusOr<std::string> EncodePng(const Image& image, float exposure) {
  const std::vector<unsigned char> rgb = ToneMapToSrgb8(image, exposure);
  std::string out;
  if (!stbi_write_png_to_func(AppendBytes, &out, image.width, image.height, 3, rgb.data(),
                              image.width * 3))
    return absl::InternalError("cannot encode PNG");
  return out;
}

absl::Status WritePng(const Image& image, const std::string& path, float exposure) {
  const std::vector<unsigned char> rgb = ToneMapToSrgb8(image, exposure);
  const std::string tmp = path + ".tmp";
  if (!stbi_write_png(tmp.c_str(), image.width, image.height, 3, rgb.data(), image.width * 3))
    return absl::InternalError(path + ": cannot write PNG");
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    return absl::InternalError(path + ": cannot rename " + tmp + " into place");
  return absl::OkStatus();
}

absl::Status ReadTextureImage(const std::string& path, bool raw, Image* floats, ByteImage* bytes) {
  *floats = Image();
  *bytes = ByteImage();
  // Sizes are checked from the header before anything is decoded: a small upload can claim any
  // size (a PNG of 40000 x 40000 would take 4.8 GB as bytes). Floats (EXR, HDR, 16-bit PNG)
  // take 12 bytes a texel: 2^27 texels is a 16K x 8K environment map; bytes 3: 2^28.
  constexpr uint64_t kMaxFloatTexels = uint64_t{1} << 27, kMaxByteTexels = uint64_t{1} << 28;
  const std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
  if (ext == ".exr" || ext == ".EXR") {
    absl::StatusOr<Image> exr = ReadExr(path, kMaxFloatTexels);
    if (!exr.ok()) return exr.status();
    *floats = std::move(*exr);
    return absl::OkStatus();
  }
  int w = 0, h = 0, n = 0;
  if (stbi_info(path.c_str(), &w, &h, &n)) {
    const bool wide = stbi_is_hdr(path.c_str()) || stbi_is_16_bit(path.c_str());
    const uint64_t cap = wide ? kMaxFloatTexels : kMaxByteTexels;
    if (uint64_t(w) * uint64_t(h) > cap) return TooLarge(path, uint64_t(w), uint64_t(h), cap);
  }
  if (stbi_is_hdr(path.c_str())) {
    // Radiance RGBE (.hdr): linear floats. stbi_load would tone-map it to 8 bits.
    float* hdr = stbi_loadf(path.c_str(), &w, &h, &n, 3);
    if (!hdr)
      return absl::InvalidArgumentError(path + ": cannot read image: " + stbi_failure_reason());
    Image image(w, h);
    for (size_t i = 0; i < image.pixels.size(); ++i)
      image.pixels[i] = Vec3(hdr[3 * i], hdr[3 * i + 1], hdr[3 * i + 2]);
    stbi_image_free(hdr);
    *floats = std::move(image);
    return absl::OkStatus();
  }
  if (stbi_is_16_bit(path.c_str())) {
    // 16-bit PNG: all 16 bits, decoded from sRGB unless `raw` and kept at half precision, as
    // Mitsuba keeps them (stbi_load would drop the low byte: 0x00ff read as 0).
    uint16_t* data16 = stbi_load_16(path.c_str(), &w, &h, &n, 3);
    if (!data16)
      return absl::InvalidArgumentError(path + ": cannot read image: " + stbi_failure_reason());
    Image image(w, h);
    for (size_t i = 0; i < image.pixels.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        const float v = float(data16[3 * i + size_t(c)]) / 65535.0f;
        image.pixels[i][c] = float(half(raw ? v : SrgbToLinear(v)));
      }
    stbi_image_free(data16);
    *floats = std::move(image);
    return absl::OkStatus();
  }
  unsigned char* data = stbi_load(path.c_str(), &w, &h, &n, 3);
  if (!data)
    return absl::InvalidArgumentError(path + ": cannot read image: " + stbi_failure_reason());
  bytes->width = w;
  bytes->height = h;
  bytes->rgb.assign(data, data + 3 * size_t(w) * size_t(h));
  stbi_image_free(data);
  return absl::OkStatus();
}

ImageError CompareImages(const Image& test, const Image& ref) {
  ImageError e;
  double rel = 0, sq = 0;
  double mt[3] = {0, 0, 0}, mr[3] = {0, 0, 0};
  for (size_t i = 0; i < test.pixels.size(); ++i) {
    if (!IsFinite(test.pixels[i])) ++e.nonfinite;
    for (int c = 0; c < 3; ++c) {
      const double x = test.pixels[i][c], r = ref.pixels[i][c];
      rel += (x - r) * (x - r) / (r * r + 0.01);
      sq += (x - r) * (x - r);
      mt[c] += x;
      mr[c] += r;
    }
  }
  const double n = double(test.pixels.size());
  e.relmse = rel / (3 * n);
  e.rmse = std::sqrt(sq / (3 * n));
  e.mean_test = Vec3(float(mt[0] / n), float(mt[1] / n), float(mt[2] / n));
  e.mean_ref = Vec3(float(mr[0] / n), float(mr[1] / n), float(mr[2] / n));
  return e;
}

Image Downsample(const Image& image, int factor) {
  Image out(image.width / factor, image.height / factor);
  const float inv = 1.0f / float(factor * factor);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      Vec3 s;
      for (int j = 0; j < factor; ++j)
        for (int i = 0; i < factor; ++i) s += image.at(x * factor + i, y * factor + j);
      out.at(x, y) = s * inv;
    }
  return out;
}

namespace {

// Index i (any integer) reflected into [0, n) about the first and last pixel.
int Reflect(int i, int n) {
  if (n == 1) return 0;
  const int period = 2 * (n - 1);
  i %= period;
  if (i < 0) i += period;
  return i < n ? i : period - i;
}

}  // namespace

Image PadMirrored(const Image& image, int border) {
  Image out(image.width + 2 * border, image.height + 2 * border);
  for (int y = 0; y < out.height; ++y) {
    const int sy = Reflect(y - border, image.height);
    for (int x = 0; x < out.width; ++x)
      out.at(x, y) = image.at(Reflect(x - border, image.width), sy);
  }
  return out;
}

Image Crop(const Image& image, int x0, int y0, int width, int height) {
  Image out(width, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) out.at(x, y) = image.at(x0 + x, y0 + y);
  return out;
}

}  // namespace irfarm
