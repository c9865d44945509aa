// atan2 for the analytic lights' inner loop: libm's was 5% of a lamp-lit room's CPU (perf on
// room-a at defaults, __ieee754_atan2; two thirds of it PolygonProjectedSolidAngle's).
// Double, for y, x of any sign (atan2(0, 0) = 0 as libm's), reduced to |z| <= tan(pi/8) by the
// octant and atan(z) = atan((z-1)/(z+1)) + pi/4, then z P(z^2) with P of degree 8 in z^2, fitted
// to atan by least squares on 4000 Chebyshev nodes in double (numpy; 1.0e-14 from atan on a fine
// grid). tests/core/fast_trig_test.cc: at most 3e-14 from libm's over every octant, signed zeros
// and the axes. bench_micro's BM_Atan2, one run: 5.5 ns against libm's 11.2 ns per call.
// A polynomial sin/cos pair (Taylor to r^9 and r^10 after reduction to a quarter turn, branch-free
// quadrant), timed the same way over 1024 turn fractions, was no faster than glibc's sincosf (4.3
// against 4.2 ns per pair) and was not kept.
#pragma once

#include <cmath>

namespace irfarm {

// atan(z) for |z| <= tan(pi/8).
inline double AtanSmall(double z) {
  const double s = z * z;
  const double p =
      0.99999999999997469 +
      s * (-0.33333333330872278 +
           s * (0.19999999613254754 +
                s * (-0.14285690811416976 +
                     s * (0.11110393878383934 +
                          s * (-0.090785014654163027 +
                               s * (0.075644546100470458 +
                                    s * (-0.058771919988228345 + s * 0.03070149028735282)))))));
  return z * p;
}

// atan2(y, x) in (-pi, pi].
inline double Atan2(double y, double x) {
  constexpr double kPi = 3.14159265358979323846, kPi2 = kPi / 2, kPi4 = kPi / 4;
  constexpr double kTan8 = 0.41421356237309504880;  // tan(pi/8)
  const double ay = std::abs(y), ax = std::abs(x);
  if (ax == 0 && ay == 0) return std::signbit(x) ? std::copysign(kPi, y) : std::copysign(0.0, y);
  // The angle of (ax, ay) in [0, pi/2]: z = min / max in [0, 1], then by its eighth.
  const bool steep = ay > ax;
  const double z = steep ? ax / ay : ay / ax;
  double a = z > kTan8 ? kPi4 + AtanSmall((z - 1) / (z + 1)) : AtanSmall(z);
  if (steep) a = kPi2 - a;
  if (std::signbit(x)) a = kPi - a;
  return std::copysign(a, y);
}

// atan2(y, x) for y > 0, in (0, pi), without a branch: the same reduction as Atan2 made of
// selects, so that a loop calling it runs as vector lanes (the Hessian's edge terms,
// render/irradiance_hessian.cc). Also within 3e-14 of libm's (tests/core/fast_trig_test.cc).
inline double Atan2Positive(double y, double x) {
  constexpr double kPi = 3.14159265358979323846, kPi2 = kPi / 2, kPi4 = kPi / 4;
  constexpr double kTan8 = 0.41421356237309504880;  // tan(pi/8)
  const double ax = std::abs(x);
  const bool steep = y > ax;
  // Both divisions are made in every lane (a division under a condition keeps a loop scalar).
  const double z = (steep ? ax : y) / (steep ? y : ax);
  const bool high = z > kTan8;
  const double zr = high ? (z - 1) / (z + 1) : z;
  double a = (high ? kPi4 : 0.0) + AtanSmall(zr);
  a = steep ? kPi2 - a : a;
  return x < 0 ? kPi - a : a;
}

}  // namespace irfarm
