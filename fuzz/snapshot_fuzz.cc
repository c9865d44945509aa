// Fuzz target: the cache snapshot reader (ParseSnapshot) and the record checks applied to every
// imported record (RecordProblem, against the cornell box's bounds). Each input is parsed twice:
// as it is (the header and checksum checks), and repaired, with the record count set from the
// input's length and the trailing checksum recomputed, so that mutated records reach the
// per-record checks instead of nearly always failing the checksum (a random mutation keeps a
// 64-bit checksum valid with probability 2^-64). Oracles: a record that passes RecordProblem
// must be finite with R > 0 and E >= 0; a version-2 snapshot that parses must serialise back to
// the same bytes, and a version-1 one (read, never written) to version-2 bytes that parse to the
// same records. Seeds: tests/data/fuzz/snapshot_fuzz/ (real snapshots exported by the service,
// fuzz/make_snapshot_seed.sh). Measured, 60 s each, side by side on a loaded machine, with this
// file, cache/snapshot.cc and coordinator/record_bounds.cc instrumented (the rest not): the
// previous harness without a seed 84 edges (5.2 M runs), with the seed 215; this harness with
// the seed 281 edges, 569 features (562 k runs).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "cache/snapshot.h"
#include "render/record_bounds.h"
#include "fuzz/cornell_record_bounds.h"

namespace {

// cache/snapshot.h: header, bytes per record of versions 1 and 2, checksum.
constexpr size_t kHeaderBytes = 32, kRecordBytesV1 = 44, kRecordBytesV2 = 56, kChecksumBytes = 8;

bool SameRecord(const irfarm::IrradianceRecord& a, const irfarm::IrradianceRecord& b) {
  return std::memcmp(&a.position, &b.position, sizeof a.position) == 0 &&
         std::memcmp(&a.normal, &b.normal, sizeof a.normal) == 0 &&
         std::memcmp(&a.irradiance, &b.irradiance, sizeof a.irradiance) == 0 &&
         std::memcmp(&a.radius, &b.radius, sizeof a.radius) == 0 && a.origin == b.origin &&
         std::memcmp(&a.occluder, &b.occluder, sizeof a.occluder) == 0;
}

uint32_t Version(const std::string& bytes) {
  uint32_t v = 0;
  if (bytes.size() >= 12) std::memcpy(&v, &bytes[8], sizeof v);
  return v;
}

void Check(const std::string& bytes) {
  absl::StatusOr<irfarm::Snapshot> snap = irfarm::ParseSnapshot(bytes, "fuzz");
  if (!snap.ok()) return;
  const std::string out = irfarm::SerializeSnapshot(*snap);
  if (Version(bytes) == irfarm::kSnapshotVersion) {
    if (out != bytes) __builtin_trap();
  } else {
    absl::StatusOr<irfarm::Snapshot> again = irfarm::ParseSnapshot(out, "fuzz");
    if (!again.ok() || again->scene_hash != snap->scene_hash ||
        again->records.size() != snap->records.size())
      __builtin_trap();
    for (size_t i = 0; i < snap->records.size(); ++i)
      if (!SameRecord(again->records[i], snap->records[i])) __builtin_trap();
  }
  for (const irfarm::IrradianceRecord& r : snap->records) {
    if (irfarm::RecordProblem(irfarm::CornellRecordBounds(), r) != nullptr) continue;
    if (!(r.radius > 0) || !std::isfinite(r.radius) || !(r.irradiance.x >= 0) ||
        !std::isfinite(r.position.x))
      __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::string bytes(reinterpret_cast<const char*>(data), size);
  Check(bytes);
  if (size < kHeaderBytes + kChecksumBytes) return 0;
  const size_t body = size - kChecksumBytes;
  const size_t record_bytes = Version(bytes) == 1 ? kRecordBytesV1 : kRecordBytesV2;
  if ((body - kHeaderBytes) % record_bytes == 0) {
    const uint64_t count = (body - kHeaderBytes) / record_bytes;
    std::memcpy(&bytes[24], &count, sizeof count);  // offset 24: the record count
  }
  const uint64_t sum = irfarm::SnapshotChecksum(bytes.data(), body);
  std::memcpy(&bytes[body], &sum, sizeof sum);
  if (std::memcmp(bytes.data(), data, size) != 0) Check(bytes);
  return 0;
}
