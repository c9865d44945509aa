#include "render/irradiance_hessian.h"

#include <algorithm>
#include <cmath>

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

bool ProjectedSolidAngleEdgeLocal(const LocalVertex& v0, const LocalVertex& v1, double weight,
                                  TangentDerivatives* sum) {
  const double* r0 = v0.r;
  const double* r1 = v1.r;
  const double e[3] = {r1[0] - r0[0], r1[1] - r0[1], r1[2] - r0[2]};
  double c[3];
  Cross3(r0, r1, c);
  const double c2 = Dot3(c, c), q0 = v0.q, q1 = v1.q;
  // As ProjectedSolidAngleEdge (the same integrals, n the frame's z axis).
  if (!(q0 > 0) || !(q1 > 0) || !(c2 > 1e-24 * q0 * q1) || !std::isfinite(c2)) return false;
  const double len_c = std::sqrt(c2);
  // Atan2 (core/fast_trig.h): within 3e-14 of libm's, in half the time; this angle was a fifth
  // of a record's Hessian.
  const double theta = Atan2(len_c, Dot3(r0, r1));
  const double a = Dot3(e, e), b = Dot3(e, r0), er1 = Dot3(e, r1);
  const double inv_c2 = 1 / c2, inv_a = 1 / a;
  const double iq0 = v0.inv_q, iq1 = v1.inv_q;
  const double I1 = theta * len_c * inv_c2;
  const double I2 = (er1 * iq1 - b * iq0 + a * I1) * (0.5 * inv_c2);
  const double J2 = ((iq0 - iq1) * 0.5 - b * I2) * inv_a;
  const double I3 = (er1 * iq1 * iq1 - b * iq0 * iq0 + 3 * a * I2) * (0.25 * inv_c2);
  const double J3 = ((iq0 * iq0 - iq1 * iq1) * 0.25 - b * I3) * inv_a;
  const double K3 = (I2 - 2 * b * J3 - q0 * I3) * inv_a;
  const double nc = c[2];
  const double nxe[2] = {-e[1], e[0]};  // z x e
  const double G[2] = {I2 * r0[0] + J2 * e[0], I2 * r0[1] + J2 * e[1]};
  const double gx = 0.5 * I1 * nxe[0] + nc * G[0];
  const double gy = 0.5 * I1 * nxe[1] + nc * G[1];
  // The tangent block (xx, yy, xy) of ProjectedSolidAngleEdge's Hessian.
  const double s_rr = 4 * nc * I3, s_ee = 4 * nc * K3, s_re = 4 * nc * J3;
  const double hxx = 2 * nxe[0] * G[0] + s_rr * r0[0] * r0[0] + s_ee * e[0] * e[0] +
                     2 * s_re * r0[0] * e[0] - nc * I2;
  const double hyy = 2 * nxe[1] * G[1] + s_rr * r0[1] * r0[1] + s_ee * e[1] * e[1] +
                     2 * s_re * r0[1] * e[1] - nc * I2;
  const double hxy = nxe[0] * G[1] + nxe[1] * G[0] + s_rr * r0[0] * r0[1] + s_ee * e[0] * e[1] +
                     s_re * (r0[0] * e[1] + r0[1] * e[0]);
  if (!std::isfinite(hxx) || !std::isfinite(hyy) || !std::isfinite(hxy)) return false;
  sum->grad[0] += weight * gx;
  sum->grad[1] += weight * gy;
  sum->hess[0] += weight * hxx;
  sum->hess[1] += weight * hyy;
  sum->hess[2] += weight * hxy;
  return true;
}

bool EstimateIrradianceDerivatives(int T, int P, const Vec3* points, const float* lum,
                                   float mean_lum, const Vec3& n, const Vec3& s, const Vec3& t,
                                   IrradianceDerivatives* out) {
  *out = IrradianceDerivatives{};
  if (T < 3 || P < 3 || P > kMaxPhiStrata || !(mean_lum > 0) || !std::isfinite(mean_lum))
    return false;
  const double inv_mean = 1.0 / double(mean_lum);
  const auto at = [&](int i, int j) { return i * P + (j >= P ? j - P : (j < 0 ? j + P : j)); };
  // A triangle's radiance: its farthest vertex's, relative to the record's mean.
  const auto back = [&](int v0, int v1, int v2) {
    const float d0 = LengthSquared(points[v0]), d1 = LengthSquared(points[v1]),
                d2 = LengthSquared(points[v2]);
    const int far = d0 >= d1 ? (d0 >= d2 ? v0 : v2) : (d1 >= d2 ? v1 : v2);
    return std::min(double(lum[far]) * inv_mean, kMaxRelativeValue);
  };
  // The vertices in the frame (s, t, n), with their squared distances and inverses: each is on
  // six edges, and the derivatives are wanted in the tangent plane only.
  const auto local = [&](int k) {
    const Vec3& p = points[k];
    return LocalVertex::At(double(p.x) * s.x + double(p.y) * s.y + double(p.z) * s.z,
                           double(p.x) * t.x + double(p.y) * t.y + double(p.z) * t.z,
                           double(p.x) * n.x + double(p.y) * n.y + double(p.z) * n.z);
  };
  TangentDerivatives sum;
  const auto edge = [&](const LocalVertex& v0, const LocalVertex& v1, double weight) {
    if (weight == 0) return;  // the same radiance on both sides: nothing changes
    ProjectedSolidAngleEdgeLocal(v0, v1, weight, &sum);
  };
  // Band i lies between rings i and i + 1; in column j its lower triangle is (i,j) (i,j+1)
  // (i+1,j) and its upper one (i+1,j+1) (i+1,j) (i,j+1), both wound the same way. Each edge is
  // taken in one direction, weighted by the value of the triangle that runs along it that way
  // minus the value of the one that runs along it the other way.
  double upper_prev[kMaxPhiStrata];    // band i - 1's upper triangle values
  LocalVertex ring[2][kMaxPhiStrata];  // rings i and i + 1 in the local frame
  for (int j = 0; j < P; ++j) ring[0][j] = local(at(0, j));
  for (int i = 0; i + 1 < T; ++i) {
    const LocalVertex* lo = ring[i & 1];
    LocalVertex* hi = ring[(i + 1) & 1];
    for (int j = 0; j < P; ++j) hi[j] = local(at(i + 1, j));
    double lower[kMaxPhiStrata], upper[kMaxPhiStrata];
    for (int j = 0; j < P; ++j) {
      lower[j] = back(at(i, j), at(i, j + 1), at(i + 1, j));
      upper[j] = back(at(i + 1, j + 1), at(i + 1, j), at(i, j + 1));
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
