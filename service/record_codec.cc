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
  // Occluders for every record of the batch or for none: a batch appended to one that came
  // without them (an older sender's) gets none either.
  if (batch->occluders_size() + 3 * int(records.size()) != 3 * batch->origins_size()) return;
  batch->mutable_occluders()->Reserve(3 * batch->origins_size());
  for (const IrradianceRecord& r : records) {
    batch->add_occluders(r.occluder.x);
    batch->add_occluders(r.occluder.y);
    batch->add_occluders(r.occluder.z);
  }
}

size_t BatchSize(const v1::RecordBatch& batch) { return size_t(batch.origins_size()); }

size_t BatchBytes(const v1::RecordBatch& batch) {
  return size_t(batch.values_size() + batch.occluders_size()) * sizeof(float) +
         size_t(batch.origins_size()) * 4;
}

absl::StatusOr<std::vector<IrradianceRecord>> DecodeRecords(const v1::RecordBatch& batch) {
  if (batch.values_size() % kFloatsPerRecord != 0 ||
      batch.values_size() / kFloatsPerRecord != batch.origins_size()) {
    return absl::InvalidArgumentError(
        "malformed record batch: " + std::to_string(batch.values_size()) + " floats for " +
        std::to_string(batch.origins_size()) + " origins");
  }
  const bool occluders = batch.occluders_size() > 0;
  if (occluders && batch.occluders_size() != 3 * batch.origins_size()) {
    return absl::InvalidArgumentError(
        "malformed record batch: " + std::to_string(batch.occluders_size()) +
        " occluder floats for " + std::to_string(batch.origins_size()) + " records");
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
    if (occluders)
      r.occluder =
          Vec3(batch.occluders(3 * i), batch.occluders(3 * i + 1), batch.occluders(3 * i + 2));
  }
  return out;
}

}  // namespace irfarm
