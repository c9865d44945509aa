// Tests of render/light_tree.*: the probabilities of picking each triangle of an emissive mesh
// sum to at most 1 (the rest: a failed walk) and agree between Sample and Pmf; a triangle that can
// light the point (non-zero projected solid angle, Lambert's formula) always has a non-zero
// probability; a point no triangle can light gets none; and next-event estimation of a tube lamp
// through the tree stays unbiased (against the exact irradiance) while its variance falls below
// picking by area.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <vector>

#include "render/light_sampler.h"
#include "render/light_tree.h"
#include "render/sampling.h"
#include "render/solid_angle.h"
#include "tests/render/chi_square.h"

namespace irfarm {
namespace {

LightTriangle Tri(const Vec3& a, const Vec3& b, const Vec3& c) {
  LightTriangle t;
  t.p0 = a;
  t.p1 = b;
  t.p2 = c;
  const Vec3 cr = Cross(b - a, c - a);
  t.area = 0.5f * Length(cr);
  t.ng = t.area > 0 ? Normalize(cr) : Vec3(0, 0, 1);
  t.n0 = t.n1 = t.n2 = t.ng;
  t.error_scale = std::max({MaxAbsComponent(a), MaxAbsComponent(b), MaxAbsComponent(c)});
  return t;
}

// An open tube along z (a fluorescent lamp), emitting outwards: `segments` x `rings` quads.
std::vector<LightTriangle> Tube(const Vec3& base, float radius, float length, int segments,
                                int rings) {
  std::vector<LightTriangle> tris;
  for (int r = 0; r < rings; ++r) {
    const float z0 = length * float(r) / float(rings), z1 = length * float(r + 1) / float(rings);
    for (int s = 0; s < segments; ++s) {
      const float a0 = 2 * kPi * float(s) / float(segments);
      const float a1 = 2 * kPi * float(s + 1) / float(segments);
      const Vec3 p00 = base + Vec3(radius * std::cos(a0), radius * std::sin(a0), z0);
      const Vec3 p10 = base + Vec3(radius * std::cos(a1), radius * std::sin(a1), z0);
      const Vec3 p01 = base + Vec3(radius * std::cos(a0), radius * std::sin(a0), z1);
      const Vec3 p11 = base + Vec3(radius * std::cos(a1), radius * std::sin(a1), z1);
      tris.push_back(Tri(p00, p10, p11));  // counter-clockwise seen from outside
      tris.push_back(Tri(p00, p11, p01));
    }
  }
  return tris;
}

// A flat disk of `segments` triangles around `centre` in the plane y = centre.y, emitting down
// (-y): a ceiling lamp.
std::vector<LightTriangle> DiskDown(const Vec3& centre, float radius, int segments) {
  std::vector<LightTriangle> tris;
  for (int s = 0; s < segments; ++s) {
    const float a0 = 2 * kPi * float(s) / float(segments);
    const float a1 = 2 * kPi * float(s + 1) / float(segments);
    const Vec3 p0 = centre + Vec3(radius * std::cos(a0), 0, radius * std::sin(a0));
    const Vec3 p1 = centre + Vec3(radius * std::cos(a1), 0, radius * std::sin(a1));
    tris.push_back(Tri(centre, p0, p1));  // counter-clockwise seen from below
  }
  return tris;
}

// A soup: triangles scattered in a box with random orientations and sizes, and a zero-area one.
std::vector<LightTriangle> Soup(Rng& rng, int n) {
  std::vector<LightTriangle> tris;
  for (int i = 0; i < n; ++i) {
    const Vec3 c(rng.Next() * 4 - 2, rng.Next() * 4 - 2, rng.Next() * 2);
    const float s = 0.05f + 0.5f * rng.Next();
    const auto corner = [&] {
      return c + Vec3(rng.Next() - 0.5f, rng.Next() - 0.5f, rng.Next() - 0.5f) * s;
    };
    tris.push_back(Tri(corner(), corner(), corner()));
  }
  tris.push_back(Tri(Vec3(0, 0, 1), Vec3(0, 0, 1), Vec3(1, 0, 1)));  // zero area
  return tris;
}

Vec3 RandomDirection(Rng& rng) {
  const float u = rng.Next();
  return UniformSphere(u, rng.Next());
}

// The exact unoccluded contribution (projected solid angle; plain solid angle without a normal)
// of triangle t at (p, n): what the tree must never give probability 0.
double Contribution(const LightTriangle& t, const Vec3& p, const Vec3& n) {
  if (!(t.area > 0) || Dot(p - t.p0, t.ng) <= 0) return 0;
  if (IsBlack(n)) return TriangleSolidAngle(p, t.p0, t.p1, t.p2);
  const Vec3 v[3] = {t.p0, t.p1, t.p2};
  return PolygonProjectedSolidAngle(p, n, v, 3);
}

TEST(LightTreeTest, ProbabilitiesSumToAtMostOneAgreeAndAreNonZeroWhereATriangleCanLight) {
  Rng rng(3, 5);
  const std::vector<std::vector<LightTriangle>> meshes = {
      Tube(Vec3(0, 0, 1), 0.05f, 1.2f, 16, 8),
      Soup(rng, 300),
      {Tri(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0))}};
  // Both walks: the full one, and the one that stops at far narrow nodes (stop_far).
  for (const bool stop_far : {false, true})
    for (size_t m = 0; m < meshes.size(); ++m) {
      const std::vector<LightTriangle>& tris = meshes[m];
      LightTree tree;
      tree.Build(tris, 2.0f);
      ASSERT_FALSE(tree.empty());
      EXPECT_LE(tree.depth(), 63);
      int lit_points = 0;
      double min_sum = 1;
      for (int k = 0; k < 200; ++k) {
        const Vec3 p(rng.Next() * 6 - 3, rng.Next() * 6 - 3, rng.Next() * 4 - 1);
        const Vec3 n = k % 5 == 0 ? Vec3() : RandomDirection(rng);
        double sum = 0, reachable = 0;
        for (size_t i = 0; i < tris.size(); ++i) {
          const double pmf = tree.Pmf(p, n, unsigned(i), stop_far);
          EXPECT_GE(pmf, 0);
          sum += pmf;
          const double c = Contribution(tris[i], p, n);
          reachable += c;
          if (c > 1e-7) {
            EXPECT_GT(pmf, 0) << "mesh " << m << " triangle " << i << " lights the point";
          }
          if (tris[i].area <= 0) {
            EXPECT_EQ(pmf, 0) << "zero-area triangle";
          }
        }
        // The bounds are conservative: a node may pass its test while neither child does, and
        // then the walk ends without a triangle. So the probabilities sum to at most 1, and the
        // rest is the chance that Sample fails.
        EXPECT_LE(sum, 1.0 + 1e-5) << "mesh " << m << " point " << k;
        if (tree.Importance(p, n) > 0) {
          ++lit_points;
          min_sum = std::min(min_sum, sum);
        } else {
          EXPECT_EQ(reachable, 0) << "root importance 0 where a triangle can light the point";
          continue;  // the light sampler gives such a light no sample
        }
        // Sample's own probability is Pmf's, exactly; it fails as often as the sum says.
        constexpr int kTries = 200;
        int failed = 0;
        for (int s = 0; s < kTries; ++s) {
          float pmf = 0;
          const int i = tree.Sample(p, n, rng.Next(), &pmf, stop_far);
          if (i < 0) {
            ++failed;
            continue;
          }
          EXPECT_EQ(pmf, tree.Pmf(p, n, unsigned(i), stop_far));
        }
        // Binomial: 5 standard deviations (and one sample) of slack.
        const double q = std::clamp(1 - sum, 0.0, 1.0);
        EXPECT_NEAR(failed, kTries * q, 5 * std::sqrt(kTries * q * (1 - q)) + 1) << "point " << k;
      }
      EXPECT_GT(lit_points, 20) << "mesh " << m;
      std::printf(
          "MEASURED mesh %zu%s: %d of 200 points lit, least chance that a walk ends at a triangle "
          "%.3f\n",
          m, stop_far ? " (stop_far)" : "", lit_points, min_sum);
    }
}

// A soup, a bucketed tube and a ceiling disk, each with its tree, seen from one point (p, n).
struct PickCase {
  std::vector<LightTriangle> tris;
  LightTree tree;
};
std::vector<PickCase> PickCases(Rng& rng) {
  std::vector<PickCase> cases(3);
  cases[0].tris = Soup(rng, 40);
  cases[1].tris = Tube(Vec3(0, 0, 0), 0.05f, 1, 12, 3);
  cases[2].tris = DiskDown(Vec3(0.5f, 3, 0.6f), 0.5f, 24);
  for (PickCase& c : cases) c.tree.Build(c.tris, 1.0f);
  return cases;
}
const Vec3 kPickPoint(0.3f, -0.2f, 0.4f);
const Vec3 kPickNormal = Normalize(Vec3(0.2f, 0.1f, 1));

// Sample's picks follow Pmf (chi-square), also on a tube, whose narrow strips the tree keeps in
// buckets of several triangles (a leaf that picks among them by power), and on a ceiling disk far
// from the point, where a walk with stop_far stops at the root and picks among all its triangles
// by power.
TEST(LightTreeTest, SamplesFollowTheirProbabilities) {
  Rng rng(8, 1);
  for (const bool stop_far : {false, true})
    for (const PickCase& c : PickCases(rng)) {
      const std::vector<LightTriangle>& tris = c.tris;
      const LightTree& tree = c.tree;
      const Vec3 &p = kPickPoint, &n = kPickNormal;
      // One cell per triangle and one for a failed walk.
      std::vector<double> observed(tris.size() + 1, 0), expected(tris.size() + 1, 0);
      constexpr int kN = 400000;
      double sum = 0;
      for (size_t i = 0; i < tris.size(); ++i) {
        expected[i] = kN * double(tree.Pmf(p, n, unsigned(i), stop_far));
        sum += double(tree.Pmf(p, n, unsigned(i), stop_far));
      }
      expected[tris.size()] = kN * std::max(0.0, 1 - sum);
      for (int s = 0; s < kN; ++s) {
        float pmf = 0;
        const int i = tree.Sample(p, n, rng.Next(), &pmf, stop_far);
        observed[i < 0 ? tris.size() : size_t(i)] += 1;
      }
      int dof = 0;
      const double chi2 = ChiSquareStatistic(observed, expected, &dof);
      EXPECT_LT(chi2, ChiSquareCritical(dof, 1e-3))
          << "dof " << dof << ", " << tris.size() << (stop_far ? ", stop_far" : "");
      EXPECT_GT(dof, 5);
    }
}

// What Sample leaves of u after its pick (u_rest, the first coordinate of the point on the
// triangle) is uniform given the pick, and evenly spread where u was: with u on an even grid,
// every triangle picked often enough gets u_rest in ten equal bins as evenly as chance allows
// (the pick's u unchanged would put them all in the sub-interval that chose it).
TEST(LightTreeTest, WhatRemainsOfUIsUniformGivenThePick) {
  Rng rng(4, 9);
  for (const bool stop_far : {false, true})
    for (const PickCase& c : PickCases(rng)) {
      const std::vector<LightTriangle>& tris = c.tris;
      const LightTree& tree = c.tree;
      const Vec3 &p = kPickPoint, &n = kPickNormal;
      constexpr int kN = 200000, kBins = 10;
      std::vector<std::vector<double>> bins(tris.size(), std::vector<double>(kBins, 0));
      for (int i = 0; i < kN; ++i) {
        float pmf = 0, rest = -1;
        const int t = tree.Sample(p, n, (float(i) + 0.5f) / kN, &pmf, stop_far, &rest);
        if (t < 0) continue;
        ASSERT_GE(rest, 0);
        ASSERT_LT(rest, 1);
        bins[size_t(t)][size_t(std::min(kBins - 1, int(rest * kBins)))] += 1;
      }
      int tested = 0;
      for (const std::vector<double>& b : bins) {
        double count = 0;
        for (const double c : b) count += c;
        if (count < 50 * kBins) continue;
        const std::vector<double> expected(kBins, count / kBins);
        int dof = 0;
        const double chi2 = ChiSquareStatistic(b, expected, &dof);
        EXPECT_LT(chi2, ChiSquareCritical(dof, 1e-3))
            << tris.size() << " triangles" << (stop_far ? ", stop_far" : "");
        ++tested;
      }
      EXPECT_GT(tested, 3);
    }
}

TEST(LightTreeTest, NothingWhereNoTriangleCanLight) {
  // A flat square emitting up (+z), in two triangles and subdivided: points below it, and points
  // above it whose horizon it lies under, get nothing.
  std::vector<LightTriangle> tris;
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j) {
      const Vec3 a(float(i) / 8, float(j) / 8, 0),
          b = a + Vec3(0.125f, 0, 0), c = a + Vec3(0.125f, 0.125f, 0), d = a + Vec3(0, 0.125f, 0);
      tris.push_back(Tri(a, b, c));
      tris.push_back(Tri(a, c, d));
    }
  LightTree tree;
  tree.Build(tris, 1.0f);
  EXPECT_EQ(tree.Importance(Vec3(0.5f, 0.5f, -0.3f), Vec3(0, 0, 1)), 0) << "behind the lamp";
  EXPECT_EQ(tree.Importance(Vec3(0.5f, 0.5f, -0.3f), Vec3()), 0) << "behind, no normal";
  EXPECT_EQ(tree.Importance(Vec3(0.5f, 0.5f, 2), Vec3(0, 0, 1)), 0) << "facing away";
  EXPECT_GT(tree.Importance(Vec3(0.5f, 0.5f, 2), Vec3(0, 0, -1)), 0) << "facing it";
  // Beside the lamp, looking at it: only the triangles in front of its plane; all of them are.
  float pmf = 0;
  EXPECT_LT(tree.Sample(Vec3(0.5f, 0.5f, -1e-3f), Vec3(0, 0, 1), 0.5f, &pmf), 0);
}

