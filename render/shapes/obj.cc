// `obj`: a Wavefront OBJ mesh from `filename` (render/mesh_loader.h: ParseObjMesh), with
// Mitsuba's flip_tex_coords (on by default: each vt is stored as (u, 1 - v)).
#include "render/mesh_loader.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  return FileMeshShape(p, [&p](const std::string& path) -> absl::StatusOr<TriangleMesh> {
    absl::StatusOr<bool> flip_tex_coords = p.Bool("flip_tex_coords", true);
    if (!flip_tex_coords.ok()) return flip_tex_coords.status();
    return LoadObjMesh(path, *flip_tex_coords);
  });
}

}  // namespace

extern const ShapePlugin kObjShape = {"obj", Parse};

}  // namespace irfarm
