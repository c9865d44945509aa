// `ply`: a PLY mesh from `filename` (render/mesh_loader.h: LoadPlyMesh; ascii or binary).
#include "render/mesh_loader.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  return FileMeshShape(p, [](const std::string& path) { return LoadPlyMesh(path); });
}

}  // namespace

extern const ShapePlugin kPlyShape = {"ply", Parse};

}  // namespace irfarm
