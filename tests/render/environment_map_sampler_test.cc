// EnvironmentMapSampler: its samples follow its pdf (chi-square over (cos theta, phi) bins), the
// pdf integrates to 1 over the sphere, and irradiance estimated with it matches numerical
// integration, for a sharp "sun" and a smooth sky in a rotated frame.
#include "render/environment_map_sampler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "render/sampling.h"
#include "tests/render/chi_square.h"

namespace irfarm {
namespace {

// A sky brighter towards +y plus a small, very bright sun: most of the light in 0.3% of the
// sphere, as in a sunset envmap.
const Vec3 kSun = Normalize(Vec3(0.6f, 0.3f, -0.74f));
Vec3 Sky(const Vec3& d) {
  const float sky = 0.2f + 0.8f * std::max(0.0f, d.y);
  const float sun = Dot(d, kSun) > 0.995f ? 400.0f : 0.0f;
  return Vec3(sky + sun, sky + 0.8f * sun, sky + 0.5f * sun);
}

Mat4 Rotation() {  // world -> env: 40 degrees about x, then 25 about y
  const double a = 40 * kPi / 180, b = 25 * kPi / 180;
  Mat4 rx, ry;
  rx.m[1][1] = std::cos(a), rx.m[1][2] = -std::sin(a), rx.m[2][1] = std::sin(a),
  rx.m[2][2] = std::cos(a);
  ry.m[0][0] = std::cos(b), ry.m[0][2] = std::sin(b), ry.m[2][0] = -std::sin(b),
  ry.m[2][2] = std::cos(b);
  Mat4 r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0;
      for (int k = 0; k < 3; ++k) s += ry.m[i][k] * rx.m[k][j];
      r.m[i][j] = s;
    }
  return r;
}

// A direction from (cos theta, phi) cell coordinates over the world sphere.
Vec3 Dir(double z, double phi) {
  const double s = std::sqrt(std::max(0.0, 1 - z * z));
  return Vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(z));
}

TEST(EnvironmentMapSamplerTest, SamplesFollowThePdfAndThePdfIntegratesToOne) {
  EnvironmentMapSampler env;
  env.Build(Sky, Rotation(), 128, 64);
  ASSERT_FALSE(env.empty());
  // Bins over the world sphere, uniform in cos(theta) and phi (equal solid angle).
  constexpr int kZ = 32, kPhi = 64, kSub = 8;
  std::vector<double> expected(kZ * kPhi, 0), observed(kZ * kPhi, 0);
  double integral = 0;
  const double cell = 4 * kPi / (kZ * kPhi) / (kSub * kSub);
  for (int a = 0; a < kZ; ++a)
    for (int b = 0; b < kPhi; ++b)
      for (int s = 0; s < kSub; ++s)
        for (int t = 0; t < kSub; ++t) {
          const double z = -1 + 2 * (a + (s + 0.5) / kSub) / kZ;
          const double phi = 2 * kPi * (b + (t + 0.5) / kSub) / kPhi;
          const double p = env.Pdf(Dir(z, phi)) * cell;
          expected[size_t(a * kPhi + b)] += p;
          integral += p;
        }
  EXPECT_NEAR(integral, 1.0, 0.01);
  const int n = 400000;
  Rng rng(11, 12);
  int failed = 0, mismatched = 0;
  for (int i = 0; i < n; ++i) {
    Vec3 d;
    float pdf = 0;
    if (!env.Sample(rng.Next(), rng.Next(), &d, &pdf)) {
      ++failed;
      continue;
    }
    // The density Sample reports is Pdf's (up to a cell edge's rounding).
    if (std::abs(pdf - env.Pdf(d)) > 1e-3f * pdf) ++mismatched;
    const double z = std::clamp(double(d.z), -1.0, 1.0);
    double phi = std::atan2(double(d.y), double(d.x));
    if (phi < 0) phi += 2 * kPi;
    const int a = std::clamp(int((z + 1) / 2 * kZ), 0, kZ - 1);
    const int b = std::clamp(int(phi / (2 * kPi) * kPhi), 0, kPhi - 1);
    observed[size_t(a * kPhi + b)] += 1;
  }
  // A direction drawn at a cell's edge can map back, after float rounding through the frame,
  // into an empty neighbour (pdf 0): such a sample is refused (it carries no light). Rare.
  EXPECT_LE(failed, n / 10000);
  EXPECT_LE(mismatched, n / 1000);
  for (double& e : expected) e *= n;
  int dof = 0;
  const double chi2 = ChiSquareStatistic(observed, expected, &dof);
  EXPECT_LT(chi2, ChiSquareCritical(dof, 1e-3)) << "dof " << dof;
}

// Irradiance at normal n from Sky: importance sampled (value / pdf) against a fine numerical
// integral. Also shows what the sampler is for: the estimate's spread is far below that of
// cosine-weighted directions with the same number of samples.
TEST(EnvironmentMapSamplerTest, IrradianceEstimateIsUnbiasedAndLessNoisyThanCosineSampling) {
  EnvironmentMapSampler env;
  env.Build(Sky, Rotation());
  const Vec3 n = Normalize(Vec3(0.3f, 0.2f, -0.9f));  // facing the sun's side
  double exact = 0;
  constexpr int kZ = 1024, kPhi = 2048;
  for (int a = 0; a < kZ; ++a)
    for (int b = 0; b < kPhi; ++b) {
      const Vec3 d = Dir(-1 + 2 * (a + 0.5) / kZ, 2 * kPi * (b + 0.5) / kPhi);
      exact += Luminance(Sky(d)) * std::max(0.0f, Dot(d, n)) * (4 * kPi / (double(kZ) * kPhi));
    }
  Rng rng(3, 4);
  Vec3 s_, t_;
  MakeFrame(n, &s_, &t_);
  const int runs = 200, per_run = 64;
  double mean_is = 0, var_is = 0, var_cos = 0;
  for (int r = 0; r < runs; ++r) {
    double is = 0, cos = 0;
    for (int i = 0; i < per_run; ++i) {
      Vec3 d;
      float pdf = 0;
      if (env.Sample(rng.Next(), rng.Next(), &d, &pdf) && Dot(d, n) > 0)
        is += Luminance(Sky(d)) * Dot(d, n) / pdf;
      const Vec3 l = CosineHemisphere(rng.Next(), rng.Next());
      const Vec3 c = s_ * l.x + t_ * l.y + n * l.z;
      cos += Luminance(Sky(c)) * kPi;  // L cos / (cos / pi)
    }
    is /= per_run;
    cos /= per_run;
    mean_is += is / runs;
    var_is += (is - exact) * (is - exact) / runs;
    var_cos += (cos - exact) * (cos - exact) / runs;
  }
  // The mean of 200 x 64 samples, within 4 standard errors.
  EXPECT_NEAR(mean_is, exact, 4 * std::sqrt(var_is / runs)) << "exact " << exact;
  EXPECT_LT(var_is, 0.1 * var_cos) << "importance " << var_is << " cosine " << var_cos;
}

}  // namespace
}  // namespace irfarm
