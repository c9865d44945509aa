// Mitsuba's `serialized` mesh format (the shape plugin of that name; Mitsuba 0.6's Blender
// exporter and its mtsimport write it, and Mitsuba 3 still reads it): a little-endian header
// (uint16 0x041C, uint16 version 3 or 4), then a zlib stream holding flags (uint32), in version 4
// the mesh's name (NUL-terminated), vertex and triangle counts (uint64 each), positions, optional
// normals, uvs and colours (float or double, by the flags) and uint32 triangle indices. A file may
// hold several meshes one after another, each with its own header and zlib stream; its last
// bytes are the meshes' offsets (uint64 in version 4, uint32 in version 3) and their count
// (uint32). Format as documented by Mitsuba 3's src/shapes/serialized.cpp.
//
// The file is untrusted: every count is checked against the bytes the stream really holds (the
// arrays grow as data arrives, so a huge count in a short file allocates nothing), every index
// against the vertex count, and every offset against the file's size. Errors are statuses whose
// message is "FILE: what is wrong" (mesh N: ...); NOT_FOUND when the file cannot be read.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "render/scene_desc.h"

namespace irfarm {

// Mesh `shape_index` (0-based) of the file, in object space. uvs are kept as stored (Mitsuba does
// not flip a serialized mesh's v), vertex colours are skipped, and the file's face-normals flag
// is ignored, all as Mitsuba 3 does.
absl::StatusOr<TriangleMesh> LoadSerializedMesh(const std::string& path, int shape_index);

// The same from the file's bytes in memory; `path` is only used in error messages.
absl::StatusOr<TriangleMesh> ParseSerializedMesh(const std::string& bytes, const std::string& path,
                                                 int shape_index);

}  // namespace irfarm
