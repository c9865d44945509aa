// Tests of render/sampling.h: chi-square goodness-of-fit of the (stratified) cosine hemisphere
// warps against cos(theta)/pi, a wrong sampler that must fail the same test, the stratified
// irradiance estimator on integrands with known integrals, the other warps, and PCG32.
#include "render/sampling.h"

#include <gtest/gtest.h>

#include "tests/render/chi_square.h"

#include <cmath>
#include <cstdint>
#include <functional>
#include <set>
#include <vector>

namespace irfarm {
namespace {

constexpr double kSignificance = 1e-3;  // chance that a correct sampler fails a chi-square test
constexpr int kCos2Bins = 10, kPhiBins = 20;

// Chi-square statistic of `n` local directions against cos(theta)/pi. Under that density,
// cos^2(theta) = 1 - sin^2(theta) is uniform on [0, 1] and phi uniform on [0, 2 pi), so a
// 10 x 20 grid of (cos^2 theta, phi) cells has equal expected counts n / 200.
double CosineChiSquare(int n, const std::function<Vec3(int)>& sample) {
  std::vector<int> counts(kCos2Bins * kPhiBins, 0);
  for (int i = 0; i < n; ++i) {
    const Vec3 d = sample(i);
    float phi = std::atan2(d.y, d.x);
    if (phi < 0) phi += 2 * kPi;
    const int a = std::min(int(d.z * d.z * kCos2Bins), kCos2Bins - 1);
    const int b = std::min(int(phi / (2 * kPi) * kPhiBins), kPhiBins - 1);
    ++counts[a * kPhiBins + b];
  }
  const double expected = double(n) / counts.size();
  double chi2 = 0;
  for (int c : counts) chi2 += (c - expected) * (c - expected) / expected;
  return chi2;
}

TEST(ChiSquareTest, ChiSquareCriticalMatchesTables) {
  // Upper 0.1% points from standard tables (e.g. NIST/SEMATECH handbook 1.3.6.7.4).
  EXPECT_NEAR(ChiSquareCritical(100, 1e-3), 149.449, 0.5);
  EXPECT_NEAR(ChiSquareCritical(50, 1e-3), 86.661, 0.5);
  EXPECT_NEAR(NormalUpperQuantile(1e-3), 3.0902, 1e-3);
}

TEST(SamplingTest, CosineHemisphereMatchesCosineDensity) {
  Rng rng(1, 2);
  const double chi2 = CosineChiSquare(200000, [&](int) {
    const float u = rng.Next();
    return CosineHemisphere(u, rng.Next());
  });
  EXPECT_LT(chi2, ChiSquareCritical(kCos2Bins * kPhiBins - 1, kSignificance));
}

// All strata in turn, each with random (u, v). T x P = 7 x 22 is deliberately not aligned with
// the bins, so each bin collects parts of several strata.
TEST(SamplingTest, StratifiedCosineHemisphereMatchesCosineDensity) {
  constexpr int kT = 7, kP = 22;
  Rng rng(3, 4);
  const double chi2 = CosineChiSquare(kT * kP * 1300, [&](int i) {
    const float u = rng.Next();
    return StratifiedCosineHemisphere((i / kP) % kT, i % kP, kT, kP, u, rng.Next());
  });
  EXPECT_LT(chi2, ChiSquareCritical(kCos2Bins * kPhiBins - 1, kSignificance));
}

// Directions uniform over the hemisphere (pdf 1 / (2 pi)) are a plausible-looking but wrong
// stand-in; the test above must be able to tell.
TEST(SamplingTest, UniformHemisphereFailsCosineChiSquare) {
  Rng rng(5, 6);
  const double chi2 = CosineChiSquare(200000, [&](int) {
    const float z = rng.Next();
    const float r = std::sqrt(std::max(0.0f, 1 - z * z)), phi = 2 * kPi * rng.Next();
    return Vec3(r * std::cos(phi), r * std::sin(phi), z);
  });
  EXPECT_GT(chi2, ChiSquareCritical(kCos2Bins * kPhiBins - 1, kSignificance));
}

TEST(SamplingTest, StratifiedSampleStaysInItsStratum) {
  constexpr int kT = 5, kP = 9;
  const float kAlmostOne = 1 - std::ldexp(1.0f, -24);
  for (int t = 0; t < kT; ++t) {
    for (int p = 0; p < kP; ++p) {
      for (float u : {0.0f, 0.5f, kAlmostOne}) {
        for (float v : {0.0f, 0.5f, kAlmostOne}) {
          const Vec3 d = StratifiedCosineHemisphere(t, p, kT, kP, u, v);
          EXPECT_NEAR(Length(d), 1.0f, 1e-6f);
          EXPECT_GE(d.z, 0.0f);
          const float sin2 = 1 - d.z * d.z;
          EXPECT_GE(sin2, float(t) / kT - 1e-6f);
          EXPECT_LE(sin2, float(t + 1) / kT + 1e-6f);
          if (sin2 < 1e-6f) continue;  // the pole (t = 0, u = 0) has no azimuth
          // Angular distance from the stratum's centre, wrapped into [-pi, pi].
          const float centre = 2 * kPi * (p + 0.5f) / kP;
          const float dphi = std::remainder(std::atan2(d.y, d.x) - centre, 2 * kPi);
          EXPECT_LE(std::abs(dphi), kPi / kP + 1e-5f);
        }
      }
    }
  }
}

// E = pi / (T P) sum L over one sample per stratum estimates integral L cos dw.
double StratifiedEstimate(int T, int P, Rng* rng, const std::function<double(const Vec3&)>& L) {
  double sum = 0;
  for (int t = 0; t < T; ++t) {
    for (int p = 0; p < P; ++p) {
      const float u = rng->Next();
      sum += L(StratifiedCosineHemisphere(t, p, T, P, u, rng->Next()));
    }
  }
  return kPi * sum / (T * P);
}

TEST(SamplingTest, StratifiedEstimatorIntegratesKnownIntegrands) {
  Rng rng(7, 8);
  // L = 1: E = pi, exactly, whatever the samples.
  EXPECT_NEAR(StratifiedEstimate(16, 50, &rng, [](const Vec3&) { return 1.0; }), kPi, 1e-6);
  // L = cos(theta): integral cos^2 dw = 2 pi / 3. Unstratified, 800 cosine samples would have a
  // standard error of pi * sqrt(Var[cos] / 800) = pi * sqrt((1/2 - 4/9) / 800) ~ 0.026; the
  // 16 elevation strata must do much better (~0.004), and the estimator must be unbiased.
  constexpr int kTrials = 200;
  double sum_err = 0, sum_err2 = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    const double err =
        StratifiedEstimate(16, 50, &rng, [](const Vec3& d) { return double(d.z); }) - 2 * kPi / 3;
    sum_err += err;
    sum_err2 += err * err;
  }
  const double rms = std::sqrt(sum_err2 / kTrials);
  EXPECT_LT(rms, 0.026 / 3);
  EXPECT_NEAR(sum_err / kTrials, 0.0, 5 * rms / std::sqrt(double(kTrials)));
}

TEST(SamplingTest, OtherWarps) {
  Rng rng(9, 10);
  double mean_z = 0, mean_b0 = 0, mean_b1 = 0;
  constexpr int kN = 100000;
  for (int i = 0; i < kN; ++i) {
    const float u = rng.Next(), v = rng.Next();
    const Vec3 s = UniformSphere(u, v);
    EXPECT_NEAR(Length(s), 1.0f, 1e-5f);
    mean_z += s.z;
    const Vec3 c = UniformCone(u, v, 0.8f);
    EXPECT_NEAR(Length(c), 1.0f, 1e-5f);
    EXPECT_GE(c.z, 0.8f - 1e-6f);
    float b0, b1;
    UniformTriangle(u, v, &b0, &b1);
    EXPECT_GE(b0, 0.0f);
    EXPECT_GE(b1, 0.0f);
    EXPECT_LE(b0 + b1, 1.0f + 1e-6f);
    mean_b0 += b0;
    mean_b1 += b1;
  }
  // Means of uniform distributions: z on the sphere 0, barycentrics 1/3 (standard errors ~2e-3
  // and ~7e-4; tolerances are 5 sigma).
  EXPECT_NEAR(mean_z / kN, 0.0, 1e-2);
  EXPECT_NEAR(mean_b0 / kN, 1.0 / 3, 4e-3);
  EXPECT_NEAR(mean_b1 / kN, 1.0 / 3, 4e-3);

  EXPECT_FLOAT_EQ(PowerHeuristic(1, 1), 0.5f);
  EXPECT_FLOAT_EQ(PowerHeuristic(3, 1), 0.9f);
  EXPECT_FLOAT_EQ(PowerHeuristic(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(PowerHeuristic(INFINITY, 5), 1.0f);
}

TEST(RngTest, MatchesPcg32Reference) {
  // First outputs of pcg32_srandom_r(&rng, 42, 54) in the PCG reference's pcg32-demo.
  Rng rng(42, 54);
  const uint32_t expected[] = {0xa15c02b7, 0x7b47f409, 0xba1d3330,
                               0x83d2f293, 0xbfa4784b, 0xcbed606e};
  for (uint32_t e : expected) EXPECT_EQ(rng.NextU32(), e);
}

TEST(RngTest, DeterministicPerSeedAndStream) {
  Rng a(123, 7), b(123, 7), c(123, 8), d(124, 7);
  int same_c = 0, same_d = 0;
  for (int i = 0; i < 1000; ++i) {
    const uint32_t x = a.NextU32();
    EXPECT_EQ(x, b.NextU32());
    same_c += x == c.NextU32();
    same_d += x == d.NextU32();
  }
  EXPECT_LT(same_c, 3);
  EXPECT_LT(same_d, 3);
}

TEST(RngTest, NextIsInUnitIntervalAndUniform) {
  EXPECT_EQ(Rng::ToUnitFloat(0), 0.0f);
  EXPECT_LT(Rng::ToUnitFloat(0xFFFFFFFFu), 1.0f);
  Rng rng(11, 12);
  constexpr int kBins = 100, kN = 1000000;
  std::vector<int> counts(kBins, 0);
  for (int i = 0; i < kN; ++i) {
    const float x = rng.Next();
    ASSERT_GE(x, 0.0f);
    ASSERT_LT(x, 1.0f);
    ++counts[int(x * kBins)];
  }
  const double expected = double(kN) / kBins;
  double chi2 = 0;
  for (int c : counts) chi2 += (c - expected) * (c - expected) / expected;
  EXPECT_LT(chi2, ChiSquareCritical(kBins - 1, kSignificance));
}

TEST(RngTest, HashCombineIsDeterministicAndOrderDependent) {
  EXPECT_EQ(HashCombine(1, 2), HashCombine(1, 2));
  EXPECT_NE(HashCombine(1, 2), HashCombine(2, 1));
  // Neighbouring pixels get distinct streams.
  std::set<uint64_t> seen;
  for (uint64_t pixel = 0; pixel < 10000; ++pixel) seen.insert(HashCombine(42, pixel));
  EXPECT_EQ(seen.size(), 10000u);
}

}  // namespace
}  // namespace irfarm
