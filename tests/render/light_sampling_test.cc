// Tests of render/solid_angle.* and render/light_sampler.*: each solid-angle sampler against the
// solid angles of the cells it should fill (chi-square), Lambert's polygon formula against
// brute-force integration (points in front, in the polygon's plane and behind it), and light
// selection probabilities (sum to 1, zero exactly for lights that cannot reach the point).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "render/light_sampler.h"
#include "render/sampling.h"
#include "render/solid_angle.h"
#include "tests/render/chi_square.h"

namespace irfarm {
namespace {

constexpr double kSignificance = 1e-3;

Vec3 RandomPoint(Rng& rng, float scale) {
  return Vec3(rng.Next() - 0.5f, rng.Next() - 0.5f, rng.Next() - 0.5f) * (2 * scale);
}

// Samples a rectangle by solid angle from o and bins the points on a K x K grid of the
// rectangle; each cell's expected share is its own solid angle (two triangles) over the total.
double RectChiSquare(const Vec3& o, const Vec3& corner, const Vec3& eu, const Vec3& ev, int n,
                     uint64_t seed, int* dof) {
  constexpr int K = 8;
  SphericalRect sr;
  EXPECT_TRUE(sr.Init(o, corner, eu, ev));
  std::vector<double> observed(K * K, 0), expected(K * K, 0);
  double total = 0;
  for (int i = 0; i < K; ++i)
    for (int j = 0; j < K; ++j) {
      const Vec3 a = corner + eu * (float(i) / K) + ev * (float(j) / K);
      const Vec3 b = a + eu * (1.0f / K), c = a + ev * (1.0f / K), d = b + ev * (1.0f / K);
      const double w = TriangleSolidAngle(o, a, b, d) + TriangleSolidAngle(o, a, d, c);
      expected[i * K + j] = w;
      total += w;
    }
  EXPECT_NEAR(total, sr.solid_angle(), 1e-4 * sr.solid_angle());
  for (double& e : expected) e *= n / total;
  Rng rng(seed, 1);
  const float lu2 = LengthSquared(eu), lv2 = LengthSquared(ev);
  for (int s = 0; s < n; ++s) {
    const float u = rng.Next();
    const Vec3 q = sr.Sample(u, rng.Next());
    const float fu = Dot(q - corner, eu) / lu2, fv = Dot(q - corner, ev) / lv2;
    const int i = std::clamp(int(fu * K), 0, K - 1), j = std::clamp(int(fv * K), 0, K - 1);
    observed[i * K + j] += 1;
  }
  return ChiSquareStatistic(observed, expected, dof);
}

TEST(SphericalRectTest, SamplesUniformInSolidAngle) {
  struct Case {
    Vec3 o;
    const char* what;
  } cases[] = {{Vec3(0.5f, 0.5f, 1.0f), "above the centre"},
               {Vec3(0.5f, 0.5f, 0.02f), "very close (fills most of the hemisphere)"},
               {Vec3(3.0f, -2.0f, 0.7f), "far to the side (grazing)"},
               {Vec3(0.1f, 0.9f, -0.3f), "below (the back side: same solid angle)"}};
  for (const Case& c : cases) {
    int dof = 0;
    const double chi2 =
        RectChiSquare(c.o, Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1.5f, 0), 200000, 7, &dof);
    EXPECT_LT(chi2, ChiSquareCritical(dof, kSignificance)) << c.what;
  }
}

// A sampler that is wrong (uniform by area instead of solid angle) must fail the same test.
TEST(SphericalRectTest, AreaSamplingFailsTheTest) {
  constexpr int K = 8, n = 200000;
  const Vec3 o(0.5f, 0.5f, 0.2f), corner(0, 0, 0), eu(1, 0, 0), ev(0, 1, 0);
  std::vector<double> observed(K * K, 0), expected(K * K, 0);
  double total = 0;
  for (int i = 0; i < K; ++i)
    for (int j = 0; j < K; ++j) {
      const Vec3 a = corner + eu * (float(i) / K) + ev * (float(j) / K);
      const Vec3 b = a + eu * (1.0f / K), c = a + ev * (1.0f / K), d = b + ev * (1.0f / K);
      expected[i * K + j] = TriangleSolidAngle(o, a, b, d) + TriangleSolidAngle(o, a, d, c);
      total += expected[i * K + j];
    }
  for (double& e : expected) e *= n / total;
  Rng rng(3, 1);
  for (int s = 0; s < n; ++s) {
    const int i = std::min(int(rng.Next() * K), K - 1), j = std::min(int(rng.Next() * K), K - 1);
    observed[i * K + j] += 1;
  }
  int dof = 0;
  const double chi2 = ChiSquareStatistic(observed, expected, &dof);
  EXPECT_GT(chi2, ChiSquareCritical(dof, kSignificance));
}

TEST(SphericalTriangleTest, SamplesUniformInSolidAngle) {
  // Bins: a K x K grid in barycentric coordinates (b1, b2), each square split into its lower
  // (and, inside the triangle, upper) half; expected counts from each cell's solid angle.
  constexpr int K = 8, n = 200000;
  const Vec3 a(0, 0, 0), b(2, 0, 0), c(0.3f, 1.2f, 0.1f);
  const Vec3 origins[] = {Vec3(0.5f, 0.3f, 0.8f), Vec3(0.6f, 0.4f, 0.05f), Vec3(-2, 3, 1)};
  for (const Vec3& o : origins) {
    SphericalTriangle st;
    ASSERT_TRUE(st.Init(o, a, b, c));
    auto P = [&](float b1, float b2) { return a + (b - a) * b1 + (c - a) * b2; };
    std::vector<double> observed(2 * K * K, 0), expected(2 * K * K, 0);
    double total = 0;
    for (int i = 0; i < K; ++i)
      for (int j = 0; i + j < K; ++j) {
        const float s = 1.0f / K;
        const Vec3 p00 = P(i * s, j * s), p10 = P((i + 1) * s, j * s), p01 = P(i * s, (j + 1) * s);
        expected[2 * (i * K + j)] = TriangleSolidAngle(o, p00, p10, p01);
        if (i + j + 2 <= K)
          expected[2 * (i * K + j) + 1] =
              TriangleSolidAngle(o, p10, P((i + 1) * s, (j + 1) * s), p01);
        total += expected[2 * (i * K + j)] + expected[2 * (i * K + j) + 1];
      }
    EXPECT_NEAR(total, st.solid_angle(), 1e-4 * st.solid_angle());
    for (double& e : expected) e *= n / total;
    Rng rng(11, 2);
    const Vec3 ng = Normalize(Cross(b - a, c - a));
    for (int k = 0; k < n; ++k) {
      const float u = rng.Next();
      const Vec3 dir = st.Sample(u, rng.Next());
      const float t = Dot(a - o, ng) / Dot(dir, ng);
      const Vec3 q = o + dir * t;
      // Barycentrics of q.
      const Vec3 e1 = b - a, e2 = c - a, dq = q - a, cr = Cross(e1, e2);
      const float inv = 1 / LengthSquared(cr);
      const float b1 = Dot(Cross(dq, e2), cr) * inv, b2 = Dot(Cross(e1, dq), cr) * inv;
      ASSERT_GT(b1, -1e-3f);
      ASSERT_GT(b2, -1e-3f);
      ASSERT_LT(b1 + b2, 1 + 1e-3f);
      const int i = std::clamp(int(b1 * K), 0, K - 1), j = std::clamp(int(b2 * K), 0, K - 1);
      const bool upper = (b1 * K - i) + (b2 * K - j) > 1;
      observed[2 * (i * K + j) + (upper ? 1 : 0)] += 1;
    }
    int dof = 0;
    const double chi2 = ChiSquareStatistic(observed, expected, &dof);
    EXPECT_LT(chi2, ChiSquareCritical(dof, kSignificance));
  }
}

// Brute force: midpoint rule over the polygon's area, integrand max(0, n.w) cos_l / d^2 (a
// triangle through the map (u, v) -> (u, v (1 - u)) of the unit square, Jacobian 1 - u).
double BruteProjectedSolidAngle(const Vec3& x, const Vec3& n, const Vec3& corner, const Vec3& eu,
                                const Vec3& ev, bool triangle) {
  constexpr int N = 600;
  const Vec3 nl = Normalize(Cross(eu, ev));
  const double cell = double(Length(Cross(eu, ev))) / (double(N) * N);
  double sum = 0;
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) {
      const float u = (i + 0.5f) / N, v = (j + 0.5f) / N;
      const float jac = triangle ? 1 - u : 1;
      const Vec3 q = corner + eu * u + ev * (triangle ? v * (1 - u) : v);
      const Vec3 d = q - x;
      const double d2 = LengthSquared(d), dist = std::sqrt(d2);
      const double cos_x = std::max(0.0, double(Dot(n, d)) / dist);
      const double cos_l = std::abs(double(Dot(nl, d))) / dist;
      sum += cos_x * cos_l / d2 * cell * jac;
    }
  return sum;
}

