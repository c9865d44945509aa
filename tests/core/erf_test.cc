// core/erf.h against libm's double-precision erf: the published bound of Abramowitz and Stegun
// 7.1.26 (1.5e-7 absolute) and a single-precision inverse, each widened by the rounding of a
// float evaluation (a few ulps of 1, 6e-8 each): 1e-6 absolute for Erf, 1e-6 relative for
// ErfInv, over their whole ranges and up to 1e-7 from +-1.
#include "core/erf.h"

#include <gtest/gtest.h>

#include <cmath>

namespace irfarm {
namespace {

// erf^-1 in double by bisection on std::erf.
double ReferenceErfInv(double z) {
  double lo = -10, hi = 10;
  for (int i = 0; i < 200; ++i) {
    const double m = 0.5 * (lo + hi);
    (std::erf(m) < z ? lo : hi) = m;
  }
  return 0.5 * (lo + hi);
}

TEST(ErfTest, ErfAndErfcWithinTheirBoundEverywhere) {
  double worst = 0;
  for (int i = -80000; i <= 80000; ++i) {
    const float x = float(i) * 1e-4f;
    worst = std::max(worst, std::abs(double(Erf(x)) - std::erf(double(x))));
    EXPECT_NEAR(Erfc(x), std::erfc(double(x)), 1e-6) << x;
  }
  EXPECT_LT(worst, 1e-6);
  EXPECT_EQ(Erf(0), Erf(-0.0f));
  EXPECT_NEAR(Erf(3), 0.999977909503, 1e-6);
}

TEST(ErfTest, ErfInvIsTheInverseToSinglePrecision) {
  double worst = 0;
  for (int i = 1; i < 200000; ++i) {
    const float z = float(-1 + 2.0 * i / 200000);
    if (!(std::abs(z) < 1) || z == 0) continue;
    const double ref = ReferenceErfInv(z);
    worst = std::max(worst, std::abs(ErfInv(z) - ref) / std::abs(ref));
  }
  for (int k = 1; k <= 7; ++k) {  // the tails, where the second polynomial takes over
    for (float s : {-1.0f, 1.0f}) {
      const float z = s * float(1 - std::pow(10.0, -k));
      const double ref = ReferenceErfInv(z);
      worst = std::max(worst, std::abs(ErfInv(z) - ref) / std::abs(ref));
    }
  }
  EXPECT_LT(worst, 1e-6);
  EXPECT_EQ(ErfInv(0), 0);
  EXPECT_TRUE(std::isinf(ErfInv(1)));
}

}  // namespace
}  // namespace irfarm
