// `cube`: Mitsuba's [-1, 1]^3 with outward faces (render/mesh_loader.h: MakeCubeMesh).
#include "render/mesh_loader.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  absl::StatusOr<ShapeGeometry> g = TriangleShape(p);
  if (!g.ok()) return g;
  g->mesh = MakeCubeMesh();
  return g;
}

}  // namespace

extern const ShapePlugin kCubeShape = {"cube", Parse};

}  // namespace irfarm
