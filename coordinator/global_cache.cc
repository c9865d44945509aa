// GlobalCache: validate, merge, remember (see global_cache.h).
#include "coordinator/global_cache.h"

#include <algorithm>
#include <cmath>

namespace irfarm {

GlobalCache::GlobalCache(const CacheSettings& settings, const RecordBounds& bounds)
    : bounds_(bounds),
      max_accuracy_(IrradianceCache::ClampedMaxAccuracy(settings.max_accuracy)),
      cells_(size_t(kGrid) * kGrid * kGrid + 1),
      cell_max_radius_(size_t(kGrid) * kGrid * kGrid, 0.0f) {}

int GlobalCache::CellOf(const Vec3& p) const {
  int c[3];
  for (int k = 0; k < 3; ++k) {
    const float lo = bounds_.box.lo[k], extent = bounds_.box.hi[k] - lo;
    const float t = extent > 0 ? (p[k] - lo) / extent * float(kGrid) : 0.0f;
    c[k] = std::clamp(int(std::floor(t)), 0, kGrid - 1);  // t is finite: records are validated
  }
  return (c[2] * kGrid + c[1]) * kGrid + c[0];
}

Bounds3 GlobalCache::CellBox(int cell) const {
  const int c[3] = {cell % kGrid, (cell / kGrid) % kGrid, cell / (kGrid * kGrid)};
  Bounds3 b;
  for (int k = 0; k < 3; ++k) {
    const double lo = bounds_.box.lo[k], extent = double(bounds_.box.hi[k]) - lo;
    const double slack = 1e-3 * extent / kGrid + 1e-6 * std::abs(lo);
    // Outer cells reach past the bounds: CellOf clamps positions there into them.
    b.lo[k] = float(c[k] == 0 ? -INFINITY : lo + extent * c[k] / kGrid - slack);
    b.hi[k] = float(c[k] == kGrid - 1 ? INFINITY : lo + extent * (c[k] + 1) / kGrid + slack);
  }
  return b;
}

GlobalCache::Near GlobalCache::RecordsNear(const Bounds3& box) const {
  Near near;
  near.records_ = records_.Snapshot();
  if (!cells_.back().empty()) near.cells_.push_back(cells_.back().Snapshot());  // level > 0
  if (box.Empty()) return near;
  for (int cell = 0; cell < kGrid * kGrid * kGrid; ++cell) {
    if (cells_[size_t(cell)].empty()) continue;
    // The cell's records reach at most max_accuracy * (their largest R) from the cell's box.
    const Bounds3 c = CellBox(cell);
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double d =
          std::max({double(box.lo[k]) - double(c.hi[k]), 0.0, double(c.lo[k]) - double(box.hi[k])});
      d2 += d * d;
    }
    const double reach = double(max_accuracy_) * double(cell_max_radius_[size_t(cell)]);
    if (d2 <= reach * reach * (1 + 1e-5)) near.cells_.push_back(cells_[size_t(cell)].Snapshot());
  }
  return near;
}

std::vector<IrradianceRecord> GlobalCache::Check(const std::vector<IrradianceRecord>& records,
                                                 const char** problem) {
  std::vector<IrradianceRecord> accepted;
  if (closed_) {  // the job is over
    rejected_ += records.size();
    if (problem && !records.empty()) *problem = "the job is finished";
    return accepted;
  }
  accepted.reserve(records.size());
  for (const IrradianceRecord& r : records) {
    if (const char* why = RecordProblem(bounds_, r)) {
      if (problem && !*problem) *problem = why;
      ++rejected_;
      continue;
    }
    accepted.push_back(r);
  }
  return accepted;
}

void GlobalCache::Insert(const std::vector<IrradianceRecord>& valid) {
  // Also after Close: these were checked (and stored) while the job ran.
  for (const IrradianceRecord& r : valid) {
    const Entry entry{r.position, r.radius, uint64_t(records_.size()), r.origin, r.level};
    records_.Append(r);
    if (r.level > 0) {
      cells_.back().Append(entry);
    } else {
      const int cell = CellOf(r.position);
      cells_[size_t(cell)].Append(entry);
      float& m = cell_max_radius_[size_t(cell)];
      m = std::max(m, r.radius);
    }
  }
}

std::vector<IrradianceRecord> GlobalCache::Merge(const std::vector<IrradianceRecord>& records,
                                                 const char** problem) {
  std::vector<IrradianceRecord> accepted = Check(records, problem);
  Insert(accepted);
  return accepted;
}

}  // namespace irfarm
