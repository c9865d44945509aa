// GlobalCache: validate, merge, remember (see global_cache.h).
#include "coordinator/global_cache.h"

namespace irfarm {

GlobalCache::GlobalCache(const CacheSettings& settings, const RecordBounds& bounds)
    : bounds_(bounds),
      cache_(std::make_unique<IrradianceCache>(settings)),
      max_accuracy_(cache_->max_accuracy()) {}

std::vector<IrradianceRecord> GlobalCache::Check(const std::vector<IrradianceRecord>& records,
                                                 const char** problem) {
  std::vector<IrradianceRecord> accepted;
  if (!cache_) {  // released: the job is over
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
  for (const IrradianceRecord& r : valid) {
    if (cache_) cache_->Insert(r);
    records_.Append(r);  // also after ReleaseIndex: checked (and stored) while the job ran
  }
}

std::vector<IrradianceRecord> GlobalCache::Merge(const std::vector<IrradianceRecord>& records,
                                                 const char** problem) {
  std::vector<IrradianceRecord> accepted = Check(records, problem);
  Insert(accepted);
  return accepted;
}

}  // namespace irfarm
