// `serialized`: mesh `shape_index` (default 0) of a Mitsuba serialized file `filename`
// (render/serialized_mesh.h).
#include "render/serialized_mesh.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  return FileMeshShape(p, [&p](const std::string& path) -> absl::StatusOr<TriangleMesh> {
    absl::StatusOr<int> shape_index = p.Int("shape_index", 0);
    if (!shape_index.ok()) return shape_index.status();
    return LoadSerializedMesh(path, *shape_index);
  });
}

}  // namespace

extern const ShapePlugin kSerializedShape = {"serialized", Parse};

}  // namespace irfarm
