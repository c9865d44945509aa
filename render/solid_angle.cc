#include "render/solid_angle.h"

#include <algorithm>
#include <cmath>

#include "core/fast_trig.h"

namespace irfarm {
namespace {

constexpr double kPiD = 3.14159265358979323846;

struct D3 {
  double x = 0, y = 0, z = 0;
};
D3 ToD(const Vec3& v) { return D3{v.x, v.y, v.z}; }
D3 Sub(const D3& a, const D3& b) { return D3{a.x - b.x, a.y - b.y, a.z - b.z}; }
D3 Add(const D3& a, const D3& b) { return D3{a.x + b.x, a.y + b.y, a.z + b.z}; }
D3 Mul(const D3& a, double s) { return D3{a.x * s, a.y * s, a.z * s}; }
double DotD(const D3& a, const D3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
D3 CrossD(const D3& a, const D3& b) {
  return D3{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double LenD(const D3& a) { return std::sqrt(DotD(a, a)); }
D3 NormD(const D3& a) {
  const double l = LenD(a);
  return l > 0 ? Mul(a, 1 / l) : D3{};
}
double SafeAcos(double c) { return std::acos(std::clamp(c, -1.0, 1.0)); }
// Angle at P between the great arcs P->Q and P->R.
double VertexAngle(const D3& p, const D3& q, const D3& r) {
  return SafeAcos(DotD(NormD(CrossD(p, q)), NormD(CrossD(p, r))));
}
void Store(const D3& v, double* out) {
  out[0] = v.x;
  out[1] = v.y;
  out[2] = v.z;
}
D3 Load(const double* v) { return D3{v[0], v[1], v[2]}; }

// Below this solid angle the samplers' angle differences lose their digits; callers then fall
// back to sampling by area, whose pdf is harmless for a far, small emitter.
constexpr double kMinSolidAngle = 1e-8;

}  // namespace

// In float: double made light sampling a third of a record's time (perf, cornell-box). Float
// keeps ~1e-6 absolute precision on the angles (near pi), so solid angles below
// kMinRectSolidAngle, whose digits that would eat, are left to area sampling (Init fails), which
// is harmless for so small (far) a lamp.
constexpr float kMinRectSolidAngle = 1e-3f;

bool SphericalRect::Init(const Vec3& o, const Vec3& corner, const Vec3& ex, const Vec3& ey) {
  const float exl = Length(ex), eyl = Length(ey);
  if (!(exl > 0) || !(eyl > 0)) return false;
  const Vec3 x = ex / exl, y = ey / eyl;
  Vec3 z = Cross(x, y);
  const Vec3 d = corner - o;
  float z0 = Dot(d, z);
  if (z0 > 0) {  // the frame is chosen so that the rectangle lies at z0 < 0
    z = -z;
    z0 = -z0;
  }
  const float x0 = Dot(d, x), y0 = Dot(d, y);
  const float x1 = x0 + exl, y1 = y0 + eyl;
  // In the rectangle's plane it subtends nothing.
  if (!(std::abs(z0) > 1e-6f * std::max({std::abs(x0), std::abs(x1), std::abs(y0), std::abs(y1)})))
    return false;
  const Vec3 n0 = Normalize(Vec3(0, z0, -y0));
  const Vec3 n1 = Normalize(Vec3(-z0, 0, x1));
  const Vec3 n2 = Normalize(Vec3(0, -z0, y1));
  const Vec3 n3 = Normalize(Vec3(z0, 0, -x0));
  auto acos_clamped = [](float c) { return std::acos(std::clamp(c, -1.0f, 1.0f)); };
  const float g0 = acos_clamped(-Dot(n0, n1));
  const float g1 = acos_clamped(-Dot(n1, n2));
  const float g2 = acos_clamped(-Dot(n2, n3));
  const float g3 = acos_clamped(-Dot(n3, n0));
  b0_ = n0.z;
  b1_ = n2.z;
  k_ = 2 * kPi - g2 - g3;
  S_ = g0 + g1 - k_;
  if (!(S_ > kMinRectSolidAngle)) return false;
  o_ = o;
  x_ = x;
  y_ = y;
  z_ = z;
  x0_ = x0;
  y0_ = y0;
  x1_ = x1;
  y1_ = y1;
  z0_ = z0;
  return true;
}

Vec3 SphericalRect::Sample(float u, float v) const {
  const float au = u * S_ + k_;
  const float sa = std::sin(au), ca = std::cos(au);
  const float fu = std::abs(sa) > 1e-30f ? (ca * b0_ - b1_) / sa : 1e30f;
  float cu = (fu > 0 ? 1.0f : -1.0f) / std::sqrt(fu * fu + b0_ * b0_);
  cu = std::clamp(cu, -1.0f, 1.0f);
  float xu = -(cu * z0_) / std::max(std::sqrt(1 - cu * cu), 1e-30f);
  xu = std::clamp(xu, x0_, x1_);
  const float dd = std::sqrt(xu * xu + z0_ * z0_);
  const float h0 = y0_ / std::sqrt(dd * dd + y0_ * y0_);
  const float h1 = y1_ / std::sqrt(dd * dd + y1_ * y1_);
  const float hv = h0 + v * (h1 - h0), hv2 = hv * hv;
  const float yv = hv2 < 1 - 1e-6f ? (hv * dd) / std::sqrt(1 - hv2) : y1_;
  const float yc = std::clamp(yv, y0_, y1_);
  return o_ + x_ * xu + y_ * yc + z_ * z0_;
}

bool SphericalTriangle::Init(const Vec3& o, const Vec3& a, const Vec3& b, const Vec3& c) {
  const D3 od = ToD(o);
  const D3 A = NormD(Sub(ToD(a), od)), B = NormD(Sub(ToD(b), od)), C = NormD(Sub(ToD(c), od));
  if (LenD(A) == 0 || LenD(B) == 0 || LenD(C) == 0) return false;
  const double alpha = VertexAngle(A, B, C);
  const double beta = VertexAngle(B, C, A);
  const double gamma = VertexAngle(C, A, B);
  area_ = alpha + beta + gamma - kPiD;
  if (!(area_ > kMinSolidAngle) || !std::isfinite(area_)) return false;
  alpha_ = alpha;
  cos_c_ = DotD(A, B);
  Store(A, A_);
  Store(B, B_);
  Store(C, C_);
  return true;
}

Vec3 SphericalTriangle::Sample(float u, float v) const {
  const D3 A = Load(A_), B = Load(B_), C = Load(C_);
  const double area_hat = double(u) * area_;
  const double s = std::sin(area_hat - alpha_), t = std::cos(area_hat - alpha_);
  const double uu = t - std::cos(alpha_);
  const double vv = s + std::sin(alpha_) * cos_c_;
  const double den = (vv * s + uu * t) * std::sin(alpha_);
  double q = den != 0 ? ((vv * t - uu * s) * std::cos(alpha_) - vv) / den : 1;
  q = std::clamp(q, -1.0, 1.0);
  const D3 c_perp = NormD(Sub(C, Mul(A, DotD(C, A))));
  const D3 c_hat = Add(Mul(A, q), Mul(c_perp, std::sqrt(std::max(0.0, 1 - q * q))));
  const double z = 1 - double(v) * (1 - DotD(c_hat, B));
  const D3 b_perp = NormD(Sub(c_hat, Mul(B, DotD(c_hat, B))));
  const D3 p = NormD(Add(Mul(B, z), Mul(b_perp, std::sqrt(std::max(0.0, 1 - z * z)))));
  return Vec3(float(p.x), float(p.y), float(p.z));
}

double TriangleSolidAngle(const Vec3& o, const Vec3& a, const Vec3& b, const Vec3& c) {
  const D3 od = ToD(o);
  const D3 A = Sub(ToD(a), od), B = Sub(ToD(b), od), C = Sub(ToD(c), od);
  const double la = LenD(A), lb = LenD(B), lc = LenD(C);
  const double num = std::abs(DotD(A, CrossD(B, C)));
  const double den = la * lb * lc + DotD(A, B) * lc + DotD(A, C) * lb + DotD(B, C) * la;
  return 2 * std::atan2(num, den);
}

double PolygonProjectedSolidAngle(const Vec3& x, const Vec3& n, const Vec3* verts, int count) {
  // Clip to the half-space n . (p - x) >= 0 (Sutherland-Hodgman), in coordinates relative to x.
  const D3 nd = ToD(n), xd = ToD(x);
  D3 in[8], out[16];
  const int m = std::min(count, 8);
  for (int i = 0; i < m; ++i) in[i] = Sub(ToD(verts[i]), xd);
  int k = 0;
  for (int i = 0; i < m; ++i) {
    const D3& p = in[i];
    const D3& q = in[(i + 1) % m];
    const double dp = DotD(p, nd), dq = DotD(q, nd);
    if (dp >= 0) out[k++] = p;
    if ((dp >= 0) != (dq >= 0)) {
      const double t = dp / (dp - dq);
      out[k++] = Add(p, Mul(Sub(q, p), t));
    }
  }
  if (k < 3) return 0;
  // Lambert: (1/2) | sum_i theta_i (gamma_i . n) | with theta_i the angle between consecutive
  // vertex directions and gamma_i the unit normal of the plane through them and x.
  double sum = 0;
  for (int i = 0; i < k; ++i) {
    const D3 u = NormD(out[i]);
    const D3 v = NormD(out[(i + 1) % k]);
    const D3 c = CrossD(u, v);
    const double sin_t = LenD(c);
    if (sin_t <= 0) continue;
    // core/fast_trig.h's: within 3e-14 of libm's at half its cost (rectangle lamps call this for
    // every direct-light estimate).
    const double theta = Atan2(sin_t, DotD(u, v));
    sum += theta * DotD(c, nd) / sin_t;
  }
  return 0.5 * std::abs(sum);
}

}  // namespace irfarm
