// Fuzz target: the PLY reader (LoadPlyMesh, which reads a file: the input is written to a file of
// this process first). Every mesh it returns must have in-range indices.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

#include "render/mesh_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = "/tmp/irfarm-ply-fuzz-" + std::to_string(getpid()) + ".ply";
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  absl::StatusOr<irfarm::TriangleMesh> mesh = irfarm::LoadPlyMesh(path);
  if (!mesh.ok()) return 0;
  const size_t n = mesh->positions.size();
  if (mesh->indices.size() % 3 != 0) __builtin_trap();
  for (const auto i : mesh->indices)
    if (size_t(i) >= n) __builtin_trap();
  return 0;
}
