// Cache snapshot files: a job's irradiance records saved to warm-start a later render of the same
// scene (design.md "Snapshots"). No network here: the coordinator, the CLI and tests share it.
//
// Format (little-endian, version 2):
//   offset 0   8 bytes  magic "IRFSNAP\0"
//          8   u32      version (2)
//         12   u32      bytes per record (56)
//         16   u64      scene hash (SceneHash of the scene the records belong to)
//         24   u64      record count N
//         32   N x 56   records: position xyz, normal xyz, irradiance rgb, radius (10 f32),
//                       origin (u32), occluder xyz (3 f32; IrradianceRecord::occluder, zero: none)
//   32 + 56N   u64      FNV-1a 64 checksum of every byte before it
// Version 1 (before 2026-12-02) is read too: 44 bytes per record, no occluder.
// Reading checks the magic, version, sizes, checksum and every record (IsValidRecord); any
// failure is an error naming what is wrong, and no record of a bad file is used.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "cache/irradiance_record.h"

namespace irfarm {

constexpr uint32_t kSnapshotVersion = 2;

struct Snapshot {
  uint64_t scene_hash = 0;
  std::vector<IrradianceRecord> records;
};

// The file's bytes.
std::string SerializeSnapshot(const Snapshot& snapshot);
// The trailing checksum of a snapshot whose bytes before the checksum are data[0, n): FNV-1a 64.
uint64_t SnapshotChecksum(const char* data, size_t n);
// Parses and validates bytes; `name` (a path or "upload") is used in error messages.
absl::StatusOr<Snapshot> ParseSnapshot(const std::string& bytes, const std::string& name);

// Writes to `path` through a temporary file in the same folder renamed into place.
absl::Status WriteSnapshotFile(const Snapshot& snapshot, const std::string& path);
absl::StatusOr<Snapshot> ReadSnapshotFile(const std::string& path);

// FAILED_PRECONDITION with a clear message when the snapshot belongs to another scene.
absl::Status CheckSnapshotScene(const Snapshot& snapshot, uint64_t scene_hash,
                                const std::string& name);

}  // namespace irfarm
