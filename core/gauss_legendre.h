// Gauss-Legendre quadrature on [-1, 1]: the n nodes (roots of the Legendre polynomial P_n) and
// weights that integrate polynomials up to degree 2n - 1 exactly (Newton's iteration on P_n from
// the Chebyshev-like first guess cos(pi (i + 3/4) / (n + 1/2)), as in Numerical Recipes' gauleg).
// Used where Mitsuba integrates with the same nodes, so that a precomputed table matches its own.
#pragma once

#include <cmath>
#include <vector>

namespace irfarm {

struct GaussLegendreRule {
  std::vector<double> nodes, weights;  // ascending nodes in (-1, 1); weights sum to 2
};

inline GaussLegendreRule GaussLegendre(int n) {
  GaussLegendreRule r;
  r.nodes.resize(size_t(n));
  r.weights.resize(size_t(n));
  const double pi = 3.14159265358979323846;
  for (int i = 0; i < (n + 1) / 2; ++i) {
    double x = std::cos(pi * (i + 0.75) / (n + 0.5)), dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = 0;  // P_k(x), P_{k-1}(x)
      for (int k = 1; k <= n; ++k) {
        const double p2 = p1;
        p1 = p0;
        p0 = ((2 * k - 1) * x * p1 - (k - 1) * p2) / k;
      }
      dp = n * (x * p0 - p1) / (x * x - 1);  // P_n'(x)
      const double step = p0 / dp;
      x -= step;
      if (std::abs(step) < 1e-15) break;
    }
    const double w = 2 / ((1 - x * x) * dp * dp);
    r.nodes[size_t(i)] = -x;
    r.nodes[size_t(n - 1 - i)] = x;
    r.weights[size_t(i)] = r.weights[size_t(n - 1 - i)] = w;
  }
  return r;
}

}  // namespace irfarm
