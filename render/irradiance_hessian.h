// How fast a record's irradiance changes when its point moves: the gradient and the Hessian of
// irradiance with respect to translation, estimated from the record's own hemisphere samples
// (Schwarzhaupt, Jensen and Jarosz 2012, "Practical Hessian-Based Error Control for Irradiance
// Caching"; RADIANCE 4.2+ spaces its ambient records this way).
//
// The sample hit points, one per stratum of the record's T x P grid, are the vertices of a
// triangulated hemisphere; each triangle is a polygon of constant radiance (that of its farthest
// vertex, so that an occluder's edge in front of a brighter background counts). Irradiance is
// then E(x) = sum_tri v_tri Phi_tri(x), Phi the projected solid angle of the triangle seen from
// x, whose derivatives have a closed form per edge (Lambert's formula differentiated; Arvo 1994,
// "The Irradiance Jacobian for Partially Occluded Polyhedral Sources"). An edge shared by two
// triangles contributes with the difference of their values: where the radiance is the same on
// both sides nothing changes as x moves. Edges on the grid's rim (its first and last ring) are
// left out, as if the radiance beyond them were the same as inside.
//
// The record's validity radius then follows from the error of using its value a distance r
// away: |g| r + 1/2 lambda r^2 (relative irradiance; lambda the Hessian's largest eigenvalue in
// the tangent plane), where Ward's split-sphere rule bounds the gradient alone, by the worst
// case for the distances the rays found.
#pragma once

#include "core/math.h"

namespace irfarm {

// Lambert's term of the directed edge from r0 to r1 (vertices relative to the viewpoint x) in the
// projected solid angle around normal n: phi = 1/2 angle(r0, r1) (n . unit(r0 x r1)). A convex
// polygon's projected solid angle (when above the horizon) is |sum of its edges' phi|, all edges
// taken in one order; grad and hess (xx, yy, zz, xy, xz, yz) are phi's derivatives with respect
// to x.
struct EdgeTerm {
  double phi = 0;
  double grad[3] = {0, 0, 0};
  double hess[6] = {0, 0, 0, 0, 0, 0};
};
// False (and out zeroed) when the edge is degenerate seen from x (a vertex at x, or both
// vertices on one line through x).
bool ProjectedSolidAngleEdge(const double r0[3], const double r1[3], const double n[3],
                             EdgeTerm* out);

// The same edge term's derivatives in a frame whose z axis is n, tangent components only: for
// vertices given in that frame (r, with q = |r|^2 and 1 / q), adds weight times d phi / dx,
// d phi / dy to sum->grad and the Hessian's xx, yy, xy to sum->hess. False (nothing added) where
// ProjectedSolidAngleEdge is false.
struct LocalVertex {
  double r[3];
  double q, inv_q;
  static LocalVertex At(double x, double y, double z) {
    const double q = x * x + y * y + z * z;
    return LocalVertex{{x, y, z}, q, 1 / q};
  }
};
struct TangentDerivatives {
  double grad[2] = {0, 0};
  double hess[3] = {0, 0, 0};  // xx, yy, xy
};
bool ProjectedSolidAngleEdgeLocal(const LocalVertex& v0, const LocalVertex& v1, double weight,
                                  TangentDerivatives* sum);
// The same for n edges v0[k] -> v1[k] with weight[k], as vector lanes where the machine has them
// (AVX-512, AVX2): the sums ProjectedSolidAngleEdgeLocal would make one edge at a time, in
// the same order, to the bit. Edges of weight 0 are skipped (they add nothing).
void AddEdgesLocal(int n, const LocalVertex* v0, const LocalVertex* v1, const double* weight,
                   TangentDerivatives* sum);

struct IrradianceDerivatives {
  // Relative to the record's irradiance luminance, in the tangent frame (s, t) given.
  float gradient[2] = {0, 0};
  float hessian_max = 0;  // largest |eigenvalue| of the 2x2 tangent Hessian
  float hessian_min = 0;
};

// From a record's T x P strata (theta-major: index i * P + j, phi wrapping around): `points`
// the hit points relative to the record (missed rays placed far along their direction) and `lum`
// the luminance of the radiance each brought. `mean_lum` normalizes (the record's mean sample
// luminance). False when the record is too small a grid (T < 3 or P < 3) or dark.
bool EstimateIrradianceDerivatives(int T, int P, const Vec3* points, const float* lum,
                                   float mean_lum, const Vec3& n, const Vec3& s, const Vec3& t,
                                   IrradianceDerivatives* out);

// The distance at which |g| r + 1/2 lambda r^2 reaches `error` (relative irradiance); infinity
// when both are zero.
float ErrorRadius(const IrradianceDerivatives& d, float error);

}  // namespace irfarm
