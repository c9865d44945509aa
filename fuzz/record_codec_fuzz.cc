// Fuzz target: the record wire codec as the coordinator meets it: bytes parsed as a RecordBatch
// (protobuf), decoded (DecodeRecords), each record checked (RecordProblem against the cornell
// box's bounds). What decodes must re-encode to the same records.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "render/record_bounds.h"
#include "fuzz/cornell_record_bounds.h"
#include "service/record_codec.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  irfarm::v1::RecordBatch batch;
  if (!batch.ParseFromArray(data, int(size))) return 0;
  absl::StatusOr<std::vector<irfarm::IrradianceRecord>> recs = irfarm::DecodeRecords(batch);
  if (!recs.ok()) return 0;
  for (const irfarm::IrradianceRecord& r : *recs)
    (void)irfarm::RecordProblem(irfarm::CornellRecordBounds(), r);
  irfarm::v1::RecordBatch again;
  irfarm::PackRecords(*recs, 1, &again);
  absl::StatusOr<std::vector<irfarm::IrradianceRecord>> back = irfarm::DecodeRecords(again);
  if (!back.ok() || back->size() != recs->size()) __builtin_trap();
  return 0;
}