// Builds a LightSampler holding one emissive mesh, as Scene does.
LightSampler MeshLightSampler(const std::vector<LightTriangle>& tris, const Vec3& radiance) {
  Light l;
  l.type = LightType::kArea;
  l.shape = AreaShape::kMesh;
  l.radiance = radiance;
  l.triangles = tris;
  float acc = 0;
  for (const LightTriangle& t : tris) {
    acc += t.area;
    l.cdf.push_back(acc);
    l.error_scale = std::max(l.error_scale, t.error_scale);
  }
  l.area = acc;
  l.tree.Build(l.triangles, Luminance(radiance));
  LightSampler sampler;
  sampler.Build({l}, 1);
  return sampler;
}

// Next-event estimation of a tube lamp from points on a wall beside it and on the ceiling above
// it: the mean of Le cos / pdf is the exact irradiance (sum of the triangles' projected solid
// angles), and its variance is lower than with the triangle picked by area (the way before the
// tree, computed here from the same spherical-triangle sampler), which spends about half of its
// samples on the triangles facing away.
TEST(LightTreeTest, TubeLampIsUnbiasedAndLessNoisyThanPickingByArea) {
  const std::vector<LightTriangle> tris = Tube(Vec3(0, 0, 0), 0.03f, 1.0f, 32, 4);
  const LightSampler sampler = MeshLightSampler(tris, Vec3(1));
  const Light& light = sampler.lights()[0];
  struct Case {
    Vec3 p, n;
    const char* what;
  } cases[] = {{Vec3(0.2f, 0, 0.5f), Vec3(-1, 0, 0), "wall 0.2 beside the middle"},
               {Vec3(0.1f, 0.05f, 1.05f), Normalize(Vec3(-1, 0, -1)), "near its end"},
               {Vec3(0.5f, 0.3f, -0.4f), Vec3(0, 0, 1), "floor below its base"}};
  for (const Case& c : cases) {
    double exact = 0;
    for (const LightTriangle& t : tris) exact += Contribution(t, c.p, c.n);
    Rng rng(21, 2);
    constexpr int kN = 200000;
    double sum = 0, sum2 = 0, area_sum = 0, area_sum2 = 0;
    for (int i = 0; i < kN; ++i) {
      const float u1 = rng.Next(), u2 = rng.Next(), u3 = rng.Next();
      LightSample s;
      double v = 0;
      if (sampler.SampleOne(0, c.p, c.n, u2, u3, &s))
        v = s.value.x * std::max(0.0f, Dot(s.wi, c.n));
      sum += v;
      sum2 += v * v;
      // By area: the triangle u1 picks, then its spherical triangle.
      const LightTriangle& t = light.PickTriangle(u1);
      double va = 0;
      SphericalTriangle st;
      if (Dot(c.p - t.p0, t.ng) > 0 && st.Init(c.p, t.p0, t.p1, t.p2)) {
        const Vec3 wi = st.Sample(u2, u3);
        va = st.solid_angle() / (t.area / light.area) * std::max(0.0f, Dot(wi, c.n));
      }
      area_sum += va;
      area_sum2 += va * va;
    }
    const double mean = sum / kN, var = sum2 / kN - mean * mean;
    const double area_mean = area_sum / kN, area_var = area_sum2 / kN - area_mean * area_mean;
    const double se = std::sqrt(var / kN), area_se = std::sqrt(area_var / kN);
    std::printf("MEASURED %s: exact %.5f, tree %.5f (var %.3g), by area %.5f (var %.3g): %.2fx\n",
                c.what, exact, mean, var, area_mean, area_var, area_var / var);
    EXPECT_NEAR(mean, exact, 4 * se + 1e-6) << c.what;
    EXPECT_NEAR(area_mean, exact, 4 * area_se + 1e-6) << c.what << " (the baseline itself)";
    EXPECT_LT(var, 0.5 * area_var) << c.what;
  }
}

