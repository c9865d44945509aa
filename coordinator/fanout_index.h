// FanoutIndex: which of a job's region-filtered workers a record reaches (RecordReachesBox,
// fanout_region.h), without testing the record against every worker's region. The regions'
// boxes are binned into a uniform grid over the scene's box (about kCellsPerBox cells per box,
// cubic cells); a record looks only at the boxes listed in the cells its reach (the cube of half
// side max_accuracy * R around it) overlaps, and tests those exactly, so the answer is exactly
// the brute-force one (tests/service/fanout_index_test.cc checks that on random regions and
// records). Per record the cost is the cells its reach overlaps plus the boxes listed there,
// not the number of workers; a box spanning more than kMaxCellsPerBox cells is kept in a list
// tested with every record, and a record whose reach spans more cells than there are workers
// is tested against all of them (both are at most the brute-force cost). Records of level > 0
// reach every worker (fanout_region.h), also without a test.
//
// Built from scratch (O(workers x cells per box)) whenever a region or the job's set of workers
// changes: JobManager marks the job's index stale then and rebuilds it at the next record batch,
// so a burst of lease changes costs one build. Workers are slots 0..size()-1 in the order given.
// Not thread-safe (JobManager's lock); Query keeps scratch state, so it allocates nothing once
// `out` has grown to its size.
#pragma once

#include <cstdint>
#include <vector>

#include "cache/irradiance_record.h"
#include "core/math.h"

namespace irfarm {

class FanoutIndex {
 public:
  struct Entry {
    uint32_t worker;  // JobManager's worker id
    Bounds3 box;      // its region (empty: none yet, gets level > 0 records only)
  };
  static constexpr int kCellsPerBox = 8;        // grid cells per non-empty box, about
  static constexpr int kMaxCells = 1 << 16;     // grid cells at most (256 KB of cell starts)
  static constexpr int kMaxCellsPerBox = 1024;  // beyond: the box goes to the always-tested list

  // `scene` bounds every box (ParseTileRegion clips them to it); records outside it are handled
  // too (their reach is clamped to the grid, which holds every box).
  void Build(const Bounds3& scene, std::vector<Entry> entries);
  size_t size() const { return entries_.size(); }
  uint32_t worker(size_t slot) const { return entries_[slot].worker; }
  // Replaces *out with the slots whose box `r` reaches at `max_accuracy` (every slot for a
  // level > 0 record), in no particular order, each once.
  void Query(const IrradianceRecord& r, float max_accuracy, std::vector<uint32_t>* out);
  // The same answer by testing every slot (the fallback for huge reaches).
  void QueryAll(const IrradianceRecord& r, float max_accuracy, std::vector<uint32_t>* out) const;
  // Level-0 queries answered from the grid, not by QueryAll (what the tests need to know they
  // tested the grid).
  uint64_t grid_queries() const { return grid_queries_; }

 private:
  // The cell coordinate of `v` on axis k, clamped to the grid: monotone in v, so a point of a box
  // lies in a cell between the cells of the box's corners.
  int Cell(double v, int k) const;

  std::vector<Entry> entries_;
  Vec3 lo_;             // the grid's corner (the scene box's lo)
  double inv_cell_[3];  // cells per scene unit, per axis
  int n_[3] = {1, 1, 1};
  std::vector<uint32_t> cell_start_;  // CSR: slots of cell c are items_[start[c], start[c+1])
  std::vector<uint32_t> items_;
  std::vector<uint32_t> always_;  // slots of boxes spanning more than kMaxCellsPerBox cells
  std::vector<uint32_t> seen_;    // per slot: the query number that last listed it
  uint32_t query_ = 0;
  uint64_t grid_queries_ = 0;
};

}  // namespace irfarm
