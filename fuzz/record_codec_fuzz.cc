// Fuzz target: the record wire codec as the coordinator meets it: bytes parsed as a RecordBatch
// (protobuf), decoded (DecodeRecords), each record checked (RecordProblem against the cornell
// box's bounds). What decodes must re-encode to the same records.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "coordinator/record_bounds.h"
#include "render/scene_loader.h"
#include "service/record_codec.h"

namespace {

const irfarm::RecordBounds& Bounds() {
  static const irfarm::RecordBounds bounds = [] {  // built once: the harness's fixed scene
    absl::StatusOr<irfarm::SceneDesc> d =
        irfarm::LoadSceneFile(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml", {});
    if (!d.ok()) __builtin_trap();
    return irfarm::RecordBoundsForScene(*d);
  }();
  return bounds;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  irfarm::v1::RecordBatch batch;
  if (!batch.ParseFromArray(data, int(size))) return 0;
  absl::StatusOr<std::vector<irfarm::IrradianceRecord>> recs = irfarm::DecodeRecords(batch);
  if (!recs.ok()) return 0;
  for (const irfarm::IrradianceRecord& r : *recs) (void)irfarm::RecordProblem(Bounds(), r);
  irfarm::v1::RecordBatch again;
  irfarm::PackRecords(*recs, 1, &again);
  absl::StatusOr<std::vector<irfarm::IrradianceRecord>> back = irfarm::DecodeRecords(again);
  if (!back.ok() || back->size() != recs->size()) __builtin_trap();
  return 0;
}
