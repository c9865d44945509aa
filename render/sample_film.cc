#include "render/sample_film.h"

#include <algorithm>

namespace irfarm {

SampleFilm::SampleFilm(size_t pixels, int slots)
    : slots_(slots),
      stride_(1 + 3 * size_t(slots)),
      data_(pixels * 2 * stride_),
      weight_(pixels * 2, 0.0f),
      count_(pixels, 0),
      peak_(pixels),
      peak_luminance_(pixels, 0.0f) {}

void SampleFilm::Add(size_t p, int index, const Vec3& L, const DirectTerms* terms, float weight) {
  Vec3* h = Half(p, index & 1);
  // Weight 1 (every sample of a box-filtered pixel) adds exactly what it did before weights.
  h[0] += L * weight;
  if (terms)
    for (int j = 0; j < slots_; ++j) {
      h[1 + 3 * j] += terms->analytic[j] * weight;
      h[2 + 3 * j] += terms->shadowed[j] * weight;
      h[3 + 3 * j] += terms->unshadowed[j] * weight;
    }
  weight_[2 * p + size_t(index & 1)] += weight;
  ++count_[p];
  const float lum = Luminance(L) * weight;
  if (lum > peak_luminance_[p]) {
    peak_luminance_[p] = lum;
    peak_[p] = L * weight;
  }
}

// Sum of the radiance and of A_j * S_j / U_j over the halves given (b may be null), over the
// sum of their weights.
Vec3 SampleFilm::Resolve(const Vec3* a, const Vec3* b, float weight) const {
  if (!(weight > 0)) return Vec3();
  Vec3 v = b ? a[0] + b[0] : a[0];
  for (int j = 0; j < slots_; ++j) {
    const Vec3 A = b ? a[1 + 3 * j] + b[1 + 3 * j] : a[1 + 3 * j];
    const Vec3 S = b ? a[2 + 3 * j] + b[2 + 3 * j] : a[2 + 3 * j];
    const Vec3 U = b ? a[3 + 3 * j] + b[3 + 3 * j] : a[3 + 3 * j];
    v += A * DirectTerms::Ratio(S, U);
  }
  return v / weight;
}

Vec3 SampleFilm::Value(size_t p) const {
  return Resolve(Half(p, 0), Half(p, 1), weight_[2 * p] + weight_[2 * p + 1]);
}

Vec3 SampleFilm::HalfValue(size_t p, int h) const {
  return Resolve(Half(p, h), nullptr, weight_[2 * p + size_t(h)]);
}

double SampleFilm::RelativeError(size_t p) const {
  if (!(weight_[2 * p] > 0 && weight_[2 * p + 1] > 0)) return 0;
  const Vec3 a = HalfValue(p, 0), b = HalfValue(p, 1);
  double e = 0;
  for (int c = 0; c < 3; ++c) {
    const double d = double(a[c]) - double(b[c]);
    // Normalised by the product of the halves, not by the pixel's own value squared: E[a b] is
    // the squared mean for independent halves, while v^2 is largest exactly when a rare bright
    // sample (a light's edge, a caustic) makes the variance large, which hid those pixels'
    // error (cornell-box --target-error 1e-3: estimate 5.1e-4 against 1.45e-3 measured, 74% of
    // it in the 0.1% of pixels at the lamp's edge; with a b: 8.2e-4 against 7.9e-4).
    const double mean_sq = std::max(0.0, double(a[c]) * double(b[c]));
    e += d * d / 4 / (mean_sq + 0.01);
  }
  return e / 3;
}

}  // namespace irfarm