TEST(PolygonIrradianceTest, MatchesBruteForce) {
  Rng rng(5, 5);
  int in_plane = 0, behind = 0;
  for (int k = 0; k < 24; ++k) {
    const Vec3 corner = RandomPoint(rng, 1);
    Vec3 eu = RandomPoint(rng, 1), ev = RandomPoint(rng, 1);
    const bool triangle = k % 2 == 1;
    if (!triangle) ev = Normalize(Cross(Cross(eu, ev), eu)) * Length(ev);  // a rectangle
    const Vec3 nl = Normalize(Cross(eu, ev));
    const Vec3 centre = corner + (eu + ev) * (triangle ? 1.0f / 3 : 0.5f);
    Vec3 x = centre + RandomPoint(rng, 1.5f);
    const float h = Dot(x - corner, nl);
    // Every third point lies in the polygon's plane (outside it), every fourth behind it, the
    // others in front; none closer than 0.3 to the plane (the brute force's grid would not
    // resolve the near-singular integrand there).
    if (k % 3 == 0) {
      x = x - nl * h;
      x = x + Normalize(x - centre) * 2.0f;
      ++in_plane;
    } else if (k % 4 == 0) {
      x = x - nl * (h + 0.3f + std::abs(h));
      ++behind;
    } else {
      x = x + nl * (0.3f + std::abs(h) - h);
    }
    const Vec3 n = Normalize(RandomPoint(rng, 1));
    const Vec3 v[4] = {corner, corner + eu, corner + eu + ev, corner + ev};
    const Vec3 tri[3] = {corner, corner + eu, corner + ev};
    const double got = triangle ? PolygonProjectedSolidAngle(x, n, tri, 3)
                                : PolygonProjectedSolidAngle(x, n, v, 4);
    const double want = BruteProjectedSolidAngle(x, n, corner, eu, ev, triangle);
    EXPECT_NEAR(got, want, 2e-3 * want + 1e-6)
        << "case " << k << " height " << Dot(x - corner, nl) << " triangle " << triangle;
  }
  EXPECT_GT(in_plane, 0);
  EXPECT_GT(behind, 0);
}

