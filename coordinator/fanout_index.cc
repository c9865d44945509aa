// Grid index of the workers' regions for the filtered fan-out (see fanout_index.h).
#include "coordinator/fanout_index.h"

#include <algorithm>
#include <cmath>

#include "coordinator/fanout_region.h"

namespace irfarm {

int FanoutIndex::Cell(double v, int k) const {
  const double c = std::floor((v - double(lo_[k])) * inv_cell_[k]);
  if (!(c >= 0)) return 0;  // also NaN
  return c >= n_[k] ? n_[k] - 1 : int(c);
}

void FanoutIndex::Build(const Bounds3& scene, std::vector<Entry> entries) {
  entries_ = std::move(entries);
  seen_.assign(entries_.size(), 0);
  query_ = 0;
  always_.clear();
  items_.clear();
  size_t boxes = 0;
  for (const Entry& e : entries_) boxes += !e.box.Empty();
  // Cubic cells, about kCellsPerBox per box, at most kMaxCells: the side s solves
  // prod(ceil(extent_k / s)) ~ target; flat scenes (an extent near 0) get one cell on that axis.
  lo_ = scene.lo;
  double ext[3];
  double diag = 0;
  for (int k = 0; k < 3; ++k) {
    ext[k] = std::max(0.0, double(scene.hi[k]) - double(scene.lo[k]));
    diag = std::max(diag, ext[k]);
  }
  const double target = double(std::clamp<size_t>(boxes * kCellsPerBox, 1, kMaxCells));
  double volume = 1;
  int dims = 0;
  for (int k = 0; k < 3; ++k)
    if (ext[k] > 1e-6 * diag) {
      volume *= ext[k];
      ++dims;
    }
  double side = dims > 0 ? std::pow(volume / target, 1.0 / dims) : 1.0;
  for (;;) {
    double cells = 1;
    for (int k = 0; k < 3; ++k) {
      n_[k] = ext[k] > 1e-6 * diag && side > 0
                  ? int(std::clamp(std::ceil(ext[k] / side), 1.0, double(kMaxCells)))
                  : 1;
      cells *= n_[k];
    }
    if (cells <= kMaxCells) break;
    side *= 1.25;  // rounding up made too many: coarser
  }
  for (int k = 0; k < 3; ++k) inv_cell_[k] = ext[k] > 0 ? n_[k] / ext[k] : 0;
  const size_t cells = size_t(n_[0]) * n_[1] * n_[2];
  // Counting sort of (cell, slot) pairs into the CSR arrays: count, prefix-sum, fill.
  cell_start_.assign(cells + 1, 0);
  std::vector<int> range(6 * entries_.size());
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t s = 0; s < entries_.size(); ++s) {
      const Bounds3& b = entries_[s].box;
      if (b.Empty()) continue;
      int* r = &range[6 * s];
      if (pass == 0) {
        for (int k = 0; k < 3; ++k) {
          r[k] = Cell(b.lo[k], k);
          r[3 + k] = Cell(b.hi[k], k);
        }
        if (size_t(r[3] - r[0] + 1) * (r[4] - r[1] + 1) * (r[5] - r[2] + 1) > kMaxCellsPerBox) {
          always_.push_back(uint32_t(s));
          r[0] = -1;  // not in the grid
          continue;
        }
      }
      if (r[0] < 0) continue;
      for (int z = r[2]; z <= r[5]; ++z)
        for (int y = r[1]; y <= r[4]; ++y)
          for (int x = r[0]; x <= r[3]; ++x) {
            const size_t c = (size_t(z) * n_[1] + y) * n_[0] + x;
            if (pass == 0)
              ++cell_start_[c + 1];
            else
              items_[cell_start_[c]++] = uint32_t(s);
          }
    }
    if (pass == 0) {
      for (size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
      items_.resize(cell_start_[cells]);
    } else {
      // The fill advanced each start to the next cell's start: shift back by one cell.
      for (size_t c = cells; c > 0; --c) cell_start_[c] = cell_start_[c - 1];
      cell_start_[0] = 0;
    }
  }
}

void FanoutIndex::QueryAll(const IrradianceRecord& r, float max_accuracy,
                           std::vector<uint32_t>* out) const {
  out->clear();
  for (size_t s = 0; s < entries_.size(); ++s)
    if (RecordReachesBox(r, entries_[s].box, max_accuracy)) out->push_back(uint32_t(s));
}

void FanoutIndex::Query(const IrradianceRecord& r, float max_accuracy, std::vector<uint32_t>* out) {
  out->clear();
  if (r.level > 0) {
    for (size_t s = 0; s < entries_.size(); ++s) out->push_back(uint32_t(s));
    return;
  }
  // The reach's cube, a little wider than RecordReachesBox's sphere (its 1e-6 relative slack,
  // and rounding here): candidates only; the exact test decides.
  const double reach = double(max_accuracy) * double(r.radius) * (1 + 1e-5);
  int lo[3], hi[3];
  size_t span = 1;
  for (int k = 0; k < 3; ++k) {
    lo[k] = Cell(double(r.position[k]) - reach, k);
    hi[k] = Cell(double(r.position[k]) + reach, k);
    span *= size_t(hi[k] - lo[k] + 1);
  }
  if (span > entries_.size()) {  // a huge reach: the brute force is cheaper
    QueryAll(r, max_accuracy, out);
    return;
  }
  ++grid_queries_;
  if (++query_ == 0) {  // wrapped: forget every mark
    std::fill(seen_.begin(), seen_.end(), 0);
    query_ = 1;
  }
  const auto consider = [&](uint32_t s) {
    if (seen_[s] == query_) return;
    seen_[s] = query_;
    if (RecordReachesBox(r, entries_[s].box, max_accuracy)) out->push_back(s);
  };
  for (uint32_t s : always_) consider(s);
  for (int z = lo[2]; z <= hi[2]; ++z)
    for (int y = lo[1]; y <= hi[1]; ++y) {
      const size_t row = (size_t(z) * n_[1] + y) * n_[0];
      for (uint32_t i = cell_start_[row + lo[0]]; i < cell_start_[row + hi[0] + 1]; ++i)
        consider(items_[i]);
    }
}

}  // namespace irfarm
