#include "render/environment_sun.h"

#include <algorithm>
#include <cmath>

#include "render/light.h"

namespace irfarm {
namespace {

constexpr int kU = EnvironmentSun::kCellsU, kV = EnvironmentSun::kCellsV;

// Solid angle of row j's cells.
double CellSolidAngle(int j) {
  const double theta0 = kPi * double(j) / kV, theta1 = kPi * double(j + 1) / kV;
  return (2 * kPi / kU) * (std::cos(theta0) - std::cos(theta1));
}

// Solid angle of row j's sub-cells (EnvironmentSun::kSubCells per cell each way).
double SubCellSolidAngle(int j) {
  constexpr int kSub = EnvironmentSun::kSubCells;
  const double theta0 = kPi * double(j) / (kV * kSub), theta1 = kPi * double(j + 1) / (kV * kSub);
  return (2 * kPi / (kU * kSub)) * (std::cos(theta0) - std::cos(theta1));
}

}  // namespace

EnvironmentSun EnvironmentSun::Find(const std::function<Vec3(const Vec3&)>& radiance,
                                    bool has_envmap) {
  EnvironmentSun sun;
  if (!has_envmap) return sun;
  std::vector<float> lum(size_t(kU) * kV);
  double total = 0;
  for (int j = 0; j < kV; ++j) {
    const double omega = CellSolidAngle(j);
    for (int i = 0; i < kU; ++i) {
      const Vec3 d = EnvmapDirection((float(i) + 0.5f) / kU, (float(j) + 0.5f) / kV);
      const float y = Luminance(radiance(d));
      lum[size_t(j) * kU + size_t(i)] = std::isfinite(y) ? std::max(y, 0.0f) : 0.0f;
      total += double(lum[size_t(j) * kU + size_t(i)]) * omega;
    }
  }
  const double threshold = kSunRatio * total / (4 * kPi);
  if (!(threshold > 0)) return sun;
  // The core cells, their luminance-weighted mean direction, and the region grown by one cell.
  std::vector<uint8_t> marked(lum.size(), 0);
  Vec3 axis;
  bool any = false;
  for (int j = 0; j < kV; ++j)
    for (int i = 0; i < kU; ++i) {
      const float y = lum[size_t(j) * kU + size_t(i)];
      if (y < threshold) continue;
      any = true;
      const Vec3 d = EnvmapDirection((float(i) + 0.5f) / kU, (float(j) + 0.5f) / kV);
      axis += d * float(double(y) * CellSolidAngle(j));
      for (int dj = -1; dj <= 1; ++dj) {
        const int jj = j + dj;
        if (jj < 0 || jj >= kV) continue;
        for (int di = -1; di <= 1; ++di) marked[size_t(jj) * kU + size_t((i + di + kU) % kU)] = 1;
      }
    }
  if (!any || !(LengthSquared(axis) > 0)) return sun;
  axis = Normalize(axis);
  // The largest angle of a marked cell's corner from the axis; the sub-cells' weights: each
  // marked cell is kSub x kSub sub-cells, weighed by the luminance at their centres times their
  // solid angle (a floor keeps every one sampleable).
  constexpr int kSub = EnvironmentSun::kSubCells;
  const double floor = 1e-3 * total / (4 * kPi);
  float min_cos = 1;
  std::vector<uint32_t> cells;
  std::vector<float> cdf;
  double acc = 0, irradiance = 0;
  for (int j = 0; j < kV; ++j)
    for (int i = 0; i < kU; ++i) {
      if (!marked[size_t(j) * kU + size_t(i)]) continue;
      for (int c = 0; c < 4; ++c) {
        const Vec3 d = EnvmapDirection(float(i + (c & 1)) / kU, float(j + (c >> 1)) / kV);
        min_cos = std::min(min_cos, Dot(d, axis));
      }
      for (int b = 0; b < kSub; ++b) {
        const double omega = SubCellSolidAngle(j * kSub + b);
        for (int a = 0; a < kSub; ++a) {
          const Vec3 d = EnvmapDirection((float(i) + (float(a) + 0.5f) / kSub) / kU,
                                         (float(j) + (float(b) + 0.5f) / kSub) / kV);
          const float y = Luminance(radiance(d));
          const double lum_sub = std::isfinite(y) ? std::max(double(y), 0.0) : 0.0;
          acc += std::max(lum_sub, floor) * omega;
          irradiance += lum_sub * omega * std::max(0.0f, Dot(d, axis));
          cells.push_back(uint32_t(j * kSub + b) * (kU * kSub) + uint32_t(i * kSub + a));
          cdf.push_back(float(acc));
        }
      }
    }
  const float radius = std::acos(std::clamp(min_cos, -1.0f, 1.0f));
  if (!(radius <= kSunMaxRadius) || !(acc > 0)) return sun;
  sun.marked_ = std::move(marked);
  sun.cells_ = std::move(cells);
  sun.cdf_ = std::move(cdf);
  sun.guide_.Build(sun.cdf_, sun.cdf_.size());
  sun.axis_ = axis;
  sun.radius_ = radius;
  sun.cos_radius_ = std::cos(radius) - 1e-4f;  // a margin for rounding
  sun.irradiance_ = float(irradiance);
  return sun;
}

bool EnvironmentSun::Contains(const Vec3& d) const {
  // Every marked cell lies within radius_ of the axis: most directions are rejected here, before
  // the grid's atan2 and acos.
  if (marked_.empty() || Dot(d, axis_) < cos_radius_) return false;
  float u, v;
  EnvmapUv(d, &u, &v);
  const int i = std::clamp(int(u * kU), 0, kU - 1), j = std::clamp(int(v * kV), 0, kV - 1);
  return marked_[size_t(j) * kU + size_t(i)] != 0;
}

void EnvironmentSun::Sample(float u1, float u2, float u3, Vec3* d, float* pdf) const {
  const float total = cdf_.back();
  const size_t k = std::min(guide_.UpperBound(cdf_, u1, u1 * total), cells_.size() - 1);
  const float weight = cdf_[k] - (k > 0 ? cdf_[k - 1] : 0.0f);
  constexpr int kFineU = kU * kSubCells, kFineV = kV * kSubCells;
  const int i = int(cells_[k] % kFineU), j = int(cells_[k] / kFineU);
  const float u = (float(i) + u2) / kFineU, v = (float(j) + u3) / kFineV;
  *d = EnvmapDirection(u, v);
  // Uniform in (u, v) over the sub-cell: solid-angle density 1 / (du dv 2 pi^2 sin(theta)).
  const float sin_theta = std::max(std::sin(v * kPi), 1e-6f);
  *pdf = (weight / total) * float(kFineU) * float(kFineV) / (2 * kPi * kPi * sin_theta);
}

}  // namespace irfarm
