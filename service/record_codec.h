// Irradiance records on the wire: packs IrradianceRecords into a RecordBatch (10 floats + one
// origin + 3 occluder floats per record, no per-record messages) and unpacks them; receivers
// validate every record (IsValidRecord: finite values, unit normal, R > 0, E >= 0) before
// anything uses it.
#pragma once

#include <cstddef>
#include <vector>

#include "absl/status/statusor.h"
#include "cache/irradiance_record.h"
#include "irfarm/v1/common.pb.h"

namespace irfarm {

constexpr int kFloatsPerRecord = 10;

// Appends `records` to `batch`. An origin of 0 is replaced by `origin_for_own` (a worker stamps
// its id on the records it computed).
void PackRecords(const std::vector<IrradianceRecord>& records, uint32_t origin_for_own,
                 v1::RecordBatch* batch);

// Number of records in a well-formed batch.
size_t BatchSize(const v1::RecordBatch& batch);
// Approximate payload bytes of a batch (what the stats call bytes sent / received).
size_t BatchBytes(const v1::RecordBatch& batch);

// Decodes every record of `batch`, valid or not: the receiver validates them (IsValidRecord)
// and counts what it rejects. INVALID_ARGUMENT when the batch is malformed: values not 10 per
// origin, occluders neither 3 per origin nor absent (then the records have none).
absl::StatusOr<std::vector<IrradianceRecord>> DecodeRecords(const v1::RecordBatch& batch);

}  // namespace irfarm
