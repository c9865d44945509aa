// Tests of render/irradiance_hessian.*: the per-edge derivatives of the projected solid angle
// against finite differences of PolygonProjectedSolidAngle (an independent implementation of
// Lambert's formula), and the derivatives estimated from a record's hemisphere grid against
// the exact derivatives of a scene whose irradiance has a closed form.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "render/irradiance_hessian.h"
#include "render/sampling.h"
#include "render/solid_angle.h"

namespace irfarm {
namespace {

struct Poly {
  Vec3 v[3];
};

// Sum of the edge terms of triangle v (relative to x), and its derivatives.
EdgeTerm TriangleTerms(const Vec3& x, const Vec3& n, const Vec3* v) {
  EdgeTerm sum;
  const double nd[3] = {n.x, n.y, n.z};
  for (int k = 0; k < 3; ++k) {
    const Vec3 a = v[k] - x, b = v[(k + 1) % 3] - x;
    const double r0[3] = {a.x, a.y, a.z}, r1[3] = {b.x, b.y, b.z};
    EdgeTerm e;
    EXPECT_TRUE(ProjectedSolidAngleEdge(r0, r1, nd, &e));
    sum.phi += e.phi;
    for (int c = 0; c < 3; ++c) sum.grad[c] += e.grad[c];
    for (int c = 0; c < 6; ++c) sum.hess[c] += e.hess[c];
  }
  return sum;
}

// A triangle well above the plane z = 0 (so that moving x by h does not clip it), normal +z.
Poly RandomTriangleAbove(Rng& rng) {
  Poly p;
  for (Vec3& v : p.v) v = Vec3(4 * rng.Next() - 2, 4 * rng.Next() - 2, 0.3f + 2 * rng.Next());
  return p;
}

TEST(IrradianceHessianTest, EdgeTermsSumToTheProjectedSolidAngle) {
  Rng rng(11, 3);
  const Vec3 x(0, 0, 0), n(0, 0, 1);
  for (int trial = 0; trial < 200; ++trial) {
    const Poly p = RandomTriangleAbove(rng);
    const double want = PolygonProjectedSolidAngle(x, n, p.v, 3);
    EXPECT_NEAR(std::abs(TriangleTerms(x, n, p.v).phi), want, 1e-9 + 1e-6 * want);
  }
}

// grad and Hessian of the projected solid angle at x = 0 against central differences of
// PolygonProjectedSolidAngle, in double (h small against the triangle's distance).
TEST(IrradianceHessianTest, EdgeDerivativesMatchFiniteDifferences) {
  Rng rng(5, 9);
  const Vec3 n(0, 0, 1);
  const double h = 1e-3;
  const auto phi = [&](const Poly& p, double dx, double dy, double dz) {
    // Moving x by d is moving the triangle by -d (PolygonProjectedSolidAngle takes floats:
    // shift the vertices in double first, then round once).
    Vec3 v[3];
    for (int k = 0; k < 3; ++k)
      v[k] = Vec3(float(double(p.v[k].x) - dx), float(double(p.v[k].y) - dy),
                  float(double(p.v[k].z) - dz));
    return PolygonProjectedSolidAngle(Vec3(0, 0, 0), n, v, 3);
  };
  double worst_grad = 0, worst_hess = 0;
  for (int trial = 0; trial < 100; ++trial) {
    const Poly p = RandomTriangleAbove(rng);
    const EdgeTerm t = TriangleTerms(Vec3(0, 0, 0), n, p.v);
    const double sign = t.phi < 0 ? -1 : 1;
    double scale_g = 0, scale_h = 0;
    for (double g : t.grad) scale_g = std::max(scale_g, std::abs(g));
    for (double v : t.hess) scale_h = std::max(scale_h, std::abs(v));
    const double d[3][3] = {{h, 0, 0}, {0, h, 0}, {0, 0, h}};
    for (int i = 0; i < 3; ++i) {
      const double fd =
          (phi(p, d[i][0], d[i][1], d[i][2]) - phi(p, -d[i][0], -d[i][1], -d[i][2])) / (2 * h);
      worst_grad = std::max(worst_grad, std::abs(sign * t.grad[i] - fd) / scale_g);
    }
    // Second differences: diagonal and mixed (xx, yy, zz, xy, xz, yz).
    const int pairs[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};
    for (int k = 0; k < 6; ++k) {
      const double* a = d[pairs[k][0]];
      const double* b = d[pairs[k][1]];
      const double fpp = phi(p, a[0] + b[0], a[1] + b[1], a[2] + b[2]);
      const double fpm = phi(p, a[0] - b[0], a[1] - b[1], a[2] - b[2]);
      const double fmp = phi(p, -a[0] + b[0], -a[1] + b[1], -a[2] + b[2]);
      const double fmm = phi(p, -a[0] - b[0], -a[1] - b[1], -a[2] - b[2]);
      const double fd = (fpp - fpm - fmp + fmm) / (4 * h * h);
      worst_hess = std::max(worst_hess, std::abs(sign * t.hess[k] - fd) / scale_h);
    }
  }
  // Float vertices: the differences carry ~1e-7 / h (gradient) and ~1e-7 / h^2 (Hessian) of
  // rounding, relative to terms of order 1.
  EXPECT_LT(worst_grad, 1e-3);
  EXPECT_LT(worst_hess, 0.05);
}

TEST(IrradianceHessianTest, DegenerateEdgesAreRejected) {
  const double n[3] = {0, 0, 1};
  const double a[3] = {0, 0, 1}, b[3] = {0, 0, 2}, zero[3] = {0, 0, 0};
  EdgeTerm e;
  EXPECT_FALSE(ProjectedSolidAngleEdge(a, b, n, &e));  // on one line through x
  EXPECT_FALSE(ProjectedSolidAngleEdge(zero, b, n, &e));
  EXPECT_EQ(e.phi, 0);
}

// The tangent-frame edge terms the estimator sums (ProjectedSolidAngleEdgeLocal) are the world
// ones' tangent block with n = z, for random edges near and far, short and long.
TEST(IrradianceHessianTest, LocalEdgeTermsMatchTheWorldOnes) {
  Rng rng(21, 4);
  const double n[3] = {0, 0, 1};
  int compared = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const double scale = trial % 2 ? 0.01 : 1.0;  // every other edge short (fine strata)
    double r0[3], r1[3];
    for (int k = 0; k < 3; ++k) {
      r0[k] = 4 * rng.Next() - 2;
      r1[k] = r0[k] + scale * (2 * rng.Next() - 1);
    }
    EdgeTerm world;
    const bool w = ProjectedSolidAngleEdge(r0, r1, n, &world);
    const LocalVertex v0 = LocalVertex::At(r0[0], r0[1], r0[2]);
    const LocalVertex v1 = LocalVertex::At(r1[0], r1[1], r1[2]);
    TangentDerivatives sum;
    ASSERT_EQ(ProjectedSolidAngleEdgeLocal(v0, v1, 2.0, &sum), w);
    if (!w) continue;
    ++compared;
    const double g = std::max(std::abs(world.grad[0]), std::abs(world.grad[1]));
    const double h =
        std::max({std::abs(world.hess[0]), std::abs(world.hess[1]), std::abs(world.hess[3])});
    EXPECT_NEAR(sum.grad[0], 2 * world.grad[0], 1e-9 * g);
    EXPECT_NEAR(sum.grad[1], 2 * world.grad[1], 1e-9 * g);
    EXPECT_NEAR(sum.hess[0], 2 * world.hess[0], 1e-9 * h);
    EXPECT_NEAR(sum.hess[1], 2 * world.hess[1], 1e-9 * h);
    EXPECT_NEAR(sum.hess[2], 2 * world.hess[3], 1e-9 * h);
  }
  EXPECT_GT(compared, 1900);
  // Degenerate edges add nothing.
  TangentDerivatives none;
  const LocalVertex a = LocalVertex::At(0, 0, 1), b = LocalVertex::At(0, 0, 2);
  EXPECT_FALSE(ProjectedSolidAngleEdgeLocal(a, b, 1.0, &none));
  EXPECT_EQ(none.grad[0], 0);
  EXPECT_EQ(none.hess[0], 0);
}

// The edges in vector lanes (AddEdgesLocal, as the estimator sums them) add up to what they add one
// at a time, degenerate edges (a vertex at x, both on one line through x, overflowing values) and
// zero weights among them, in batches longer and shorter than one vector.
TEST(IrradianceHessianTest, EdgesInLanesSumAsOneAtATime) {
  Rng rng(5, 17);
  for (const int n : {1, 7, 64, 65, 300}) {
    std::vector<LocalVertex> v0, v1;
    std::vector<double> w;
    int degenerate = 0;
    for (int k = 0; k < n; ++k) {
      double r0[3], r1[3];
      for (int c = 0; c < 3; ++c) {
        r0[c] = 4 * rng.Next() - 2;
        r1[c] = r0[c] + (k % 2 ? 0.01 : 1.0) * (2 * rng.Next() - 1);
      }
      if (k % 11 == 3) r0[0] = r0[1] = r0[2] = 0;  // a vertex at x
      if (k % 13 == 5) {                           // both on one line through x
        for (int c = 0; c < 3; ++c) r1[c] = 2 * r0[c];
      }
      if (k % 17 == 6) {  // a vertex so near x that 1 / |r|^2 overflows: the terms are not finite
        r0[0] = 1e-155;
        r0[1] = 2e-155;
        r0[2] = 1e-155;
      }
      v0.push_back(LocalVertex::At(r0[0], r0[1], r0[2]));
      v1.push_back(LocalVertex::At(r1[0], r1[1], r1[2]));
      w.push_back(k % 7 == 2 ? 0.0 : 2 * rng.Next() - 1);
      TangentDerivatives one;
      degenerate += w.back() != 0 && !ProjectedSolidAngleEdgeLocal(v0.back(), v1.back(), 1, &one);
    }
    TangentDerivatives lanes, single;
    AddEdgesLocal(n, v0.data(), v1.data(), w.data(), &lanes);
    for (int k = 0; k < n; ++k)
      if (w[size_t(k)] != 0)
        ProjectedSolidAngleEdgeLocal(v0[size_t(k)], v1[size_t(k)], w[size_t(k)], &single);
    if (n >= 64) {
      EXPECT_GT(degenerate, 0) << n;
    }
    // The same bits: the file is built without fused multiply-adds (CMakeLists.txt), so every
    // clone of the lanes computes each edge as one edge at a time does.
    const double g = std::abs(single.grad[0]) + std::abs(single.grad[1]);
    const double h = std::abs(single.hess[0]) + std::abs(single.hess[1]) + std::abs(single.hess[2]);
    ASSERT_TRUE(std::isfinite(g) && std::isfinite(h)) << n;
    EXPECT_EQ(lanes.grad[0], single.grad[0]) << n;
    EXPECT_EQ(lanes.grad[1], single.grad[1]) << n;
    EXPECT_EQ(lanes.hess[0], single.hess[0]) << n;
    EXPECT_EQ(lanes.hess[1], single.hess[1]) << n;
    EXPECT_EQ(lanes.hess[2], single.hess[2]) << n;
  }
}

// A point under an infinite ceiling z = 1 of radiance `base`, with a lamp rectangle of radiance
// `lamp` on it: E(x) = pi base + (lamp - base) * Phi_rect(x), exact by Lambert's formula.
struct CeilingScene {
  float base = 0.2f, lamp = 1.0f;
  Vec3 rect[4] = {Vec3(-0.3f, -0.2f, 1), Vec3(0.5f, -0.2f, 1), Vec3(0.5f, 0.4f, 1),
                  Vec3(-0.3f, 0.4f, 1)};
  double E(double x, double y) const {
    Vec3 r[4];
    for (int k = 0; k < 4; ++k) r[k] = Vec3(float(rect[k].x - x), float(rect[k].y - y), rect[k].z);
    return kPi * base +
           (lamp - base) * PolygonProjectedSolidAngle(Vec3(0, 0, 0), Vec3(0, 0, 1), r, 4);
  }
  bool InLamp(const Vec3& p) const {
    return p.x >= rect[0].x && p.x <= rect[1].x && p.y >= rect[0].y && p.y <= rect[2].y;
  }
};

// Relative error of the grid's gradient and largest Hessian eigenvalue at x = 0 (T x P strata,
// rays through the strata centres) against finite differences of the exact E.
void GridErrors(const CeilingScene& sc, int T, int P, double* grad_err, double* hess_err) {
  std::vector<Vec3> pts(size_t(T * P));
  std::vector<float> lum(size_t(T * P));
  double sum = 0;
  for (int i = 0; i < T; ++i)
    for (int j = 0; j < P; ++j) {
      const Vec3 d = StratifiedCosineHemisphere(i, j, T, P, 0.5f, 0.5f);
      const Vec3 hit = d / d.z;  // the ceiling z = 1
      pts[size_t(i * P + j)] = hit;
      lum[size_t(i * P + j)] = sc.InLamp(hit) ? sc.lamp : sc.base;
      sum += lum[size_t(i * P + j)];
    }
  IrradianceDerivatives der;
  ASSERT_TRUE(EstimateIrradianceDerivatives(T, P, pts.data(), lum.data(), float(sum / (T * P)),
                                            Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0, 1, 0), &der));
  const double h = 1e-3, e0 = sc.E(0, 0);
  const double gx = (sc.E(h, 0) - sc.E(-h, 0)) / (2 * h) / e0;
  const double gy = (sc.E(0, h) - sc.E(0, -h)) / (2 * h) / e0;
  const double hxx = (sc.E(h, 0) - 2 * e0 + sc.E(-h, 0)) / (h * h) / e0;
  const double hyy = (sc.E(0, h) - 2 * e0 + sc.E(0, -h)) / (h * h) / e0;
  const double hxy = (sc.E(h, h) - sc.E(h, -h) - sc.E(-h, h) + sc.E(-h, -h)) / (4 * h * h) / e0;
  const double half_tr = 0.5 * (hxx + hyy);
  const double disc = std::sqrt(half_tr * half_tr - (hxx * hyy - hxy * hxy));
  const double lmax = std::max(std::abs(half_tr + disc), std::abs(half_tr - disc));
  *grad_err = std::hypot(der.gradient[0] - gx, der.gradient[1] - gy) / std::hypot(gx, gy);
  *hess_err = std::abs(der.hessian_max - lmax) / lmax;
}