TEST(PolygonIrradianceTest, InThePlaneIsZeroAndHalfSpaceIsPi) {
  const Vec3 v[4] = {Vec3(-1e4f, -1e4f, 0), Vec3(1e4f, -1e4f, 0), Vec3(1e4f, 1e4f, 0),
                     Vec3(-1e4f, 1e4f, 0)};
  // A huge polygon straight above fills the hemisphere: projected solid angle -> pi.
  EXPECT_NEAR(PolygonProjectedSolidAngle(Vec3(0, 0, -1), Vec3(0, 0, 1), v, 4), kPi, 1e-3);
  // A point in the polygon's plane sees it edge-on.
  EXPECT_NEAR(PolygonProjectedSolidAngle(Vec3(3e4f, 0, 0), Vec3(0, 0, 1), v, 4), 0, 1e-9);
  // A surface facing away sees nothing.
  EXPECT_EQ(PolygonProjectedSolidAngle(Vec3(0, 0, -1), Vec3(0, 0, -1), v, 4), 0);
}

Light RectLight(const Vec3& corner, const Vec3& eu, const Vec3& ev, const Vec3& L) {
  Light l;
  l.type = LightType::kArea;
  l.shape = AreaShape::kRect;
  l.radiance = L;
  l.corner = corner;
  l.edge_u = eu;
  l.edge_v = ev;
  l.normal = Normalize(Cross(eu, ev));
  l.area = Length(Cross(eu, ev));
  return l;
}

