// `sphere`: analytic (Embree's user geometry in Scene::Build), `center` (default the origin) and
// `radius` (default 1) in its own space; to_world may move and scale it uniformly.
#include "absl/strings/str_cat.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  ShapeGeometry g;
  g.sphere = true;
  absl::StatusOr<std::optional<std::array<double, 3>>> center = p.Point("center");
  if (!center.ok()) return center.status();
  if (*center) g.center = **center;
  absl::StatusOr<float> radius = p.Float("radius", 1);
  if (!radius.ok()) return radius.status();
  if (!(*radius > 0)) {
    return p.Error("radius", absl::StrCat("sphere radius must be positive, got ", *radius));
  }
  g.radius = *radius;
  return g;
}

}  // namespace

extern const ShapePlugin kSphereShape = {"sphere", Parse};

}  // namespace irfarm
