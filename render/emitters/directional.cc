// `directional`: parallel light travelling along `direction` (or to_world's +z; one or the
// other), of `irradiance` (W/m^2 on a surface facing it, default 1).
#include "render/emitters/registry.h"

namespace irfarm {
namespace {

absl::Status Parse(EmitterParams& p, EmitterDesc* d) {
  absl::StatusOr<std::optional<Vec3>> direction = p.Vector("direction");
  if (!direction.ok()) return direction.status();
  absl::StatusOr<std::optional<Mat4>> to_world = p.Transform("to_world");
  if (!to_world.ok()) return to_world.status();
  if (*direction && *to_world) {
    return p.Error("", "give either direction or to_world for a directional emitter, not both");
  }
  const Vec3 v = *direction ? **direction : to_world->value_or(Mat4()).ApplyVector(Vec3(0, 0, 1));
  if (!(LengthSquared(v) > 0)) return p.Error("direction", "zero light direction");
  d->direction = Normalize(v);
  absl::StatusOr<Vec3> irradiance = p.Rgb("irradiance", Vec3(1.0f));
  if (!irradiance.ok()) return irradiance.status();
  // Mitsuba lights along to_world's +z as it is, not made unit (directional.cpp: ds.d = -M z), so
  // a to_world that scales it scales the cosine a diffuse surface sees by |M z|: its irradiance is
  // that much larger (a Blender sun of object scale 2 renders twice as bright there).
  d->irradiance = *irradiance * (*direction ? 1.0f : Length(v));
  return absl::OkStatus();
}

absl::StatusOr<Light> Build(const EmitterDesc& d, std::vector<std::unique_ptr<Texture>>*) {
  Light l;
  l.type = LightType::kDirectional;
  l.direction = Normalize(d.direction);
  l.intensity = d.irradiance;
  return l;
}

double Bound(const EmitterDesc& d, double) { return std::max(0.0f, MaxComponent(d.irradiance)); }

}  // namespace

extern const EmitterPlugin kDirectionalEmitter = {"directional", EmitterPlugin::Kind::kLocal, Parse,
                                                  Build, Bound};

}  // namespace irfarm
