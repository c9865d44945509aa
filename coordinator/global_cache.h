// GlobalCache: the merged irradiance cache of one job on the coordinator. Every record a worker
// publishes is validated (IsValidRecord: finite values, unit normal, R > 0, E >= 0, and within the
// scene's RecordBounds, record_bounds.h) before it is merged; invalid ones are dropped and
// counted, the rest of the batch is kept. Keeps the records
// in arrival order too, for late-joining workers, snapshots and the store. Not thread-safe:
// JobManager serialises access.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "cache/irradiance_cache.h"
#include "coordinator/record_bounds.h"
#include "coordinator/record_log.h"

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
  // records Check returned (to the record list even when the index was released meanwhile).
  std::vector<IrradianceRecord> Check(const std::vector<IrradianceRecord>& records,
                                      const char** problem = nullptr);
  void Insert(const std::vector<IrradianceRecord>& valid);
  // Drops the lookup octree (a finished job takes no more records; the record list stays for
  // snapshots and seeding).
  void ReleaseIndex() { cache_.reset(); }

  const RecordLog& records() const { return records_; }
  size_t size() const { return records_.size(); }
  size_t rejected() const { return rejected_; }
  const RecordBounds& bounds() const { return bounds_; }
  // The largest lookup accuracy of the job (CacheSettings.max_accuracy, as clamped by the
  // cache): a record reaches max_accuracy() * R_i (filtered fan-out, fanout_region.h).
  float max_accuracy() const { return max_accuracy_; }

 private:
  RecordBounds bounds_;
  std::unique_ptr<IrradianceCache> cache_;  // null after ReleaseIndex
  RecordLog records_;
  size_t rejected_ = 0;
  float max_accuracy_;
};

}  // namespace irfarm
