// `ply`: a PLY mesh from `filename` (render/mesh_loader.h: LoadPlyMesh; ascii or binary), with
// Mitsuba's flip_tex_coords (off by default for PLY: set, each uv is stored as (u, 1 - v)).
#include "render/mesh_loader.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  return FileMeshShape(p, [&p](const std::string& path) -> absl::StatusOr<TriangleMesh> {
    absl::StatusOr<bool> flip_tex_coords = p.Bool("flip_tex_coords", false);
    if (!flip_tex_coords.ok()) return flip_tex_coords.status();
    absl::StatusOr<TriangleMesh> mesh = LoadPlyMesh(path);
    if (mesh.ok() && *flip_tex_coords)
      for (size_t i = 1; i < mesh->uvs.size(); i += 2) mesh->uvs[i] = 1 - mesh->uvs[i];
    return mesh;
  });
}

}  // namespace

extern const ShapePlugin kPlyShape = {"ply", Parse};

}  // namespace irfarm
