// Stratified 2D points for the samples of one pixel, in a progressive order, as two independent
// interleaved sets: even samples k = 2m and odd samples k = 2m + 1 each take point m of the
// (0,2)-sequence (van der Corput in u, the second Sobol' dimension in v), rotated by a random
// shift of their own (Cranley-Patterson). Every prefix of 2^j points of each set is stratified
// (one point in each of 2^j elementary intervals of any shape), so a pixel that gets more
// samples in later adaptive rounds stays well stratified; the shifts keep each set uniformly
// distributed (unbiased) and neighbouring pixels from sharing a pattern. The two sets are
// independent randomisations, so the difference of the half-images they make estimates the
// pixel's error (SampleFilm); one sequence split by parity would not (its even points all lie
// in the left half of the pixel).
#pragma once

#include <cstdint>

#include "render/sampling.h"

namespace irfarm {

class PixelSampler {
 public:
  PixelSampler(int n, Rng& rng) : n_(n > 0 ? n : 1) {
    for (int h = 0; h < 2; ++h) {
      shift_u_[h] = rng.Next();
      shift_v_[h] = rng.Next();
    }
  }
  // The k-th point, k >= 0 (any k; n is only the caller's planned count).
  void Get(int k, float* u, float* v) const {
    const uint32_t m = uint32_t(k) >> 1;
    const int h = k & 1;
    *u = Wrap(Rng::ToUnitFloat(ReverseBits(m)) + shift_u_[h]);
    *v = Wrap(Rng::ToUnitFloat(Sobol2(m)) + shift_v_[h]);
  }
  int count() const { return n_; }

 private:
  static uint32_t ReverseBits(uint32_t k) {
    k = (k << 16) | (k >> 16);
    k = ((k & 0x00ff00ffu) << 8) | ((k & 0xff00ff00u) >> 8);
    k = ((k & 0x0f0f0f0fu) << 4) | ((k & 0xf0f0f0f0u) >> 4);
    k = ((k & 0x33333333u) << 2) | ((k & 0xccccccccu) >> 2);
    return ((k & 0x55555555u) << 1) | ((k & 0xaaaaaaaau) >> 1);
  }
  // Second dimension of Sobol's sequence (generator matrix with v_{j+1} = v_j ^ (v_j >> 1)).
  static uint32_t Sobol2(uint32_t k) {
    uint32_t r = 0;
    for (uint32_t v = 1u << 31; k; k >>= 1, v ^= v >> 1)
      if (k & 1) r ^= v;
    return r;
  }
  static float Wrap(float x) {
    const float y = x >= 1 ? x - 1 : x;
    return y < 1 ? y : 0x1.fffffep-1f;
  }
  int n_;
  float shift_u_[2], shift_v_[2];
};

}  // namespace irfarm
