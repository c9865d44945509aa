#include "core/cdf_guide.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace irfarm {
namespace {

// Cumulative sums of n weights spread over many orders of magnitude, some of them zero (entries
// no u may land on), as a sun's sub-cells are: a few very bright, most at the floor.
std::vector<float> SkewedCdf(size_t n, std::mt19937& gen) {
  std::uniform_real_distribution<float> exponent(-6, 3), coin(0, 1);
  std::vector<float> cdf(n);
  float acc = 0;
  for (size_t i = 0; i < n; ++i) {
    acc += coin(gen) < 0.1f ? 0.0f : std::pow(10.0f, exponent(gen));
    cdf[i] = acc;
  }
  return cdf;
}

size_t Reference(const std::vector<float>& cdf, float x) {
  return size_t(std::upper_bound(cdf.begin(), cdf.end(), x) - cdf.begin());
}

// The guide must give std::upper_bound's answer for every u: random u, u at every bucket's
// boundary and the float just below it (where rounding could put u * K in the next bucket), and
// the ends of [0, 1). A guide whose buckets start one entry late fails here.
TEST(CdfGuideTest, GivesTheBinarySearchsAnswerForEveryU) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<float> uniform(0, 1);
  for (const size_t n : {size_t(1), size_t(2), size_t(7), size_t(64), size_t(10240)}) {
    for (const size_t buckets : {size_t(1), n, 4 * n + 3}) {
      const std::vector<float> cdf = SkewedCdf(n, gen);
      if (!(cdf.back() > 0)) continue;
      CdfGuide guide;
      guide.Build(cdf, buckets);
      const float total = cdf.back();
      std::vector<float> us = {0.0f, 0x1.fffffep-1f};
      for (size_t b = 0; b <= buckets; ++b) {
        const float edge = float(double(b) / double(buckets));
        us.push_back(std::min(edge, 0x1.fffffep-1f));
        us.push_back(std::nextafter(edge, 0.0f));
      }
      for (int k = 0; k < 20000; ++k) us.push_back(uniform(gen));
      size_t mismatches = 0;
      for (const float u : us) {
        if (!(u >= 0 && u < 1)) continue;
        const float x = u * total;
        mismatches += guide.UpperBound(cdf, u, x) != Reference(cdf, x);
      }
      EXPECT_EQ(mismatches, 0u) << "n " << n << " buckets " << buckets;
    }
  }
}

// The entries each u lands on, over a uniform grid of u, are drawn in proportion to their
// weights: the guide changes how the entry is found, not which.
TEST(CdfGuideTest, EntriesAreDrawnByTheirWeights) {
  const std::vector<float> weights = {0.5f, 0.0f, 3.0f, 1e-3f, 0.0f, 2.5f, 4.0f};
  std::vector<float> cdf;
  float acc = 0;
  for (float w : weights) cdf.push_back(acc += w);
  CdfGuide guide;
  guide.Build(cdf, cdf.size());
  std::vector<double> count(weights.size(), 0);
  constexpr int kSteps = 1 << 20;
  for (int s = 0; s < kSteps; ++s) {
    const float u = (float(s) + 0.5f) / float(kSteps);
    const size_t k = guide.UpperBound(cdf, u, u * acc);
    ASSERT_LT(k, weights.size());
    count[k] += 1;
  }
  for (size_t k = 0; k < weights.size(); ++k)
    EXPECT_NEAR(count[k] / kSteps, weights[k] / acc, 2.0 / kSteps + 1e-6) << "entry " << k;
}

}  // namespace
}  // namespace irfarm