TEST(LightSelectionTest, ProbabilitiesSumToOneAndAreZeroForUnreachableLights) {
  std::vector<Light> lights;
  // 0: a ceiling lamp at z = 2 facing down.
  lights.push_back(RectLight(Vec3(-0.5f, -0.5f, 2), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(10)));
  // 1: a point light below the floor (z = -1): never reaches an upward-facing point.
  Light point;
  point.type = LightType::kPoint;
  point.position = Vec3(0, 0, -1);
  point.intensity = Vec3(5);
  lights.push_back(point);
  // 2: a spot at (3, 0, 1) pointing along +x (away from the room's centre).
  Light spot;
  spot.type = LightType::kSpot;
  spot.position = Vec3(3, 0, 1);
  spot.direction = Vec3(1, 0, 0);
  spot.intensity = Vec3(20);
  spot.cutoff = 0.35f;
  spot.cos_cutoff = std::cos(0.35f);
  spot.cos_beam = std::cos(0.26f);
  spot.inv_transition = 1 / (0.35f - 0.26f);
  lights.push_back(spot);
  // 3: a sun travelling down.
  Light sun;
  sun.type = LightType::kDirectional;
  sun.direction = Vec3(0, 0, -1);
  sun.intensity = Vec3(3);
  lights.push_back(sun);
  // 4: a sphere light.
  Light sphere;
  sphere.type = LightType::kArea;
  sphere.shape = AreaShape::kSphere;
  sphere.center = Vec3(-2, 1, 1);
  sphere.radius = 0.2f;
  sphere.area = 4 * kPi * 0.04f;
  sphere.radiance = Vec3(7);
  lights.push_back(sphere);
  // 5: a lamp on the floor facing down (its back to the room): unreachable from above.
  lights.push_back(RectLight(Vec3(0, 0, -0.5f), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(10)));
  Light sky;
  sky.type = LightType::kConstant;
  sky.radiance = Vec3(0.2f);
  sky.average_radiance = sky.radiance;
  lights.push_back(sky);
  LightSampler sampler;
  sampler.Build(lights, 6);

  Rng rng(9, 9);
  for (int k = 0; k < 200; ++k) {
    const Vec3 p(rng.Next() * 4 - 2, rng.Next() * 4 - 2, 0);
    const Vec3 n(0, 0, 1);
    double sum = 0;
    for (int i = 0; i <= sampler.num_local(); ++i) sum += sampler.SelectionProbability(p, n, i);
    EXPECT_NEAR(sum, 1.0, 1e-5);
    EXPECT_EQ(sampler.SelectionProbability(p, n, 1), 0) << "point light below the floor";
    EXPECT_EQ(sampler.SelectionProbability(p, n, 2), 0) << "spot pointing away";
    EXPECT_EQ(sampler.SelectionProbability(p, n, 5), 0) << "lamp facing away";
    EXPECT_GT(sampler.SelectionProbability(p, n, 0), 0);
    EXPECT_GT(sampler.SelectionProbability(p, n, 3), 0);
    int skipped = 0;
    LightSample s;
    const float u1 = rng.Next(), u2 = rng.Next();
    sampler.Sample(p, n, u1, u2, rng.Next(), true, &s, &skipped);
    EXPECT_EQ(skipped, 3);
  }
  // A point under the spot's cone does get the spot.
  EXPECT_GT(sampler.SelectionProbability(Vec3(6, 0, 0), Vec3(0, 0, 1), 2), 0);
}

// Light sampling is unbiased: averaged over many samples, Le cos / pdf equals the analytic
// unoccluded irradiance, for a rectangle close to the point (by solid angle) and for a sphere.
TEST(LightSamplerTest, SampleOneIsUnbiasedAgainstAnalyticIrradiance) {
  std::vector<Light> lights;
  lights.push_back(RectLight(Vec3(-1, -1, 0.3f), Vec3(0, 2, 0), Vec3(2, 0, 0), Vec3(1)));
  LightSampler sampler;
  sampler.Build(lights, 1);
  const Vec3 p(0.9f, 0.2f, 0), n = Normalize(Vec3(0.3f, 0, 1));
  const double analytic = sampler.AnalyticIrradiance(0, p, n).x;
  Rng rng(4, 4);
  double sum = 0, sum2 = 0;
  constexpr int kN = 200000;
  for (int i = 0; i < kN; ++i) {
    LightSample s;
    const float u2 = rng.Next();
    double v = 0;
    if (sampler.SampleOne(0, p, n, u2, rng.Next(), &s))
      v = s.value.x * std::max(0.0f, Dot(s.wi, n));
    sum += v;
    sum2 += v * v;
  }
  const double mean = sum / kN, sd = std::sqrt((sum2 / kN - mean * mean) / kN);
  EXPECT_NEAR(mean, analytic, 4 * sd + 1e-6);
  // Bounded: solid-angle sampling never weights a sample by more than L * Omega.
  EXPECT_LT(sum2 / kN, 4 * kPi * kPi);
}

}  // namespace
}  // namespace irfarm
