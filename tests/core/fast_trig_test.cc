// core/fast_trig.h against libm in double.
#include "core/fast_trig.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>

namespace irfarm {
namespace {

// Uniform in [-1, 1): a fixed stream from `state`.
double NextUniform(uint64_t& state) {
  state = state * 6364136223846793005ull + 1442695040888963407ull;
  return double(state >> 11) / double(1ull << 52) - 1.0;
}

TEST(FastTrigTest, Atan2MatchesLibmInEveryOctant) {
  double worst = 0;
  uint64_t state = 12345;
  const auto next = [&state] { return NextUniform(state); };
  for (int i = 0; i < 1000000; ++i) {
    const double scale = std::ldexp(1.0, int(i % 40) - 20);  // magnitudes from 1e-6 to 1e6
    const double y = next() * scale, x = next() * scale * (i % 3 == 0 ? 1e-3 : 1.0);
    worst = std::max(worst, std::abs(Atan2(y, x) - std::atan2(y, x)));
  }
  std::printf("MEASURED Atan2 worst %.3g\n", worst);
  EXPECT_LT(worst, 3e-14);
  EXPECT_GT(worst, 0);
  // The axes, the diagonals and signed zeros as libm has them.
  const double cases[][2] = {{0.0, 1.0},  {0.0, -1.0},  {-0.0, -1.0}, {1.0, 0.0},
                             {-1.0, 0.0}, {0.0, 0.0},   {0.0, -0.0},  {-0.0, -0.0},
                             {1.0, 1.0},  {-1.0, -1.0}, {1.0, -1.0},  {1e-300, 1.0}};
  for (const auto& c : cases) {
    EXPECT_NEAR(Atan2(c[0], c[1]), std::atan2(c[0], c[1]), 1e-15) << c[0] << " " << c[1];
    EXPECT_EQ(std::signbit(Atan2(c[0], c[1])), std::signbit(std::atan2(c[0], c[1])))
        << c[0] << " " << c[1];
  }
}

TEST(FastTrigTest, Atan2PositiveMatchesLibm) {
  double worst = 0;
  uint64_t state = 54321;
  const auto next = [&state] { return NextUniform(state); };
  for (int i = 0; i < 1000000; ++i) {
    const double scale = std::ldexp(1.0, int(i % 40) - 20);
    const double y = std::abs(next()) * scale + 1e-300,
                 x = next() * scale * (i % 3 == 0 ? 1e-3 : 1.0);
    worst = std::max(worst, std::abs(Atan2Positive(y, x) - std::atan2(y, x)));
  }
  std::printf("MEASURED Atan2Positive worst %.3g\n", worst);
  EXPECT_LT(worst, 3e-14);
  EXPECT_GT(worst, 0);
  // The axes and the diagonals: x = 0 of either sign is pi / 2.
  const double cases[][2] = {{1.0, 0.0},   {1.0, -0.0},   {1.0, 1.0},    {1.0, -1.0},
                             {1.0, 1e300}, {1.0, -1e300}, {1e-300, 1.0}, {2.0, -1e-300}};
  for (const auto& c : cases)
    EXPECT_NEAR(Atan2Positive(c[0], c[1]), std::atan2(c[0], c[1]), 1e-15) << c[0] << " " << c[1];
}

}  // namespace
}  // namespace irfarm
