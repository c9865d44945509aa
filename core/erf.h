// The error function and its inverse in single precision, for the samplers' inner loops (the
// Beckmann distribution's visible slopes and masking), where libm's double erf, called dozens of
// times per sample, was a tenth of a glossy scene's CPU.
//   Erfc: Abramowitz and Stegun 7.1.26, erfc(x) = t (a1 + t (a2 + ...)) exp(-x^2) with
//         t = 1 / (1 + p x) for x >= 0 (absolute error <= 1.5e-7); erfc(-x) = 2 - erfc(x).
//   ErfInv: Giles 2010, "Approximating the erfinv function" (GPU Computing Gems), its
//         single-precision polynomials in w = -log((1 - x)(1 + x)).
// tests/core/erf_test.cc checks both against libm in double over their whole ranges.
#pragma once

#include <cmath>

namespace irfarm {

// exp(x^2) erfc(x) for x >= 0: erfc(x) without its Gaussian factor, for callers that have
// exp(-x^2) already.
inline float ScaledErfc(float x) {
  const float t = 1 / (1 + 0.3275911f * x);
  return t * (0.254829592f +
              t * (-0.284496736f + t * (1.421413741f + t * (-1.453152027f + t * 1.061405429f))));
}

// erfc(x) = 1 - erf(x).
inline float Erfc(float x) {
  const float ax = std::abs(x);
  const float r = ScaledErfc(ax) * std::exp(-ax * ax);
  return x >= 0 ? r : 2 - r;
}

inline float Erf(float x) { return 1 - Erfc(x); }

// erf^-1(x) for x in (-1, 1); +-infinity at +-1.
inline float ErfInv(float x) {
  float w = -std::log((1 - x) * (1 + x)), p;
  if (w < 5) {
    w -= 2.5f;
    p = 2.81022636e-08f;
    p = 3.43273939e-07f + p * w;
    p = -3.5233877e-06f + p * w;
    p = -4.39150654e-06f + p * w;
    p = 0.00021858087f + p * w;
    p = -0.00125372503f + p * w;
    p = -0.00417768164f + p * w;
    p = 0.246640727f + p * w;
    p = 1.50140941f + p * w;
  } else {
    w = std::sqrt(w) - 3;
    p = -0.000200214257f;
    p = 0.000100950558f + p * w;
    p = 0.00134934322f + p * w;
    p = -0.00367342844f + p * w;
    p = 0.00573950773f + p * w;
    p = -0.0076224613f + p * w;
    p = 0.00943887047f + p * w;
    p = 1.00167406f + p * w;
    p = 2.83297682f + p * w;
  }
  return p * x;
}

}  // namespace irfarm
