// Fuzz target: the reader of Mitsuba's serialized meshes (ParseSerializedMesh, from memory), for
// mesh 0 and mesh 1 of each input (the second goes through the end-of-file table of meshes).
// Every mesh it returns must have in-range indices and whole arrays.
#include <cstddef>
#include <cstdint>
#include <string>

#include "render/serialized_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  for (int index = 0; index < 2; ++index) {
    absl::StatusOr<irfarm::TriangleMesh> mesh =
        irfarm::ParseSerializedMesh(bytes, "fuzz.serialized", index);
    if (!mesh.ok()) continue;
    const size_t n = mesh->positions.size();
    if (mesh->indices.size() % 3 != 0) __builtin_trap();
    if (!mesh->normals.empty() && mesh->normals.size() != n) __builtin_trap();
    if (!mesh->uvs.empty() && mesh->uvs.size() != 2 * n) __builtin_trap();
    for (const auto i : mesh->indices)
      if (size_t(i) >= n) __builtin_trap();
  }
  return 0;
}
