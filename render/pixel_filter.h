// The film's reconstruction filter (FilterDesc, Mitsuba 3's box, tent and gaussian): its weights
// and where camera samples land.
// The final pass splats (render/final_pass.cc, SplatReach): a sample lands uniformly in its pixel
// and is added to every pixel whose centre its filter reaches, with weight w(dx) w(dy); a pixel
// is the weighted sum over the sum of weights, as Mitsuba's film divides by its weight channel.
// Samples added to one pixel only (adaptive rounds, the pilot, filters too wide to splat) are
// placed by FilmPoint instead: filter importance sampling, as pbrt-v4 does. Each sample's film
// point is drawn from the pixel's own normalised filter and counted with weight 1 for that
// pixel: the same expected value (the filter-weighted average of the radiance around the
// pixel's centre), with the variance of that pixel's samples alone. Both axes are drawn by
// inverting the filter's 1D distribution function, truncated to the image as Mitsuba's film
// truncates it (it samples only inside the image), so a monotone warp keeps stratified (u, v)
// stratified. Box gives exactly px + u, as before filters.
#pragma once

#include <array>
#include <cmath>

#include "render/scene_desc.h"

namespace irfarm {

class PixelFilter {
 public:
  PixelFilter() = default;  // box over a 1 x 1 image
  // The filter of a width x height image (the crop window, in pixels).
  PixelFilter(const FilterDesc& desc, int width, int height);

  // The film point (x, y) (pixels, row 0 at the top) of the camera sample (u, v) in [0, 1)^2 of
  // pixel (px, py). Its density is w(x - px - 0.5) w(y - py - 0.5) normalised over the image.
  void FilmPoint(int px, int py, float u, float v, float* x, float* y) const {
    if (desc_.type == FilterType::kBox) {
      *x = u + float(px);
      *y = v + float(py);
      return;
    }
    *x = float(double(px) + 0.5 + Offset(u, px, width_));
    *y = float(double(py) + 0.5 + Offset(v, py, height_));
  }

  // Mitsuba's 1D weight w(t) at offset t (pixels) from a pixel's centre; 0 outside the support.
  double Weight(double t) const;
  // An offset t in [lo, hi] (lo <= 0 <= hi) with density proportional to Weight(t) there, by the
  // inverse distribution function at u in [0, 1). [lo, hi] is clipped to the support.
  double SampleOffset(double u, double lo, double hi) const;

  // The final pass splats (render/final_pass.cc): each camera sample lands uniformly in its own
  // pixel and is added, with weight Weight(dx) Weight(dy), to every pixel whose centre its filter
  // reaches, as Mitsuba's film does. That averages each pixel over about 1 / SplatVarianceFactor
  // times the samples (3.1x for the gaussian, 2.25x for the tent) where FilmPoint's one-pixel
  // estimate has the same mean and the variance of its own samples only. SplatReach: how many
  // pixels around its own a sample reaches, 1 for the tent and 2 for the gaussian; 0 for box (a
  // sample stays in its pixel) and for filters wider than kMaxSplatReach, whose samples are
  // placed by FilmPoint instead (splatting costs (2 reach + 1)^2 adds per sample).
  static constexpr int kMaxSplatReach = 4;
  int SplatReach() const {
    if (desc_.type == FilterType::kBox) return 0;
    const int g = int(std::ceil(reach()));
    return g <= kMaxSplatReach ? g : 0;
  }
  // sum(w_i^2) / sum(w_i)^2 of the splat weights for samples spread uniformly at one per unit of
  // area: the variance of a splatted pixel over that of a mean of one pixel's samples
  // (1 without splatting).
  double SplatVarianceFactor() const { return splat_variance_factor_; }
  // The weight, times its filter weights, that makes a splatted sample count as one sample of a
  // pixel's own (FilmPoint): its pixels' sums of weights are then, on average, the number of
  // FilmPoint samples of the same variance (n / SplatVarianceFactor for n samples per pixel), so
  // the two kinds of samples mix in one weighted mean. 1 without splatting.
  double SplatSampleWeight() const { return splat_sample_weight_; }

  const FilterDesc& desc() const { return desc_; }
  // How far (pixels) beyond its own square a pixel's samples can land: 0 for box.
  float reach() const { return desc_.type == FilterType::kBox ? 0.0f : desc_.radius - 0.5f; }

 private:
  // Offset of pixel p's sample along an axis of n pixels: the filter truncated to [0, n].
  double Offset(float u, int p, int n) const {
    const double c = double(p) + 0.5;
    return SampleOffset(double(u), -c, double(n) - c);
  }
  // W(t): the integral of Weight from -radius to t, for |t| <= radius.
  double Cumulative(double t) const;

  FilterDesc desc_{FilterType::kBox, 0.5f, 0.5f};
  int width_ = 1, height_ = 1;
  // gaussian: the inverse of W at kTable + 1 equally spaced values from 0 to W(radius), the
  // bracket and first guess of the Newton iteration that inverts W exactly.
  static constexpr int kTable = 128;
  std::array<double, kTable + 1> inverse_{};
  double total_ = 1;                                            // W(radius)
  double splat_variance_factor_ = 1, splat_sample_weight_ = 1;  // 1 without splatting
  // gaussian: 1 / (2 stddev^2), the weight at the radius (exp(-8)) that Mitsuba subtracts, and
  // G(t) = erf_scale_ erf(erf_arg_ t) - bias_ t, W(t) = G(t) + g_radius_.
  double inv_two_var_ = 2, bias_ = 0, erf_scale_ = 0, erf_arg_ = 0, g_radius_ = 0;
};

}  // namespace irfarm
