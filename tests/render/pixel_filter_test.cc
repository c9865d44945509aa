// Tests of render/pixel_filter.h: the filters' weights against Mitsuba 3's own evaluation, the
// sampled film offsets against the filters' normalised weights (chi-square, as the hemisphere
// samplers are tested in sampling_test.cc), truncated to the image at its borders, a wrong
// sampler that must fail the same test, stratification kept by the warp, and box unchanged.
#include "render/pixel_filter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "render/pixel_sampler.h"
#include "render/sampling.h"
#include "tests/render/chi_square.h"

namespace irfarm {
namespace {

constexpr double kSignificance = 1e-3;  // chance that a correct sampler fails a chi-square test

FilterDesc Gaussian(float stddev) { return FilterDesc{FilterType::kGaussian, 4 * stddev, stddev}; }
FilterDesc Tent(float radius) { return FilterDesc{FilterType::kTent, radius, 0.5f}; }

// The integral of the filter's weight over [a, b], by Simpson's rule on 64 panels: the test's own
// integration of the weights, independent of the sampler's distribution function.
double WeightIntegral(const PixelFilter& f, double a, double b) {
  constexpr int kPanels = 64;
  const double h = (b - a) / kPanels;
  double sum = f.Weight(a) + f.Weight(b);
  for (int i = 1; i < kPanels; ++i) sum += (i % 2 ? 4 : 2) * f.Weight(a + i * h);
  return sum * h / 3;
}

// Chi-square statistic of n offsets sample(i) against the filter's weights normalised over
// [lo, hi], in `bins` equal bins; *dof receives the degrees of freedom.
double OffsetChiSquare(const PixelFilter& f, double lo, double hi, int n, int bins,
                       const std::function<double(int)>& sample, int* dof) {
  std::vector<double> observed(bins, 0), expected(bins, 0);
  const double total = WeightIntegral(f, lo, hi);
  for (int b = 0; b < bins; ++b) {
    const double a = lo + (hi - lo) * b / bins, c = lo + (hi - lo) * (b + 1) / bins;
    expected[b] = n * WeightIntegral(f, a, c) / total;
  }
  for (int i = 0; i < n; ++i) {
    const double t = sample(i);
    EXPECT_GE(t, lo);
    EXPECT_LE(t, hi);
    const int b = std::clamp(int((t - lo) / (hi - lo) * bins), 0, bins - 1);
    ++observed[b];
  }
  return ChiSquareStatistic(observed, expected, dof);
}

// Mitsuba 3.9.1's own values (mi.load_dict({'type': 'gaussian', 'stddev': s}).eval(t) and
// {'type': 'tent', 'radius': r}.eval(t), scalar_rgb and llvm_ad_rgb alike; radius() gave 2.0 for
// the default gaussian, i.e. 4 stddev). Mitsuba's CPU variants evaluate the gaussian's exp through
// a degree-9 polynomial fit (rfilters/gaussian.cpp): over the whole support it is within 4.2e-4 of
// exp(-t^2 / (2 stddev^2)) - exp(-8), the filter it documents and irfarm uses (measured at 40001
// points for stddev 0.5 and 0.3; the normalised 1D filters differ by 1.3e-4 in total variation, so
// a pixel differs by at most 2.7e-4 of the radiance range under its filter). Tent is exact.
TEST(PixelFilterTest, WeightsMatchMitsuba) {
  constexpr double kFit = 5e-4;  // Mitsuba's polynomial against the exact gaussian (above)
  const PixelFilter g(Gaussian(0.5f), 64, 64);
  EXPECT_FLOAT_EQ(g.desc().radius, 2.0f);
  EXPECT_NEAR(g.Weight(0), 0.9992471, kFit);
  EXPECT_NEAR(g.Weight(0.3), 0.8350478, kFit);
  EXPECT_NEAR(g.Weight(-0.75), 0.3242426, kFit);
  EXPECT_NEAR(g.Weight(1.5), 0.01075821, kFit);
  EXPECT_NEAR(g.Weight(1.99), 2.97375e-05, kFit);
  EXPECT_EQ(g.Weight(2.01), 0);
  const PixelFilter g3(Gaussian(0.3f), 64, 64);
  EXPECT_NEAR(g3.Weight(0.3), 0.60644, kFit);
  EXPECT_NEAR(g3.Weight(-0.75), 0.04362074, kFit);
  EXPECT_EQ(g3.Weight(1.5), 0);
  const PixelFilter t(Tent(1), 64, 64);
  EXPECT_NEAR(t.Weight(0.25), 0.75, 1e-7);
  EXPECT_NEAR(t.Weight(-0.9), 0.1, 1e-7);
  EXPECT_EQ(t.Weight(1.1), 0);
  const PixelFilter t15(Tent(1.5f), 64, 64);
  EXPECT_NEAR(t15.Weight(0.6), 0.6, 1e-7);
}

struct OffsetCase {
  std::string name;
  FilterDesc desc;
  int pixel, size;  // pixel index along an axis of `size` pixels
};

// Offsets of pixels inside the image and at its borders (where the filter is cut at the image's
// edge, as Mitsuba's film cuts it), against the weights over the part of the support inside.
TEST(PixelFilterTest, OffsetsFollowTheNormalisedFilter) {
  const std::vector<OffsetCase> cases = {
      {"gaussian 0.5 inside", Gaussian(0.5f), 10, 32},
      {"gaussian 0.5 first pixel", Gaussian(0.5f), 0, 32},
      {"gaussian 0.5 second pixel", Gaussian(0.5f), 1, 32},
      {"gaussian 0.5 last pixel", Gaussian(0.5f), 31, 32},
      {"gaussian 0.5 one-pixel image", Gaussian(0.5f), 0, 1},
      {"gaussian 0.3 inside", Gaussian(0.3f), 5, 32},
      {"gaussian 1.5 inside", Gaussian(1.5f), 20, 40},
      {"tent 1 inside", Tent(1), 3, 8},
      {"tent 1 first pixel", Tent(1), 0, 8},
      {"tent 1.5 last pixel", Tent(1.5f), 7, 8},
      {"tent 0.3 inside", Tent(0.3f), 3, 8},
  };
  constexpr int kN = 200000, kBins = 50;
  for (const OffsetCase& c : cases) {
    SCOPED_TRACE(c.name);
    const PixelFilter f(c.desc, c.size, c.size);
    const double centre = c.pixel + 0.5;
    const double lo = std::max(-double(c.desc.radius), -centre);
    const double hi = std::min(double(c.desc.radius), c.size - centre);
    Rng rng(11, uint64_t(c.pixel));
    int dof = 0;
    // Through FilmPoint, as the renderer calls it: the offset from the pixel's centre along x.
    const double chi2 = OffsetChiSquare(
        f, lo, hi, kN, kBins,
        [&](int) {
          float x, y;
          f.FilmPoint(c.pixel, c.pixel, rng.Next(), rng.Next(), &x, &y);
          EXPECT_GE(y, 0.0f);
          EXPECT_LE(y, float(c.size));
          return double(x) - centre;
        },
        &dof);
    EXPECT_GE(dof, 20);
    EXPECT_LT(chi2, ChiSquareCritical(dof, kSignificance)) << "dof " << dof;
  }
}

// Plausible but wrong offsets must fail the same test: the gaussian's offsets cut at 3 instead of
// 4 standard deviations (what a careless reading of the radius gives), offsets that ignore the
// image border (samples outside the image, then clamped), and uniform offsets over the support.
TEST(PixelFilterTest, WrongOffsetsFailChiSquare) {
  constexpr int kN = 200000, kBins = 50;
  const PixelFilter f(Gaussian(0.5f), 32, 32);
  const PixelFilter narrow(FilterDesc{FilterType::kGaussian, 1.5f, 0.5f}, 32, 32);
  Rng rng(12, 1);
  int dof = 0;
  double chi2 = OffsetChiSquare(
      f, -2, 2, kN, kBins, [&](int) { return narrow.SampleOffset(rng.Next(), -2, 2); }, &dof);
  EXPECT_GT(chi2, ChiSquareCritical(dof, kSignificance));
  // Pixel 0: the right distribution is cut at -0.5; samples drawn over the whole support and
  // clamped to the image pile up at the edge.
  chi2 = OffsetChiSquare(
      f, -0.5, 2, kN, kBins, [&](int) { return std::max(-0.5, f.SampleOffset(rng.Next(), -2, 2)); },
      &dof);
  EXPECT_GT(chi2, ChiSquareCritical(dof, kSignificance));
  chi2 = OffsetChiSquare(
      f, -2, 2, kN, kBins, [&](int) { return -2 + 4.0 * rng.Next(); }, &dof);
  EXPECT_GT(chi2, ChiSquareCritical(dof, kSignificance));
}

// The warp is monotone in u and spans [lo, hi], so stratified (u, v) stay stratified: the
// renderer's PixelSampler points (a (0,2)-sequence per half) give offsets whose histogram is
// closer to the expected one than independent points would be.
TEST(PixelFilterTest, WarpIsMonotoneAndKeepsStratification) {
  for (const FilterDesc& d : {Gaussian(0.5f), Gaussian(0.2f), Tent(1), Tent(2.5f)}) {
    const PixelFilter f(d, 16, 16);
    const double r = d.radius;
    EXPECT_NEAR(f.SampleOffset(0, -r, r), -r, 1e-9);
    EXPECT_NEAR(f.SampleOffset(1, -r, r), r, 1e-9);
    EXPECT_NEAR(f.SampleOffset(0.5, -r, r), 0, 1e-9);  // symmetric filters
    double previous = -r;
    for (int i = 0; i <= 4096; ++i) {
      const double t = f.SampleOffset(i / 4096.0, -r, 0.7 * r);
      EXPECT_GE(t, previous - 1e-12);
      previous = t;
    }
    EXPECT_NEAR(previous, 0.7 * r, 1e-9);
  }
  const PixelFilter f(Gaussian(0.5f), 64, 64);
  Rng rng(13, 1);
  const PixelSampler sampler(4096, rng);
  int dof = 0;
  const double chi2 = OffsetChiSquare(
      f, -2, 2, 4096, 32,
      [&](int i) {
        float u, v, x, y;
        sampler.Get(i, &u, &v);
        f.FilmPoint(20, 20, u, v, &x, &y);
        return double(x) - 20.5;
      },
      &dof);
  // Independent points would give about dof; a stratified set far less.
  EXPECT_LT(chi2, 0.25 * dof);
}

// Box: exactly the film point the renderer used before filters (bit-identical images).
TEST(PixelFilterTest, BoxIsThePixelSquare) {
  const PixelFilter f(FilterDesc{FilterType::kBox, 0.5f, 0.5f}, 40, 30);
  Rng rng(14, 1);
  for (int i = 0; i < 1000; ++i) {
    const float u = rng.Next(), v = rng.Next();
    const int px = i % 40, py = i % 30;
    float x, y;
    f.FilmPoint(px, py, u, v, &x, &y);
    EXPECT_EQ(x, u + float(px));
    EXPECT_EQ(y, v + float(py));
  }
  EXPECT_EQ(f.reach(), 0.0f);
  EXPECT_FLOAT_EQ(PixelFilter(Gaussian(0.5f), 8, 8).reach(), 1.5f);
}

}  // namespace
}  // namespace irfarm
