// `disk`: Mitsuba's unit disk in z = 0, facing +z, as a fan of 128 triangles
// (render/mesh_loader.h: MakeDiskMesh).
#include "render/mesh_loader.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  absl::StatusOr<ShapeGeometry> g = TriangleShape(p);
  if (!g.ok()) return g;
  g->mesh = MakeDiskMesh(128);
  g->turns_with_mirror = true;
  return g;
}

}  // namespace

extern const ShapePlugin kDiskShape = {"disk", Parse};

}  // namespace irfarm
