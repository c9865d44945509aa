// AovImages: from per-pixel sums to images, and their EXR layer names.
#include "render/aov.h"

#include <algorithm>

namespace irfarm {

AovImages::AovImages(int w, int h)
    : albedo(w, h),
      normal(w, h),
      depth(w, h),
      emission(w, h),
      direct(w, h),
      indirect(w, h),
      variance(w, h) {}

void AovImages::Set(int x, int y, const PixelAovSum& s, int n) {
  const float inv = 1.0f / float(std::max(1, n));
  emission.at(x, y) = s.emission * inv;
  direct.at(x, y) = s.direct * inv;
  indirect.at(x, y) = s.indirect * inv;
  albedo.at(x, y) = s.albedo * inv;
  normal.at(x, y) = s.normal * inv;
  depth.at(x, y) = Vec3(float(s.depth / std::max(1, n)), 0, 0);
  Vec3 v;
  if (n > 1) {
    for (int c = 0; c < 3; ++c) {
      const double mean = s.sum[c] / n;
      const double sample_var = std::max(0.0, (s.sum_sq[c] - n * mean * mean) / (n - 1));
      v[c] = float(sample_var / n);
    }
  }
  variance.at(x, y) = v;
}

namespace {

// Layer name, channel names and the member holding it, in file order.
struct LayerSpec {
  const char* name;
  std::vector<std::string> channels;
  Image AovImages::*member;
};

const std::vector<LayerSpec>& LayerSpecs() {
  static const std::vector<LayerSpec>* specs = new std::vector<LayerSpec>{
      {"albedo", {"R", "G", "B"}, &AovImages::albedo},
      {"normal", {"X", "Y", "Z"}, &AovImages::normal},
      {"depth", {"Z"}, &AovImages::depth},
      {"emission", {"R", "G", "B"}, &AovImages::emission},
      {"direct", {"R", "G", "B"}, &AovImages::direct},
      {"indirect", {"R", "G", "B"}, &AovImages::indirect},
      {"variance", {"R", "G", "B"}, &AovImages::variance},
  };
  return *specs;
}

}  // namespace

std::vector<ExrLayer> AovImages::Layers() const {
  std::vector<ExrLayer> layers;
  for (const LayerSpec& s : LayerSpecs())
    layers.push_back({s.name, s.channels, &(this->*s.member)});
  return layers;
}

absl::StatusOr<AovImages> AovImages::Read(const std::string& path) {
  AovImages a;
  for (const LayerSpec& s : LayerSpecs()) {
    absl::StatusOr<Image> image = ReadExrLayer(path, s.name, s.channels);
    if (!image.ok()) return image.status();
    a.*s.member = std::move(*image);
  }
  return a;
}

}  // namespace irfarm
