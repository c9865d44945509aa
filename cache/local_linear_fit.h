// Irradiance at a lookup point from the records that count there, as the value at that point of
// the plane fitted to them by weighted least squares (Ward's weights), instead of their weighted
// mean (local linear regression; the weighted mean is its constant-only case).
//
// Why: records lie where earlier lookups found none, so around a point they are rarely balanced.
// The weighted mean then carries a first-order bias, g . (m - x) for an irradiance gradient g and
// the records' weighted centre m: along a crease or an edge every record lies on one side, and
// the surface there gets the irradiance of a point a little way off. The fitted plane takes that
// term off (what is left is second order) without a gradient per record (Ward and Heckbert's,
// from the record's own noisy strata, made cornell-box worse when it was tried); the slope comes
// from the records' values, each the mean of hundreds of rays.
//
// Coordinates: the records' offsets from the lookup point in a tangent frame of its normal (u, v).
// The fit is refused (the weighted mean stands) when the records do not span the plane (fewer than
// three, or nearly on one line: the smaller eigenvalue of their weighted covariance below
// kMinSpread of the larger) or leave no residual to judge the slope by (Kish's effective number
// of records n_eff = (sum w)^2 / sum w^2 at most 3). Its value is kept within a factor kMaxChange
// of the weighted mean, per channel, so that a badly conditioned fit cannot make a pixel black or
// a blotch.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/math.h"

namespace irfarm {

class LocalLinearFit {
 public:
  // Smallest ratio of the weighted covariance's eigenvalues (min / max) for a fit.
  static constexpr double kMinSpread = 1e-3;
  // The fit's value stays within [mean / kMaxChange, mean * kMaxChange].
  static constexpr double kMaxChange = 2.0;

  // A record with weight w > 0 at offset (du, dv) from the lookup point, irradiance e.
  void Add(double w, double du, double dv, const Vec3& e) {
    ++count_;
    w_ += w;
    ww_ += w * w;
    su_ += w * du;
    sv_ += w * dv;
    suu_ += w * du * du;
    suv_ += w * du * dv;
    svv_ += w * dv * dv;
    for (int k = 0; k < 3; ++k) {
      const double we = w * double(e[k]);
      se_[k] += we;
      see_[k] += we * double(e[k]);
      seu_[k] += we * du;
      sev_[k] += we * dv;
    }
  }
  int count() const { return count_; }

  // The fitted plane's value at the lookup point (u = v = 0); false (out untouched) where the fit
  // is refused (see above).
  bool ValueAtOrigin(Vec3* out) const {
    if (count_ < 3 || !(w_ > 0)) return false;
    const double iw = 1 / w_;
    const double mu = su_ * iw, mv = sv_ * iw;
    const double cuu = suu_ * iw - mu * mu, cuv = suv_ * iw - mu * mv, cvv = svv_ * iw - mv * mv;
    const double det = cuu * cvv - cuv * cuv, tr = cuu + cvv;
    // With eigenvalues l1 <= l2: det / tr^2 = r / (1 + r)^2 for r = l1 / l2, increasing in r.
    constexpr double kMinDet = kMinSpread / ((1 + kMinSpread) * (1 + kMinSpread));
    if (!(tr > 0) || !(det > kMinDet * tr * tr)) return false;
    // Kish's effective number of records: the plane takes 3 of them, the residuals the rest.
    const double n_eff = w_ * w_ / ww_;
    if (!(n_eff > 3)) return false;
    const double idet = 1 / det;
    // m^T C^-1 m for the records' centre m, the variance of the correction per unit residual.
    const double mcm = (cvv * mu * mu - 2 * cuv * mu * mv + cuu * mv * mv) * idet;
    const double var_scale = mcm / (n_eff - 3);
    Vec3 v;
    for (int k = 0; k < 3; ++k) {
      const double me = se_[k] * iw;
      const double ceu = seu_[k] * iw - me * mu, cev = sev_[k] * iw - me * mv;
      const double gu = (cvv * ceu - cuv * cev) * idet, gv = (cuu * cev - cuv * ceu) * idet;
      // The correction to the mean, and its variance from the fit's residuals (the records'
      // noise and whatever the plane does not explain): Var(g) = s^2 / (n_eff - 3) C^-1.
      const double delta = gu * mu + gv * mv;
      const double spread = see_[k] * iw - me * me;
      const double residual = std::max(0.0, spread - (gu * ceu + gv * cev));
      const double d2 = delta * delta, var = residual * var_scale;
      // Shrunk by delta^2 / (delta^2 + var): whole where the slope stands out of the records'
      // scatter, nothing where it is their noise.
      const double c = d2 > 0 ? me - d2 / (d2 + var) * delta : me;
      v[k] = float(me > 0 ? std::clamp(c, me / kMaxChange, me * kMaxChange) : me);
    }
    if (!IsFinite(v)) return false;
    *out = v;
    return true;
  }

 private:
  int count_ = 0;
  double w_ = 0, ww_ = 0, su_ = 0, sv_ = 0, suu_ = 0, suv_ = 0, svv_ = 0;
  double se_[3] = {0, 0, 0}, see_[3] = {0, 0, 0}, seu_[3] = {0, 0, 0}, sev_[3] = {0, 0, 0};
};

}  // namespace irfarm
