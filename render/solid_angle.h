// Solid-angle sampling of area lights and the analytic irradiance of polygons, as seen from a
// shading point. Sampling a lamp by its area gives a solid-angle pdf d^2 / (cos_l A) that blows
// up next to the lamp (fireflies on a wall the lamp touches); sampling the solid angle it
// subtends keeps L cos / pdf = L cos * Omega bounded by L * Omega.
//   SphericalRect: Urena, Fajardo and King 2013, "An Area-Preserving Parametrization for
//     Spherical Rectangles" (uniform in the rectangle's solid angle).
//   SphericalTriangle: Arvo 1995, "Stratified Sampling of Spherical Triangles".
//   Spheres: the cone of directions (UniformCone in sampling.h).
//   PolygonProjectedSolidAngle: Lambert's formula for the cosine-weighted solid angle of a
//     polygon clipped to the hemisphere above the surface; a uniform emitter of radiance L
//     gives irradiance E = L * PolygonProjectedSolidAngle.
// The triangle and polygon geometry is done in double: the angles are differences of numbers
// near pi, and a lamp far away subtends a solid angle well below float precision of those.
#pragma once

#include "core/math.h"

namespace irfarm {

class SphericalRect {
 public:
  // Rectangle corner + edges ex, ey (orthogonal), seen from o. False when o is (numerically) in
  // the rectangle's plane or the solid angle is too small to sample this way (below 1e-3 sr:
  // callers then sample by area).
  bool Init(const Vec3& o, const Vec3& corner, const Vec3& ex, const Vec3& ey);
  float solid_angle() const { return S_; }
  // A point on the rectangle, uniform in solid angle for (u, v) uniform in [0,1)^2.
  Vec3 Sample(float u, float v) const;

 private:
  Vec3 o_, x_, y_, z_;
  float x0_, y0_, x1_, y1_, z0_, b0_, b1_, k_, S_ = 0;
};

class SphericalTriangle {
 public:
  // Triangle a, b, c seen from o. False when degenerate or too small to sample this way.
  bool Init(const Vec3& o, const Vec3& a, const Vec3& b, const Vec3& c);
  double solid_angle() const { return area_; }
  // A unit direction from o into the triangle, uniform in solid angle.
  Vec3 Sample(float u, float v) const;

 private:
  double A_[3], B_[3], C_[3];
  double alpha_ = 0, cos_c_ = 0, area_ = 0;
};

// Solid angle of the triangle (a, b, c) seen from o (Van Oosterom and Strackee 1983), >= 0.
double TriangleSolidAngle(const Vec3& o, const Vec3& a, const Vec3& b, const Vec3& c);

// Integral of max(0, n . w) dw over the directions w from x through the convex planar polygon
// `verts` (count <= 8), clipped to the hemisphere n . w >= 0. Units: steradians (projected).
double PolygonProjectedSolidAngle(const Vec3& x, const Vec3& n, const Vec3* verts, int count);

}  // namespace irfarm
