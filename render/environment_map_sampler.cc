#include "render/environment_map_sampler.h"

#include <algorithm>
#include <cmath>

namespace irfarm {

void EnvironmentMapSampler::Build(const std::function<Vec3(const Vec3&)>& radiance,
                                  const Mat4& world_to_env, int nu, int nv) {
  *this = EnvironmentMapSampler();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      double dot = 0;  // row r . row c: 1 on the diagonal, 0 off it for a rotation
      for (int k = 0; k < 3; ++k) dot += world_to_env.m[r][k] * world_to_env.m[c][k];
      if (std::abs(dot - (r == c ? 1.0 : 0.0)) > 1e-4) return;
    }
  nu_ = std::max(1, nu);
  nv_ = std::max(1, nv);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) rot_[r][c] = float(world_to_env.m[r][c]);
  const size_t n = size_t(nu_) * nv_;
  cells_.assign(n, 0.0f);
  total_ = 0;
  for (int j = 0; j < nv_; ++j)
    for (int i = 0; i < nu_; ++i) {
      double sum = 0;
      for (int s = 0; s < 4; ++s) {
        const float u = (float(i) + 0.25f + 0.5f * float(s & 1)) / float(nu_);
        const float v = (float(j) + 0.25f + 0.5f * float(s >> 1)) / float(nv_);
        const double lum = double(std::max(0.0f, Luminance(radiance(FromUv(u, v)))));
        sum += std::isfinite(lum) ? lum * std::sin(double(v) * kPi) : 0.0;
      }
      cells_[size_t(j) * nu_ + size_t(i)] = float(sum / 4);
      total_ += sum / 4;
    }
  keep_.assign(n, 1.0f);
  alias_.resize(n);
  for (size_t k = 0; k < n; ++k) alias_[k] = uint32_t(k);
  pdf_scale_ = total_ > 0 ? float(double(n) / (total_ * 2 * kPi * kPi)) : 0.0f;
  if (!(total_ > 0)) return;
  // Vose's construction: each entry's scaled weight n p_k; entries below 1 are topped up from
  // one above 1, which becomes their alias.
  std::vector<double> scaled(n);
  std::vector<uint32_t> small, large;
  for (size_t k = 0; k < n; ++k) {
    scaled[k] = double(cells_[k]) * double(n) / total_;
    (scaled[k] < 1 ? small : large).push_back(uint32_t(k));
  }
  while (!small.empty() && !large.empty()) {
    const uint32_t a = small.back(), b = large.back();
    small.pop_back();
    keep_[a] = float(scaled[a]);
    alias_[a] = b;
    scaled[b] -= 1 - scaled[a];
    if (scaled[b] < 1) {
      large.pop_back();
      small.push_back(b);
    }
  }
  // What is left is 1 up to rounding.
  for (uint32_t k : small) keep_[k] = 1.0f;
  for (uint32_t k : large) keep_[k] = 1.0f;
}

float EnvironmentMapSampler::CellPdf(int i, int j, float sin_theta) const {
  // Density on the unit square, then per solid angle: d omega = 2 pi^2 sin(theta) du dv.
  return sin_theta > 0 ? cells_[size_t(j) * nu_ + size_t(i)] * pdf_scale_ / sin_theta : 0.0f;
}

bool EnvironmentMapSampler::Sample(float u1, float u2, Vec3* wi, float* pdf) const {
  if (empty()) return false;
  // u1 picks an entry of the table and, with what is left of it, the entry or its alias and the
  // point's u within the cell; u2 gives its v.
  const size_t n = cells_.size();
  const double x = double(u1) * double(n);
  const size_t k = std::min(n - 1, size_t(x));
  const float frac = float(x - double(k));
  const float keep = keep_[k];
  size_t cell = k;
  float fu = keep > 0 ? frac / keep : 0.5f;
  if (frac >= keep) {
    cell = alias_[k];
    fu = (frac - keep) / (1 - keep);
  }
  fu = std::clamp(fu, 0.0f, 0x1.fffffep-1f);
  const int i = int(cell % size_t(nu_)), j = int(cell / size_t(nu_));
  const float v = (float(j) + u2) / float(nv_);
  *wi = FromUv((float(i) + fu) / float(nu_), v);
  *pdf = CellPdf(i, j, std::sin(v * kPi));
  return *pdf > 0;
}

float EnvironmentMapSampler::Pdf(const Vec3& wi) const {
  if (empty()) return 0;
  const Vec3 e(rot_[0][0] * wi.x + rot_[0][1] * wi.y + rot_[0][2] * wi.z,
               rot_[1][0] * wi.x + rot_[1][1] * wi.y + rot_[1][2] * wi.z,
               rot_[2][0] * wi.x + rot_[2][1] * wi.y + rot_[2][2] * wi.z);
  float u, v;
  EnvmapUv(e, &u, &v);
  const float y = std::clamp(e.y, -1.0f, 1.0f);
  const int i = std::clamp(int(u * float(nu_)), 0, nu_ - 1);
  const int j = std::clamp(int(v * float(nv_)), 0, nv_ - 1);
  return CellPdf(i, j, std::sqrt(std::max(0.0f, 1 - y * y)));
}

Vec3 EnvironmentMapSampler::FromUv(float u, float v) const {
  const Vec3 e = EnvmapDirection(u, v);
  return Normalize(Vec3(rot_[0][0] * e.x + rot_[1][0] * e.y + rot_[2][0] * e.z,
                        rot_[0][1] * e.x + rot_[1][1] * e.y + rot_[2][1] * e.z,
                        rot_[0][2] * e.x + rot_[1][2] * e.y + rot_[2][2] * e.z));
}

}  // namespace irfarm