// The triangle of `tris` that point q lies on (within a relative tolerance), or -1.
int TriangleAt(const std::vector<LightTriangle>& tris, const Vec3& q) {
  for (size_t i = 0; i < tris.size(); ++i) {
    const LightTriangle& t = tris[i];
    const Vec3 e1 = t.p1 - t.p0, e2 = t.p2 - t.p0, d = q - t.p0;
    const Vec3 c = Cross(e1, e2);
    const float c2 = LengthSquared(c);
    if (!(c2 > 0) || std::abs(Dot(d, c)) > 1e-4f * std::sqrt(c2) * (Length(e1) + Length(e2)))
      continue;
    const float b1 = Dot(Cross(d, e2), c) / c2, b2 = Dot(Cross(e1, d), c) / c2;
    if (b1 >= -1e-4f && b2 >= -1e-4f && b1 + b2 <= 1 + 1e-4f) return int(i);
  }
  return -1;
}

// SampleOne's pdf for a mesh lamp is PdfOne's for the direction it gave (what MIS weighs paths
// that hit the lamp with), at points near the lamp, where its triangles are sampled by solid
// angle, and farther away, where the small ones are sampled by area: the two must make the same
// choice per triangle.
TEST(LightTreeTest, MeshSamplePdfIsWhatPdfOneGives) {
  const std::vector<LightTriangle> tris = Tube(Vec3(0, 0, 0), 0.03f, 1.0f, 32, 4);
  const LightSampler sampler = MeshLightSampler(tris, Vec3(1));
  Rng rng(5, 9);
  int checked = 0, near = 0, far = 0;
  for (int k = 0; k < 800; ++k) {
    const bool coarse =
        k % 2 == 1;  // the tree's walk with stop_far (PathSettings::coarse_light_tree)
    // Distances from 0.05 to 3 from the tube's axis (its triangles are 0.25 long).
    const float r = 0.05f * std::pow(60.0f, rng.Next()), a = 2 * kPi * rng.Next();
    const Vec3 p(r * std::cos(a), r * std::sin(a), 1.4f * rng.Next() - 0.2f);
    const Vec3 n = k % 4 == 0 ? Vec3() : RandomDirection(rng);
    const float u2 = rng.Next(), u3 = rng.Next();
    LightSample s;
    if (!sampler.SampleOne(0, p, n, u2, u3, &s, coarse)) continue;
    const int prim = TriangleAt(tris, s.light_point);
    ASSERT_GE(prim, 0) << "sample off the lamp at point " << k;
    const float pdf =
        sampler.PdfOne(0, p, n, s.light_point, s.light_normal, unsigned(prim), s.wi, coarse);
    EXPECT_NEAR(pdf, s.pdf, 1e-3f * s.pdf) << "point " << k << " at " << r << " from the axis";
    ++checked;
    (r < 0.25f ? near : far) += 1;
  }
  EXPECT_GT(near, 100);
  EXPECT_GT(far, 100);
  std::printf("MEASURED %d samples checked (%d within 0.25 of the axis, %d farther)\n", checked,
              near, far);
}

}  // namespace
}  // namespace irfarm
