// GlobalCache: the merged irradiance cache of one job on the coordinator. Every record a worker
// publishes is validated (IsValidRecord: finite values, unit normal, R > 0, E >= 0) before it is
// merged; invalid ones are dropped and counted, the rest of the batch is kept. Keeps the records
// in arrival order too, for late-joining workers, snapshots and the store. Not thread-safe:
// JobManager serialises access.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "cache/irradiance_cache.h"

namespace irfarm {

class GlobalCache {
 public:
  explicit GlobalCache(const CacheSettings& settings);

  // Merges the valid records of `records`; returns them (in order). Counts the others.
  std::vector<IrradianceRecord> Merge(const std::vector<IrradianceRecord>& records);

  const std::vector<IrradianceRecord>& records() const { return records_; }
  size_t size() const { return records_.size(); }
  size_t rejected() const { return rejected_; }
  const IrradianceCache& octree() const { return *cache_; }

 private:
  std::unique_ptr<IrradianceCache> cache_;
  std::vector<IrradianceRecord> records_;
  size_t rejected_ = 0;
};

}  // namespace irfarm
