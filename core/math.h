// Small vector and transform types used by the scene description, the renderer and the cache.
// Points, vectors and normals are all Vec3 (float); transforms are 4x4 row-major matrices that
// act on column vectors (p' = M p), as in Mitsuba's XML.
#pragma once

#include <algorithm>
#include <cmath>

namespace irfarm {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 0.31830988618379067154f;
constexpr float kSqrtPi = 1.77245385090551602730f;

struct Vec3 {
  float x = 0, y = 0, z = 0;
  constexpr Vec3() = default;
  constexpr Vec3(float a, float b, float c) : x(a), y(b), z(c) {}
  constexpr explicit Vec3(float a) : x(a), y(a), z(a) {}
  float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
  Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
  Vec3 operator*(const Vec3& o) const { return {x * o.x, y * o.y, z * o.z}; }
  Vec3 operator/(const Vec3& o) const { return {x / o.x, y / o.y, z / o.z}; }
  Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
  Vec3 operator/(float s) const { return {x / s, y / s, z / s}; }
  Vec3 operator-() const { return {-x, -y, -z}; }
  Vec3& operator+=(const Vec3& o) {
    x += o.x;
    y += o.y;
    z += o.z;
    return *this;
  }
  Vec3& operator-=(const Vec3& o) {
    x -= o.x;
    y -= o.y;
    z -= o.z;
    return *this;
  }
  Vec3& operator*=(const Vec3& o) {
    x *= o.x;
    y *= o.y;
    z *= o.z;
    return *this;
  }
  Vec3& operator*=(float s) {
    x *= s;
    y *= s;
    z *= s;
    return *this;
  }
  Vec3& operator/=(float s) {
    x /= s;
    y /= s;
    z /= s;
    return *this;
  }
};

inline Vec3 operator*(float s, const Vec3& v) { return v * s; }
inline float Dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 Cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float LengthSquared(const Vec3& v) { return Dot(v, v); }
inline float Length(const Vec3& v) { return std::sqrt(Dot(v, v)); }
inline Vec3 Normalize(const Vec3& v) { return v / Length(v); }
inline Vec3 Min(const Vec3& a, const Vec3& b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
inline Vec3 Max(const Vec3& a, const Vec3& b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
inline float MaxComponent(const Vec3& v) { return std::max(v.x, std::max(v.y, v.z)); }
inline float MaxAbsComponent(const Vec3& v) {
  return std::max(std::abs(v.x), std::max(std::abs(v.y), std::abs(v.z)));
}
inline bool IsFinite(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
inline bool IsBlack(const Vec3& v) { return v.x == 0 && v.y == 0 && v.z == 0; }
inline float Luminance(const Vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

// Builds an orthonormal basis (s, t, n) around unit vector n (Duff et al. 2017, branchless).
inline void MakeFrame(const Vec3& n, Vec3* s, Vec3* t) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float b = n.x * n.y * a;
  *s = Vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
  *t = Vec3(b, sign + n.y * n.y * a, -n.y);
}

struct Bounds3 {
  Vec3 lo{INFINITY, INFINITY, INFINITY};
  Vec3 hi{-INFINITY, -INFINITY, -INFINITY};
  void Extend(const Vec3& p) {
    lo = Min(lo, p);
    hi = Max(hi, p);
  }
  void Extend(const Bounds3& b) {
    lo = Min(lo, b.lo);
    hi = Max(hi, b.hi);
  }
  bool Empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  Vec3 Diagonal() const { return hi - lo; }
  Vec3 Center() const { return (lo + hi) * 0.5f; }
};

// 4x4 matrix, row-major, acting on column vectors. Stored in double so that chains of
// transforms (and their inverses) keep precision for scenes far from the unit scale.
struct Mat4 {
  double m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};

  static Mat4 Identity() { return Mat4(); }
  static Mat4 Translate(double x, double y, double z) {
    Mat4 r;
    r.m[0][3] = x;
    r.m[1][3] = y;
    r.m[2][3] = z;
    return r;
  }
  static Mat4 Scale(double x, double y, double z) {
    Mat4 r;
    r.m[0][0] = x;
    r.m[1][1] = y;
    r.m[2][2] = z;
    return r;
  }
  // Right-handed rotation by angle_deg degrees about axis (x, y, z) (need not be unit).
  static Mat4 Rotate(double x, double y, double z, double angle_deg) {
    // Scaled by the largest component first: the squares of an axis like (1e-200, 0, 0) or
    // (1e200, 0, 0) would underflow to 0 or overflow to inf (a NaN or a shrinking matrix).
    const double big = std::max({std::abs(x), std::abs(y), std::abs(z)});
    if (big > 0 && std::isfinite(big)) {
      x /= big;
      y /= big;
      z /= big;
    }
    const double len = std::sqrt(x * x + y * y + z * z);
    x /= len;
    y /= len;
    z /= len;
    const double a = angle_deg * 3.14159265358979323846 / 180.0;
    const double c = std::cos(a), s = std::sin(a), t = 1 - c;
    Mat4 r;
    r.m[0][0] = t * x * x + c;
    r.m[0][1] = t * x * y - s * z;
    r.m[0][2] = t * x * z + s * y;
    r.m[1][0] = t * x * y + s * z;
    r.m[1][1] = t * y * y + c;
    r.m[1][2] = t * y * z - s * x;
    r.m[2][0] = t * x * z - s * y;
    r.m[2][1] = t * y * z + s * x;
    r.m[2][2] = t * z * z + c;
    return r;
  }
  // Mitsuba's lookat: camera space looks along +z, +y up, +x to the image's left.
  static Mat4 LookAt(const Vec3& origin, const Vec3& target, const Vec3& up) {
    const Vec3 f = Normalize(target - origin);
    const Vec3 left = Normalize(Cross(Normalize(up), f));
    const Vec3 u = Cross(f, left);
    Mat4 r;
    for (int i = 0; i < 3; ++i) {
      r.m[i][0] = left[i];
      r.m[i][1] = u[i];
      r.m[i][2] = f[i];
      r.m[i][3] = origin[i];
    }
    return r;
  }
  Mat4 operator*(const Mat4& o) const {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        double s = 0;
        for (int k = 0; k < 4; ++k) s += m[i][k] * o.m[k][j];
        r.m[i][j] = s;
      }
    return r;
  }
  Vec3 ApplyPoint(const Vec3& p) const {
    double r[4];
    for (int i = 0; i < 4; ++i) r[i] = m[i][0] * p.x + m[i][1] * p.y + m[i][2] * p.z + m[i][3];
    return Vec3(float(r[0] / r[3]), float(r[1] / r[3]), float(r[2] / r[3]));
  }
  Vec3 ApplyVector(const Vec3& v) const {
    return Vec3(float(m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z),
                float(m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z),
                float(m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z));
  }
  // Normals transform with the inverse transpose of the upper 3x3 (NormalMatrix, which also
  // handles a 3x3 that flattens along the normal); the result is normalized.
  Vec3 ApplyNormal(const Vec3& n) const;
  Mat4 Inverse() const;  // General 4x4 inverse (Gauss-Jordan); identity-scaled if singular.
  double Determinant3() const {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  }
};

inline Mat4 Mat4::Inverse() const {
  double a[4][8];
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      a[i][j] = m[i][j];
      a[i][j + 4] = (i == j) ? 1 : 0;
    }
  for (int c = 0; c < 4; ++c) {
    int p = c;
    for (int r = c + 1; r < 4; ++r)
      if (std::abs(a[r][c]) > std::abs(a[p][c])) p = r;
    if (a[p][c] == 0) return Mat4();
    for (int j = 0; j < 8; ++j) std::swap(a[c][j], a[p][j]);
    const double inv = 1.0 / a[c][c];
    for (int j = 0; j < 8; ++j) a[c][j] *= inv;
    for (int r = 0; r < 4; ++r)
      if (r != c) {
        const double f = a[r][c];
        for (int j = 0; j < 8; ++j) a[r][j] -= f * a[c][j];
      }
  }
  Mat4 r;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) r.m[i][j] = a[i][j + 4];
  return r;
}

