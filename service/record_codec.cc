// Packing and validating irradiance records for the wire (see record_codec.h).
#include "service/record_codec.h"

#include <string>

namespace irfarm {

void PackRecords(const std::vector<IrradianceRecord>& records, uint32_t origin_for_own,
                 v1::RecordBatch* batch) {
  batch->mutable_values()->Reserve(batch->values_size() + int(records.size()) * kFloatsPerRecord);
  batch->mutable_origins()->Reserve(batch->origins_size() + int(records.size()));
  for (const IrradianceRecord& r : records) {
    const float v[kFloatsPerRecord] = {r.position.x,   r.position.y, r.position.z,   r.normal.x,
                                       r.normal.y,     r.normal.z,   r.irradiance.x, r.irradiance.y,
                                       r.irradiance.z, r.radius};
    for (float f : v) batch->add_values(f);
    batch->add_origins(r.origin != 0 ? r.origin : origin_for_own);
  }
}

size_t BatchSize(const v1::RecordBatch& batch) { return size_t(batch.origins_size()); }

size_t BatchBytes(const v1::RecordBatch& batch) {
  return size_t(batch.values_size()) * sizeof(float) + size_t(batch.origins_size()) * 4;
}

absl::StatusOr<std::vector<IrradianceRecord>> DecodeRecords(const v1::RecordBatch& batch) {
  if (batch.values_size() % kFloatsPerRecord != 0 ||
      batch.values_size() / kFloatsPerRecord != batch.origins_size()) {
    return absl::InvalidArgumentError(
        "malformed record batch: " + std::to_string(batch.values_size()) + " floats for " +
        std::to_string(batch.origins_size()) + " origins");
  }
  std::vector<IrradianceRecord> out(size_t(batch.origins_size()));
  const float* v = batch.values().data();
  for (int i = 0; i < batch.origins_size(); ++i, v += kFloatsPerRecord) {
    IrradianceRecord& r = out[size_t(i)];
    r.position = Vec3(v[0], v[1], v[2]);
    r.normal = Vec3(v[3], v[4], v[5]);
    r.irradiance = Vec3(v[6], v[7], v[8]);
    r.radius = v[9];
    r.origin = batch.origins(i);
  }
  return out;
}

}  // namespace irfarm
