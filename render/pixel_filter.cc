#include "render/pixel_filter.h"

#include <algorithm>
#include <cmath>

namespace irfarm {
namespace {

constexpr double kSqrtHalfPi = 1.2533141373155002512;  // sqrt(pi / 2)
constexpr double kSqrt2 = 1.4142135623730950488;

}  // namespace

PixelFilter::PixelFilter(const FilterDesc& desc, int width, int height)
    : desc_(desc), width_(std::max(1, width)), height_(std::max(1, height)) {
  if (desc_.type == FilterType::kBox) desc_.radius = 0.5f;
  const double r = desc_.radius, s = desc_.stddev;
  if (desc_.type == FilterType::kGaussian) {
    inv_two_var_ = 1 / (2 * s * s);
    bias_ = std::exp(-r * r * inv_two_var_);
    erf_scale_ = s * kSqrtHalfPi;
    erf_arg_ = 1 / (s * kSqrt2);
    g_radius_ = Cumulative(r);  // with g_radius_ = 0 still, this is G(r)
  }
  total_ = Cumulative(r);
  if (SplatReach() > 0) {
    // Separable: the 2D ratio sum(w^2) / sum(w)^2 is the square of the 1D one, with the 1D
    // integral of w^2 by the midpoint rule over the support (that of w is total_).
    constexpr int kSteps = 4096;
    const double dt = 2 * r / kSteps;
    double sum_sq = 0;
    for (int i = 0; i < kSteps; ++i) {
      const double w = Weight(-r + (i + 0.5) * dt);
      sum_sq += w * w * dt;
    }
    const double ratio = sum_sq / (total_ * total_);
    splat_variance_factor_ = ratio * ratio;
    // n samples per pixel add n total_^2 of weight to a pixel on average; they must add
    // n / splat_variance_factor_ = n total_^4 / sum_sq^2.
    splat_sample_weight_ = total_ * total_ / (sum_sq * sum_sq);
  }
  if (desc_.type != FilterType::kGaussian) return;
  // Each entry by bisection on the monotone W: 200 halvings reach the spacing of doubles.
  const double total = total_;
  inverse_[0] = -r;
  inverse_[kTable] = r;
  for (int i = 1; i < kTable; ++i) {
    const double target = total * i / kTable;
    double lo = -r, hi = r;
    for (int k = 0; k < 200 && hi - lo > 0; ++k) {
      const double mid = 0.5 * (lo + hi);
      if (mid <= lo || mid >= hi) break;
      (Cumulative(mid) < target ? lo : hi) = mid;
    }
    inverse_[i] = 0.5 * (lo + hi);
  }
}

double PixelFilter::Weight(double t) const {
  const double r = desc_.radius, a = std::abs(t);
  switch (desc_.type) {
    case FilterType::kBox:
      return a <= 0.5 ? 1 : 0;
    case FilterType::kTent:
      return std::max(0.0, 1 - a / r);
    case FilterType::kGaussian:
      // Mitsuba subtracts the value at the radius so that the window ends at 0.
      return a >= r ? 0 : std::max(0.0, std::exp(-t * t * inv_two_var_) - bias_);
  }
  return 0;
}

double PixelFilter::Cumulative(double t) const {
  const double r = desc_.radius;
  t = std::clamp(t, -r, r);
  switch (desc_.type) {
    case FilterType::kBox:
      return t + r;
    case FilterType::kTent:
      return t <= 0 ? (t + r) * (t + r) / (2 * r) : r - (r - t) * (r - t) / (2 * r);
    case FilterType::kGaussian:
      // The antiderivative of exp(-t^2 / (2 s^2)) - bias is
      // G(t) = s sqrt(pi / 2) erf(t / (s sqrt 2)) - bias t; it is odd, so W(t) = G(t) + G(r).
      return erf_scale_ * std::erf(t * erf_arg_) - bias_ * t + g_radius_;
  }
  return 0;
}

double PixelFilter::SampleOffset(double u, double lo, double hi) const {
  const double r = desc_.radius;
  lo = std::max(lo, -r);
  hi = std::min(hi, r);
  if (!(hi > lo)) return std::clamp(0.0, lo, hi);
  // Inside the image (the common case) the bounds are the support's: W(-r) = 0, W(r) = total.
  const double w_lo = lo > -r ? Cumulative(lo) : 0, w_hi = hi < r ? Cumulative(hi) : total_;
  const double target = w_lo + u * (w_hi - w_lo);
  switch (desc_.type) {
    case FilterType::kBox:
      return lo + u * (hi - lo);
    case FilterType::kTent: {
      const double t = target <= 0.5 * r ? std::sqrt(2 * r * target) - r
                                         : r - std::sqrt(std::max(0.0, 2 * r * (r - target)));
      return std::clamp(t, lo, hi);
    }
    case FilterType::kGaussian:
      break;
  }
  // Newton's method on W(t) = target, kept inside a bracket that shrinks at every step (a step
  // that would leave it bisects instead): W is increasing with W' = Weight, which is small only
  // in the far tails. The table gives a bracket and a first guess good to ~1e-4 pixels, so it
  // takes 2 steps.
  const double f = std::clamp(target / total_ * kTable, 0.0, double(kTable));
  const int i = std::min(int(f), kTable - 1);
  double a = std::max(lo, inverse_[i]), b = std::min(hi, inverse_[i + 1]);
  if (!(b > a)) {  // the table's cell and [lo, hi] barely touch (rounding): use [lo, hi]
    a = lo;
    b = hi;
  }
  double t = std::clamp(inverse_[i] + (f - i) * (inverse_[i + 1] - inverse_[i]), a, b);
  for (int k = 0; k < 100; ++k) {
    const double e = Cumulative(t) - target;
    if (e == 0) break;
    (e > 0 ? b : a) = t;
    const double w = Weight(t);
    double next = w > 0 ? t - e / w : a - 1;
    if (!(next > a && next < b)) next = 0.5 * (a + b);
    const double step = std::abs(next - t);
    t = next;
    if (step < 1e-8) break;  // pixels: below a float's resolution of a film position (>= 1)
  }
  return std::clamp(t, lo, hi);
}

}  // namespace irfarm
