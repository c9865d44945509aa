// Per-pixel sample sums of the final pass, kept as two interleaved half-images (even and odd
// samples) so that each pixel's error can be estimated from the difference of its halves:
// for independent halves h0, h1 of n/2 samples each, E[(h0 - h1)^2] / 4 = Var(mean of all n).
// Besides the radiance sums, each half keeps the ratio estimator's three sums per rectangle light
// (DirectTerms, only the slots the scene uses), resolved per half and for the whole pixel.
// Samples carry a weight (1, or the film filter's weight when the final pass splats a sample into
// the pixels around it): every sum is weighted, and a pixel's value is the weighted sum over the
// sum of the weights, as Mitsuba's film divides by its weight channel.
#pragma once

#include <cstddef>
#include <vector>

#include "render/irrcache_integrator.h"

namespace irfarm {

class SampleFilm {
 public:
  SampleFilm(size_t pixels, int slots);

  // Adds sample number `index` (of the pixel it was taken for; its half is index & 1) to pixel p
  // with `weight`: radiance L and, with slots, its direct terms.
  void Add(size_t p, int index, const Vec3& L, const DirectTerms* terms, float weight = 1);
  // How many samples were added to pixel p (with any weight).
  int count(size_t p) const { return count_[p]; }
  // The pixel's estimate from all its samples, and from half h (0 even, 1 odd) alone.
  Vec3 Value(size_t p) const;
  Vec3 HalfValue(size_t p, int h) const;
  // The plain mean of the radiance samples added (without the DirectTerms' ratio part).
  Vec3 SampleMean(size_t p) const {
    const float w = weight_[2 * p] + weight_[2 * p + 1];
    return w > 0 ? (Half(p, 0)[0] + Half(p, 1)[0]) / w : Vec3();
  }
  // The contribution of pixel p's brightest sample (by luminance) to Value(p): its weighted
  // radiance over the pixel's weight sum (SpreadFireflies).
  Vec3 Peak(size_t p) const {
    const float w = weight_[2 * p] + weight_[2 * p + 1];
    return w > 0 ? peak_[p] / w : Vec3();
  }
  // Estimated squared error of Value(p), relative as relMSE weighs it:
  // mean over channels of ((h0 - h1)^2 / 4) / (max(h0 h1, 0) + 0.01). 0 unless both halves
  // have samples.
  double RelativeError(size_t p) const;

 private:
  // Layout per pixel and half: [sum, A_0, S_0, U_0, ..., A_{k-1}, S_{k-1}, U_{k-1}].
  Vec3* Half(size_t p, int h) { return &data_[(p * 2 + size_t(h)) * stride_]; }
  const Vec3* Half(size_t p, int h) const { return &data_[(p * 2 + size_t(h)) * stride_]; }
  Vec3 Resolve(const Vec3* a, const Vec3* b, float weight) const;

  int slots_;
  size_t stride_;
  std::vector<Vec3> data_;
  std::vector<float> weight_;  // per pixel and half
  std::vector<int> count_;
  std::vector<Vec3> peak_;  // per pixel: the brightest sample's weighted radiance
  std::vector<float> peak_luminance_;
};

}  // namespace irfarm
