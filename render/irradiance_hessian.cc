#include "render/irradiance_hessian.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/fast_trig.h"

namespace irfarm {
namespace {

double Dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
void Cross3(const double* a, const double* b, double* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}
// Symmetric 3x3 stored as xx, yy, zz, xy, xz, yz: adds s * (a b^T + b a^T).
void AddSymOuter(double s, const double* a, const double* b, double* h) {
  h[0] += s * 2 * a[0] * b[0];
  h[1] += s * 2 * a[1] * b[1];
  h[2] += s * 2 * a[2] * b[2];
  h[3] += s * (a[0] * b[1] + a[1] * b[0]);
  h[4] += s * (a[0] * b[2] + a[2] * b[0]);
  h[5] += s * (a[1] * b[2] + a[2] * b[1]);
}

// A sample brighter than this many times the record's mean counts as this bright in the
// derivatives: one path-traced firefly would otherwise shrink the record to its minimum.
constexpr double kMaxRelativeValue = 8.0;
// Widest grid handled (P strata around the normal): one band of triangle values on the stack.
constexpr int kMaxPhiStrata = 1024;
constexpr double kMaxFinite = std::numeric_limits<double>::max();

}  // namespace

bool ProjectedSolidAngleEdge(const double r0[3], const double r1[3], const double n[3],
                             EdgeTerm* out) {
  *out = EdgeTerm{};
  const double e[3] = {r1[0] - r0[0], r1[1] - r0[1], r1[2] - r0[2]};
  double c[3];
  Cross3(r0, r1, c);
  const double c2 = Dot3(c, c), q0 = Dot3(r0, r0), q1 = Dot3(r1, r1), a = Dot3(e, e);
  // Both vertices on one line through x: the edge subtends nothing and the integrals below
  // (over 1 / |r0 + t e|^k) lose all their digits.
  if (!(q0 > 0) || !(q1 > 0) || !(c2 > 1e-24 * q0 * q1) || !std::isfinite(c2)) return false;
  const double len_c = std::sqrt(c2);
  const double theta = std::atan2(len_c, Dot3(r0, r1));
  const double b = Dot3(e, r0), er1 = Dot3(e, r1);
  // Integrals over the edge r(t) = r0 + t e, t in [0, 1], of t^m / |r(t)|^(2k), from the
  // quadratic |r(t)|^2 = a t^2 + 2 b t + q0 with discriminant a q0 - b^2 = |r0 x r1|^2.
  const double I1 = theta / len_c;                                              // 1 / |r|^2
  const double I2 = (er1 / q1 - b / q0 + a * I1) / (2 * c2);                    // 1 / |r|^4
  const double J2 = ((1 / q0 - 1 / q1) * 0.5 - b * I2) / a;                     // t / |r|^4
  const double I3 = (er1 / (q1 * q1) - b / (q0 * q0) + 3 * a * I2) / (4 * c2);  // 1 / |r|^6
  const double J3 = ((1 / (q0 * q0) - 1 / (q1 * q1)) * 0.25 - b * I3) / a;      // t / |r|^6
  const double K3 = (I2 - 2 * b * J3 - q0 * I3) / a;                            // t^2 / |r|^6
  const double nc = Dot3(n, c);
  double nxe[3];
  Cross3(n, e, nxe);
  // phi = 1/2 (n . c) I1; with r = p - x: grad (n . c) = n x e, grad (1 / |r|^2) = 2 r / |r|^4.
  out->phi = 0.5 * nc * I1;
  // G = integral of r / |r|^4 = I2 r0 + J2 e.
  const double G[3] = {I2 * r0[0] + J2 * e[0], I2 * r0[1] + J2 * e[1], I2 * r0[2] + J2 * e[2]};
  for (int k = 0; k < 3; ++k) out->grad[k] = 0.5 * I1 * nxe[k] + nc * G[k];
  // Hessian: (n x e) G^T + G (n x e)^T + (n . c) grad G, with
  // grad G = integral of (4 r r^T / |r|^6 - I / |r|^4).
  double* h = out->hess;
  AddSymOuter(1, nxe, G, h);
  AddSymOuter(2 * nc * I3, r0, r0, h);
  AddSymOuter(2 * nc * K3, e, e, h);
  AddSymOuter(4 * nc * J3, r0, e, h);
  h[0] -= nc * I2;
  h[1] -= nc * I2;
  h[2] -= nc * I2;
  for (int k = 0; k < 6; ++k)
    if (!std::isfinite(h[k])) {
      *out = EdgeTerm{};
      return false;
    }
  return true;
}

namespace {

// One edge's tangent terms for ProjectedSolidAngleEdgeLocal, without branches: every step is
// computed for every edge and the degenerate or non-finite ones come out as zeros with false, so
// that a loop over many edges (EdgeBatch) runs as vector lanes.
__attribute__((always_inline)) inline bool EdgeTermsLocal(double x0, double y0, double z0,
                                                          double q0, double iq0, double x1,
                                                          double y1, double z1, double q1,
                                                          double iq1, double weight, double* gx,
                                                          double* gy, double* hxx, double* hyy,
                                                          double* hxy) {
  const double ex = x1 - x0, ey = y1 - y0, ez = z1 - z0;
  const double cx = y0 * z1 - z0 * y1, cy = z0 * x1 - x0 * z1, cz = x0 * y1 - y0 * x1;
  const double c2 = cx * cx + cy * cy + cz * cz;
  // As ProjectedSolidAngleEdge (the same integrals, n the frame's z axis).
  const bool ok = (q0 > 0) & (q1 > 0) & (c2 > 1e-24 * q0 * q1) & (c2 <= kMaxFinite);
  // Stand-ins for the degenerate lanes, so that no lane divides by zero.
  const double c2s = ok ? c2 : 1.0;
  const double len_c = std::sqrt(c2s);
  // Atan2Positive (core/fast_trig.h): within 3e-14 of libm's, and no branch.
  const double theta = Atan2Positive(len_c, x0 * x1 + y0 * y1 + z0 * z1);
  const double a = ok ? ex * ex + ey * ey + ez * ez : 1.0;
  const double b = ex * x0 + ey * y0 + ez * z0, er1 = ex * x1 + ey * y1 + ez * z1;
  const double inv_c2 = 1 / c2s, inv_a = 1 / a;
  const double I1 = theta * len_c * inv_c2;
  const double I2 = (er1 * iq1 - b * iq0 + a * I1) * (0.5 * inv_c2);
  const double J2 = ((iq0 - iq1) * 0.5 - b * I2) * inv_a;
  const double I3 = (er1 * iq1 * iq1 - b * iq0 * iq0 + 3 * a * I2) * (0.25 * inv_c2);
  const double J3 = ((iq0 * iq0 - iq1 * iq1) * 0.25 - b * I3) * inv_a;
  const double K3 = (I2 - 2 * b * J3 - q0 * I3) * inv_a;
  const double nc = cz;
  const double nxe0 = -ey, nxe1 = ex;  // z x e
  const double G0 = I2 * x0 + J2 * ex, G1 = I2 * y0 + J2 * ey;
  const double g0 = 0.5 * I1 * nxe0 + nc * G0;
  const double g1 = 0.5 * I1 * nxe1 + nc * G1;
  // The tangent block (xx, yy, xy) of ProjectedSolidAngleEdge's Hessian.
  const double s_rr = 4 * nc * I3, s_ee = 4 * nc * K3, s_re = 4 * nc * J3;
  const double h00 = 2 * nxe0 * G0 + s_rr * x0 * x0 + s_ee * ex * ex + 2 * s_re * x0 * ex - nc * I2;
  const double h11 = 2 * nxe1 * G1 + s_rr * y0 * y0 + s_ee * ey * ey + 2 * s_re * y0 * ey - nc * I2;
  const double h01 =
      nxe0 * G1 + nxe1 * G0 + s_rr * x0 * y0 + s_ee * ex * ey + s_re * (x0 * ey + y0 * ex);
  // Finite: |h| <= the largest double (false for infinities and NaN).
  const bool f00 = std::abs(h00) <= kMaxFinite, f11 = std::abs(h11) <= kMaxFinite,
             f01 = std::abs(h01) <= kMaxFinite;
  const bool keep = ok & f00 & f11 & f01;
  *gx = keep ? weight * g0 : 0.0;
  *gy = keep ? weight * g1 : 0.0;
  *hxx = keep ? weight * h00 : 0.0;
  *hyy = keep ? weight * h11 : 0.0;
  *hxy = keep ? weight * h01 : 0.0;
  return keep;
}

// Edges gathered for EdgeTermsLocal in batches (arrays of each coordinate, for vector lanes):
// a record's Hessian has three edges per stratum, 4.6 thousand for the default 22 x 70, and one
// at a time they were a tenth of a record's time.
struct EdgeBatch {
  static constexpr int kSize = 64;
  int n = 0;
  alignas(64) double x0[kSize], y0[kSize], z0[kSize], q0[kSize], iq0[kSize];
  alignas(64) double x1[kSize], y1[kSize], z1[kSize], q1[kSize], iq1[kSize];
  alignas(64) double w[kSize];
  alignas(64) double out[5][kSize];  // weighted gx, gy, hxx, hyy, hxy
};

// The batch's terms, in vector lanes where the machine has them: with GCC, one clone of the loop
// for AVX-512, one for AVX2 and one for the baseline (SSE2, scalar), picked when the program loads.
// Not under ThreadSanitizer (GCC instruments the clones' resolver, which the dynamic loader runs
// before TSan is set up: the program crashed at load) nor with other compilers (clang 14 resolves
// the x86-64-v3/v4 clones wrongly).
#if defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#endif
void BatchEdgeTerms(
    EdgeBatch& b) {
  for (int k = 0; k < b.n; ++k)
    EdgeTermsLocal(b.x0[k], b.y0[k], b.z0[k], b.q0[k], b.iq0[k], b.x1[k], b.y1[k], b.z1[k], b.q1[k],
                   b.iq1[k], b.w[k], &b.out[0][k], &b.out[1][k], &b.out[2][k], &b.out[3][k],
                   &b.out[4][k]);
}

// Adds the batch's terms to `sum` in edge order (the order ProjectedSolidAngleEdgeLocal would)
// and empties it.
void FlushEdges(EdgeBatch& b, TangentDerivatives* sum) {
  BatchEdgeTerms(b);
  for (int k = 0; k < b.n; ++k) {
    sum->grad[0] += b.out[0][k];
    sum->grad[1] += b.out[1][k];
    sum->hess[0] += b.out[2][k];
    sum->hess[1] += b.out[3][k];
    sum->hess[2] += b.out[4][k];
  }
  b.n = 0;
}

void AddEdge(const LocalVertex& v0, const LocalVertex& v1, double weight, EdgeBatch& b,
             TangentDerivatives* sum) {
  if (weight == 0) return;  // the same radiance on both sides: nothing changes
  const int k = b.n++;
  b.x0[k] = v0.r[0];
  b.y0[k] = v0.r[1];
  b.z0[k] = v0.r[2];
  b.q0[k] = v0.q;
  b.iq0[k] = v0.inv_q;
  b.x1[k] = v1.r[0];
  b.y1[k] = v1.r[1];
  b.z1[k] = v1.r[2];
  b.q1[k] = v1.q;
  b.iq1[k] = v1.inv_q;
  b.w[k] = weight;
  if (b.n == EdgeBatch::kSize) FlushEdges(b, sum);
}

}  // namespace

bool ProjectedSolidAngleEdgeLocal(const LocalVertex& v0, const LocalVertex& v1, double weight,
                                  TangentDerivatives* sum) {
  double gx, gy, hxx, hyy, hxy;
  if (!EdgeTermsLocal(v0.r[0], v0.r[1], v0.r[2], v0.q, v0.inv_q, v1.r[0], v1.r[1], v1.r[2], v1.q,
                      v1.inv_q, weight, &gx, &gy, &hxx, &hyy, &hxy))
    return false;
  sum->grad[0] += gx;
  sum->grad[1] += gy;
  sum->hess[0] += hxx;
  sum->hess[1] += hyy;
  sum->hess[2] += hxy;
  return true;
}

void AddEdgesLocal(int n, const LocalVertex* v0, const LocalVertex* v1, const double* weight,
                   TangentDerivatives* sum) {
  EdgeBatch batch;
  for (int k = 0; k < n; ++k) AddEdge(v0[k], v1[k], weight[k], batch, sum);
  FlushEdges(batch, sum);
}

bool EstimateIrradianceDerivatives(int T, int P, const Vec3* points, const float* lum,
                                   float mean_lum, const Vec3& n, const Vec3& s, const Vec3& t,
                                   IrradianceDerivatives* out) {
  *out = IrradianceDerivatives{};
  if (T < 3 || P < 3 || P > kMaxPhiStrata || !(mean_lum > 0) || !std::isfinite(mean_lum))
    return false;
  const double inv_mean = 1.0 / double(mean_lum);
  // The vertices in the frame (s, t, n), with their squared distances and inverses: each is on
  // six edges, and the derivatives are wanted in the tangent plane only.
  const auto local = [&](int k) {
    const Vec3& p = points[k];
    return LocalVertex::At(double(p.x) * s.x + double(p.y) * s.y + double(p.z) * s.z,
                           double(p.x) * t.x + double(p.y) * t.y + double(p.z) * t.z,
                           double(p.x) * n.x + double(p.y) * n.y + double(p.z) * n.z);
  };
  TangentDerivatives sum;
  EdgeBatch batch;  // the edges, in batches for vector lanes (AddEdgesLocal)
  const auto edge = [&](const LocalVertex& v0, const LocalVertex& v1, double weight) {
    AddEdge(v0, v1, weight, batch, &sum);
  };
  // Band i lies between rings i and i + 1; in column j its lower triangle is (i,j) (i,j+1)
  // (i+1,j) and its upper one (i+1,j+1) (i+1,j) (i,j+1), both wound the same way. Each edge is
  // taken in one direction, weighted by the value of the triangle that runs along it that way
  // minus the value of the one that runs along it the other way.
  double upper_prev[kMaxPhiStrata];  // band i - 1's upper triangle values
  // Rings i and i + 1: the vertices in the local frame, their squared distances (in float, as
  // the points are) and values relative to the record's mean.
  LocalVertex ring[2][kMaxPhiStrata];
  float ring_d2[2][kMaxPhiStrata];
  double ring_rel[2][kMaxPhiStrata];
  const auto load_ring = [&](int i, int slot) {
    for (int j = 0; j < P; ++j) {
      const int k = i * P + j;
      ring[slot][j] = local(k);
      ring_d2[slot][j] = LengthSquared(points[k]);
      ring_rel[slot][j] = std::min(double(lum[k]) * inv_mean, kMaxRelativeValue);
    }
  };
  // A triangle's radiance: its farthest vertex's (vertex j of ring slot r), relative to the mean.
  const auto back = [&](int r0, int j0, int r1, int j1, int r2, int j2) {
    const float d0 = ring_d2[r0][j0], d1 = ring_d2[r1][j1], d2 = ring_d2[r2][j2];
    return d0 >= d1 ? (d0 >= d2 ? ring_rel[r0][j0] : ring_rel[r2][j2])
                    : (d1 >= d2 ? ring_rel[r1][j1] : ring_rel[r2][j2]);
  };
  load_ring(0, 0);
  for (int i = 0; i + 1 < T; ++i) {
    const int l = i & 1, h = (i + 1) & 1;
    load_ring(i + 1, h);
    const LocalVertex* lo = ring[l];
    const LocalVertex* hi = ring[h];
    double lower[kMaxPhiStrata], upper[kMaxPhiStrata];
    for (int j = 0; j < P; ++j) {
      const int j1 = j + 1 == P ? 0 : j + 1;
      lower[j] = back(l, j, l, j1, h, j);
      upper[j] = back(h, j1, h, j, l, j1);
    }
    for (int j = 0; j < P; ++j) {
      const int j1 = j + 1 == P ? 0 : j + 1;
      // Diagonal (i,j+1) -> (i+1,j): lower(i,j) against upper(i,j).
      edge(lo[j1], hi[j], lower[j] - upper[j]);
      // Meridian (i,j) -> (i+1,j): upper(i,j-1) against lower(i,j).
      edge(lo[j], hi[j], upper[j == 0 ? P - 1 : j - 1] - lower[j]);
      // Ring i (not the rim) (i,j) -> (i,j+1): lower(i,j) against band i-1's upper(i-1,j).
      if (i > 0) edge(lo[j], lo[j1], lower[j] - upper_prev[j]);
    }
    std::copy(upper, upper + P, upper_prev);
  }
  FlushEdges(batch, &sum);
  // E / E_record = sum v_rel Phi / pi. With phi growing counter-clockwise about n, the grid's
  // directions in the frame (s, t, n) are right-handed whatever the handedness of s, t, n in the
  // world; the triangles above run clockwise seen from above n: their edge terms sum to -Phi.
  const double orient = -kInvPi;
  out->gradient[0] = float(orient * sum.grad[0]);
  out->gradient[1] = float(orient * sum.grad[1]);
  const double hss = orient * sum.hess[0], htt = orient * sum.hess[1], hst = orient * sum.hess[2];
  const double half_tr = 0.5 * (hss + htt);
  const double disc = std::sqrt(std::max(0.0, half_tr * half_tr - (hss * htt - hst * hst)));
  const double l0 = std::abs(half_tr + disc), l1 = std::abs(half_tr - disc);
  out->hessian_max = float(std::max(l0, l1));
  out->hessian_min = float(std::min(l0, l1));
  return std::isfinite(out->hessian_max) && std::isfinite(out->gradient[0]) &&
         std::isfinite(out->gradient[1]);
}

float ErrorRadius(const IrradianceDerivatives& d, float error) {
  const double g = std::hypot(double(d.gradient[0]), double(d.gradient[1]));
  const double l = d.hessian_max;
  if (!(g > 0) && !(l > 0)) return INFINITY;
  // Root of 1/2 l r^2 + g r - error in the form that stays exact when l r << g.
  return float(2 * double(error) / (g + std::sqrt(g * g + 2 * l * double(error))));
}

}  // namespace irfarm
