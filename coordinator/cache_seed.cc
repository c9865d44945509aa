// Cache seeding across jobs of the same scene (see cache_seed.h).
#include "coordinator/cache_seed.h"

#include <cstring>

namespace irfarm {
namespace {

bool IsIrrcache(const v1::RenderSettings& s) {
  return s.integrator().empty() || s.integrator() == "irrcache";
}

// FNV-1a over the bits that identify a record (where it is, which way it faces, its radius).
uint64_t RecordKey(const IrradianceRecord& r) {
  const float f[7] = {r.position.x, r.position.y, r.position.z, r.normal.x,
                      r.normal.y,   r.normal.z,   r.radius};
  unsigned char bytes[sizeof f];
  std::memcpy(bytes, f, sizeof f);
  uint64_t h = 1469598103934665603ull;
  for (unsigned char b : bytes) h = (h ^ b) * 1099511628211ull;
  return h;
}

}  // namespace

bool CanSeed(const v1::StoredJob& from, const v1::StoredJob& to) {
  const v1::Job& a = from.job();
  const v1::Job& b = to.job();
  return a.id() != b.id() && a.owner() == b.owner() && a.scene_hash() == b.scene_hash() &&
         IsIrrcache(a.settings()) && IsIrrcache(b.settings()) && b.settings().share_records() &&
         from.max_accuracy() == to.max_accuracy() &&
         a.settings().record_rays() == b.settings().record_rays() &&
         a.settings().no_caustics() == b.settings().no_caustics();
}

void SeedSet::Add(const std::vector<IrradianceRecord>& records) {
  for (const IrradianceRecord& r : records) Add(r);
}

void SeedSet::Add(const IrradianceRecord& r) {
  if (seen_.insert(RecordKey(r)).second) records_.push_back(r);
}

}  // namespace irfarm