// The grid's estimate converges to the exact derivatives as the strata get finer (the lamp's
// edges are approximated by the triangles' sides: first-order in the strata's size).
TEST(IrradianceHessianTest, GridDerivativesConvergeToTheExactOnes) {
  CeilingScene sc;
  double g1, h1, g2, h2, g3, h3;
  GridErrors(sc, 22, 70, &g1, &h1);  // the default record's 1540 strata
  GridErrors(sc, 44, 140, &g2, &h2);
  GridErrors(sc, 88, 280, &g3, &h3);
  std::printf("gradient error %.3f %.3f %.3f, Hessian error %.3f %.3f %.3f\n", g1, g2, g3, h1, h2,
              h3);
  EXPECT_LT(g3, g1);
  EXPECT_LT(h3, h1);
  EXPECT_LT(g3, 0.1);
  EXPECT_LT(h3, 0.2);
}

// A record's derivatives in its own frame do not depend on how that frame lies in the world:
// the same hemisphere (hit points and values in the frame) under a random rotation, and under a
// mirrored (left-handed) frame, gives the same tangent gradient and eigenvalues.
TEST(IrradianceHessianTest, DerivativesDoNotDependOnTheFramesPlacement) {
  const int T = 22, P = 70;
  Rng rng(8, 8);
  std::vector<Vec3> local(size_t(T * P));
  std::vector<float> lum(size_t(T * P));
  double sum = 0;
  for (int i = 0; i < T; ++i)
    for (int j = 0; j < P; ++j) {
      const Vec3 d = StratifiedCosineHemisphere(i, j, T, P, rng.Next(), rng.Next());
      local[size_t(i * P + j)] = d * (0.5f + 2 * rng.Next());  // a cluttered room
      lum[size_t(i * P + j)] = rng.Next() < 0.1f ? 5.0f : 0.2f + rng.Next();
      sum += lum[size_t(i * P + j)];
    }
  const auto derivatives = [&](const Vec3& s, const Vec3& t, const Vec3& n) {
    std::vector<Vec3> pts(local.size());
    for (size_t k = 0; k < local.size(); ++k)
      pts[k] = s * local[k].x + t * local[k].y + n * local[k].z;
    IrradianceDerivatives d;
    EXPECT_TRUE(EstimateIrradianceDerivatives(T, P, pts.data(), lum.data(), float(sum / (T * P)), n,
                                              s, t, &d));
    return d;
  };
  const IrradianceDerivatives base = derivatives(Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1));
  EXPECT_GT(base.hessian_max, 0);
  for (int trial = 0; trial < 8; ++trial) {
    const Vec3 n = UniformSphere(rng.Next(), rng.Next());
    Vec3 s, t;
    MakeFrame(n, &s, &t);
    if (trial % 2) std::swap(s, t);                        // mirrored: left-handed about n
    const IrradianceDerivatives d = derivatives(s, t, n);  // the same hemisphere in (s, t, n)
    const float tol = 1e-4f;
    EXPECT_NEAR(d.gradient[0], base.gradient[0], tol * std::abs(base.gradient[0]) + 1e-6f);
    EXPECT_NEAR(d.gradient[1], base.gradient[1], tol * std::abs(base.gradient[1]) + 1e-6f);
    EXPECT_NEAR(d.hessian_max, base.hessian_max, tol * base.hessian_max);
    EXPECT_NEAR(d.hessian_min, base.hessian_min, tol * base.hessian_max);
  }
}

TEST(IrradianceHessianTest, ErrorRadiusSolvesTheErrorModel) {
  IrradianceDerivatives d;
  EXPECT_EQ(ErrorRadius(d, 0.1f), INFINITY);
  d.gradient[0] = 3;
  d.gradient[1] = 4;  // |g| = 5
  EXPECT_NEAR(ErrorRadius(d, 0.1f), 0.02f, 1e-7f);
  d.hessian_max = 8;
  const float r = ErrorRadius(d, 0.1f);
  EXPECT_NEAR(5 * r + 0.5f * 8 * r * r, 0.1f, 1e-6f);
}

}  // namespace
}  // namespace irfarm
