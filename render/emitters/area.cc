// `area`: uniform `radiance` (default 1) from the front of the shape it is nested in. Its light is
// built from the shape's triangles by Scene::Build (rectangles keep their analytic solid angle,
// meshes get a light tree), so the plugin only reads the radiance.
#include "render/emitters/registry.h"

namespace irfarm {
namespace {

absl::Status Parse(EmitterParams& p, EmitterDesc* d) {
  absl::StatusOr<Vec3> radiance = p.Rgb("radiance", Vec3(1.0f));
  if (!radiance.ok()) return radiance.status();
  d->radiance = *radiance;
  return absl::OkStatus();
}

double Bound(const EmitterDesc& d, double) {
  return kPi * std::max(0.0f, MaxComponent(d.radiance));
}

}  // namespace

extern const EmitterPlugin kAreaEmitter = {"area", EmitterPlugin::Kind::kArea, Parse, nullptr,
                                           Bound};

}  // namespace irfarm
