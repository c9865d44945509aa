// Fuzz target: the OBJ reader (ParseObjMesh) on arbitrary text. Every mesh it returns must have
// in-range indices and matching attribute arrays.
#include <cstddef>
#include <cstdint>
#include <string>

#include "render/mesh_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  absl::StatusOr<irfarm::TriangleMesh> mesh = irfarm::ParseObjMesh(text, "fuzz.obj");
  if (!mesh.ok()) return 0;
  const size_t n = mesh->positions.size();
  if (mesh->indices.size() % 3 != 0) __builtin_trap();
  for (const auto i : mesh->indices)
    if (size_t(i) >= n) __builtin_trap();
  if (!mesh->normals.empty() && mesh->normals.size() != n) __builtin_trap();
  if (!mesh->uvs.empty() && mesh->uvs.size() != 2 * n) __builtin_trap();
  return 0;
}
