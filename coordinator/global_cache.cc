// GlobalCache: validate, merge, remember (see global_cache.h).
#include "coordinator/global_cache.h"

namespace irfarm {

GlobalCache::GlobalCache(const CacheSettings& settings)
    : cache_(std::make_unique<IrradianceCache>(settings)) {}

std::vector<IrradianceRecord> GlobalCache::Merge(const std::vector<IrradianceRecord>& records) {
  std::vector<IrradianceRecord> accepted;
  accepted.reserve(records.size());
  for (const IrradianceRecord& r : records) {
    if (!IsValidRecord(r)) {
      ++rejected_;
      continue;
    }
    cache_->Insert(r);
    records_.push_back(r);
    accepted.push_back(r);
  }
  return accepted;
}

}  // namespace irfarm