// The normal matrix of the upper 3 x 3 part A as cofactors: cof(A) = det(A) A^-T, times the sign
// of det(A), so that it maps normals as A^-T does (the same direction) where A is invertible, and
// still maps the normal of a surface that A keeps flat where A is singular (a scale of 0 along
// the normal of a rectangle: A^-T does not exist, and Inverse() answers the identity).
// out[i][j] multiplies n[j].
inline void NormalMatrix(const Mat4& m, double out[3][3]) {
  const auto a = [&](int i, int j) { return m.m[i % 3][j % 3]; };
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      out[i][j] = a(i + 1, j + 1) * a(i + 2, j + 2) - a(i + 1, j + 2) * a(i + 2, j + 1);
  const double det = m.Determinant3();
  if (det < 0)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) out[i][j] = -out[i][j];
}

// A normal through NormalMatrix's `c`, normalised.
inline Vec3 ApplyNormalMatrix(const double c[3][3], const Vec3& n) {
  return Normalize(Vec3(float(c[0][0] * n.x + c[0][1] * n.y + c[0][2] * n.z),
                        float(c[1][0] * n.x + c[1][1] * n.y + c[1][2] * n.z),
                        float(c[2][0] * n.x + c[2][1] * n.y + c[2][2] * n.z)));
}

inline Vec3 Mat4::ApplyNormal(const Vec3& n) const {
  double c[3][3];
  NormalMatrix(*this, c);
  return ApplyNormalMatrix(c, n);
}

}  // namespace irfarm
