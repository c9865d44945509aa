// `rectangle`: Mitsuba's [-1, 1]^2 in z = 0, facing +z, as two triangles
// (render/mesh_loader.h: MakeRectangleMesh). Rectangle lamps keep the analytic solid angle:
// Scene::Build recognises two triangles forming a rectangle.
#include "render/mesh_loader.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  absl::StatusOr<ShapeGeometry> g = TriangleShape(p);
  if (!g.ok()) return g;
  g->mesh = MakeRectangleMesh();
  g->turns_with_mirror = true;
  return g;
}

}  // namespace

extern const ShapePlugin kRectangleShape = {"rectangle", Parse};

}  // namespace irfarm
