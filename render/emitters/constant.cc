// `constant`: uniform `radiance` (default 1) from every direction, infinitely far away.
#include "render/emitters/registry.h"

namespace irfarm {
namespace {

absl::Status Parse(EmitterParams& p, EmitterDesc* d) {
  absl::StatusOr<Vec3> radiance = p.Rgb("radiance", Vec3(1.0f));
  if (!radiance.ok()) return radiance.status();
  d->radiance = *radiance;
  return absl::OkStatus();
}

absl::StatusOr<Light> Build(const EmitterDesc& d, std::vector<std::unique_ptr<Texture>>*) {
  Light l;
  l.type = LightType::kConstant;
  l.radiance = d.radiance;
  l.average_radiance = d.radiance;
  return l;
}

double Bound(const EmitterDesc& d, double) {
  return kPi * std::max(0.0f, MaxComponent(d.radiance));
}

}  // namespace

extern const EmitterPlugin kConstantEmitter = {"constant", EmitterPlugin::Kind::kEnvironment, Parse,
                                               Build, Bound};

}  // namespace irfarm
