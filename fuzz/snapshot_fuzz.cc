// Fuzz target: the cache snapshot reader (ParseSnapshot) and the record checks applied to every
// imported record (RecordProblem, against the cornell box's bounds). A record that passes must be
// finite with R > 0 and E >= 0.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "cache/snapshot.h"
#include "coordinator/record_bounds.h"
#include "fuzz/cornell_record_bounds.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  absl::StatusOr<irfarm::Snapshot> snap = irfarm::ParseSnapshot(bytes, "fuzz");
  if (!snap.ok()) return 0;
  for (const irfarm::IrradianceRecord& r : snap->records) {
    if (irfarm::RecordProblem(irfarm::CornellRecordBounds(), r) != nullptr) continue;
    if (!(r.radius > 0) || !std::isfinite(r.radius) || !(r.irradiance.x >= 0) ||
        !std::isfinite(r.position.x))
      __builtin_trap();
  }
  return 0;
}
