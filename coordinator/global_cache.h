// GlobalCache: the merged irradiance cache of one job on the coordinator. Every record a worker
// publishes is validated (IsValidRecord: finite values, unit normal, R > 0, E >= 0, and within the
// scene's RecordBounds, record_bounds.h) before it is merged; invalid ones are dropped and
// counted, the rest of the batch is kept. The merged records are kept in arrival order
// (RecordLog), for late-joining workers, snapshots and the store, and a compact entry of each by
// the cell of a 16^3 grid over the scene they lie in, so that a grown fan-out region's backlog
// looks at the records near it only (RecordsNear). The coordinator never looks irradiance up, so it
// builds no octree: inserting every record into one was about a tenth of its CPU at 64 workers
// (bench_scale_sim --perf) and most of its memory, for nothing that was read. The workers' caches
// interpolate. Not thread-safe: JobManager serialises access.
#pragma once

#include <cstddef>
#include <vector>

#include "cache/irradiance_cache.h"
#include "coordinator/record_log.h"
#include "render/record_bounds.h"

namespace irfarm {

class GlobalCache {
 public:
  GlobalCache(const CacheSettings& settings, const RecordBounds& bounds);

  // Merges the valid records of `records`; returns them (in order). Counts the others and, when
  // `problem` is given, sets it to why the first of them was refused (else leaves it).
  std::vector<IrradianceRecord> Merge(const std::vector<IrradianceRecord>& records,
                                      const char** problem = nullptr);
  // Merge in two steps, so that a caller can store the records before they count: Check
  // returns the valid records (counting and explaining the others like Merge) and Insert adds
  // records Check returned (even when the cache was closed meanwhile).
  std::vector<IrradianceRecord> Check(const std::vector<IrradianceRecord>& records,
                                      const char** problem = nullptr);
  void Insert(const std::vector<IrradianceRecord>& valid);
  // A finished job takes no more records (Check refuses them; the records stay for snapshots
  // and seeding).
  void Close() { closed_ = true; }

  const RecordLog& records() const { return records_; }

  // What a grid cell keeps of each of its records: enough to decide whether it belongs to a
  // backlog without reading the record (the scan stays in the cell's contiguous entries).
  struct Entry {
    Vec3 position;
    float radius;
    uint64_t index;  // in records()
    uint32_t origin;
    uint8_t level;
  };
  // A cell's entries, in small blocks: most of the 4,096 cells hold few records.
  using CellLog = BlockLog<Entry, 256>;

  // The records merged so far that may reach `box` at max_accuracy(): every one that
  // RecordReachesBox(r, box, max_accuracy()) accepts, and others of the grid cells near it, as
  // views that stay valid and unchanged without the caller's lock while the cache grows.
  class Near {
   public:
    // f(record) for each record whose entry `keep(entry)` accepts.
    template <typename Keep, typename F>
    void ForEach(Keep keep, F f) const {
      for (const CellLog::View& cell : cells_)
        for (size_t i = 0; i < cell.size(); ++i)
          if (keep(cell[i])) f(records_[cell[i].index]);
    }
    template <typename F>
    void ForEach(F f) const {
      ForEach([](const Entry&) { return true; }, f);
    }

   private:
    friend class GlobalCache;
    RecordLog::View records_;
    std::vector<CellLog::View> cells_;
  };
  Near RecordsNear(const Bounds3& box) const;
  size_t size() const { return records_.size(); }
  size_t rejected() const { return rejected_; }
  const RecordBounds& bounds() const { return bounds_; }
  // The largest lookup accuracy of the job (CacheSettings.max_accuracy, as clamped by the
  // cache): a record reaches max_accuracy() * R_i (filtered fan-out, fanout_region.h).
  float max_accuracy() const { return max_accuracy_; }

 private:
  static constexpr int kGrid = 16;  // cells per axis
  int CellOf(const Vec3& p) const;
  Bounds3 CellBox(int cell) const;  // a little larger than the cell: covers rounding in CellOf

  RecordBounds bounds_;
  float max_accuracy_;
  bool closed_ = false;
  RecordLog records_;
  std::vector<CellLog> cells_;          // kGrid^3 cells of level-0 records, then level > 0
  std::vector<float> cell_max_radius_;  // per level-0 cell
  size_t rejected_ = 0;
};

}  // namespace irfarm
