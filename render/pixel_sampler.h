// Stratified 2D points for the samples of one pixel: the Hammersley set {((k + 0.5) / n,
// radical_inverse_2(k))} rotated by a random per-pixel shift (Cranley-Patterson), so each pixel's
// n points are well spread over the unit square and still uniformly distributed as a whole
// (unbiased), and neighbouring pixels do not share a pattern.
#pragma once

#include <cstdint>

#include "render/sampling.h"

namespace irfarm {

class PixelSampler {
 public:
  PixelSampler(int n, Rng& rng) : n_(n > 0 ? n : 1), shift_u_(rng.Next()), shift_v_(rng.Next()) {}
  // The k-th point, k in [0, n).
  void Get(int k, float* u, float* v) const {
    *u = Wrap((float(k) + 0.5f) / float(n_) + shift_u_);
    *v = Wrap(RadicalInverse2(uint32_t(k)) + shift_v_);
  }
  int count() const { return n_; }

 private:
  static float RadicalInverse2(uint32_t k) {
    k = (k << 16) | (k >> 16);
    k = ((k & 0x00ff00ffu) << 8) | ((k & 0xff00ff00u) >> 8);
    k = ((k & 0x0f0f0f0fu) << 4) | ((k & 0xf0f0f0f0u) >> 4);
    k = ((k & 0x33333333u) << 2) | ((k & 0xccccccccu) >> 2);
    k = ((k & 0x55555555u) << 1) | ((k & 0xaaaaaaaau) >> 1);
    return Rng::ToUnitFloat(k);
  }
  static float Wrap(float x) {
    const float y = x >= 1 ? x - 1 : x;
    return y < 1 ? y : 0x1.fffffep-1f;
  }
  int n_;
  float shift_u_, shift_v_;
};

}  // namespace irfarm
