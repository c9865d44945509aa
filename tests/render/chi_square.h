// Chi-square helpers shared by the sampler tests: the critical value of a chi-square statistic
// at a significance level, and the statistic of observed counts against expected counts.
#pragma once

#include <cmath>
#include <vector>

namespace irfarm {

// z such that P(Z > z) = alpha for a standard normal Z, by bisection on erfc.
inline double NormalUpperQuantile(double alpha) {
  double lo = -10, hi = 10;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(mid / std::sqrt(2.0)) > alpha ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Critical value c with P(chi^2_k > c) = alpha, by the Wilson-Hilferty approximation:
// (chi^2_k / k)^(1/3) is nearly normal with mean 1 - 2/(9k) and variance 2/(9k). Accurate to
// well under 1% for k >= 30 at alpha = 1e-3 (see ChiSquareCriticalMatchesTables).
inline double ChiSquareCritical(int k, double alpha) {
  const double h = 2.0 / (9.0 * k);
  return k * std::pow(1 - h + NormalUpperQuantile(alpha) * std::sqrt(h), 3);
}

// Pearson's statistic; cells expecting fewer than 5 are pooled into one (the usual rule, so the
// chi-square approximation holds). *dof receives the degrees of freedom (cells - 1).
inline double ChiSquareStatistic(const std::vector<double>& observed,
                                 const std::vector<double>& expected, int* dof) {
  double chi2 = 0, pooled_obs = 0, pooled_exp = 0;
  int cells = 0;
  for (size_t i = 0; i < observed.size(); ++i) {
    if (expected[i] < 5) {
      pooled_obs += observed[i];
      pooled_exp += expected[i];
      continue;
    }
    chi2 += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
    ++cells;
  }
  if (pooled_exp >= 5) {
    chi2 += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
    ++cells;
  }
  *dof = cells - 1;
  return chi2;
}

}  // namespace irfarm
