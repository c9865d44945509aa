// `point`: an isotropic point light of `intensity` (W/sr, default 1) at `position`, or at the
// origin of `to_world` (one or the other, as Mitsuba).
#include "render/emitters/registry.h"

namespace irfarm {
namespace {

absl::Status Parse(EmitterParams& p, EmitterDesc* d) {
  absl::StatusOr<std::optional<std::array<double, 3>>> position = p.Point("position");
  if (!position.ok()) return position.status();
  absl::StatusOr<std::optional<Mat4>> to_world = p.Transform("to_world");
  if (!to_world.ok()) return to_world.status();
  if (*position && *to_world) {
    return p.Error("", "give either position or to_world for a point emitter, not both");
  }
  const Mat4 m = *position ? Mat4::Translate((**position)[0], (**position)[1], (**position)[2])
                           : to_world->value_or(Mat4());
  d->position = p.World(m).ApplyPoint(Vec3(0.0f));
  absl::StatusOr<Vec3> intensity = p.Rgb("intensity", Vec3(1.0f));
  if (!intensity.ok()) return intensity.status();
  d->intensity = *intensity;
  return absl::OkStatus();
}

absl::StatusOr<Light> Build(const EmitterDesc& d, std::vector<std::unique_ptr<Texture>>*) {
  Light l;
  l.type = LightType::kPoint;
  l.position = d.position;
  l.intensity = d.intensity;
  return l;
}

// I / d^2 at the closest distance allowed.
double Bound(const EmitterDesc& d, double d_min) { return InverseSquareBound(d.intensity, d_min); }

}  // namespace

extern const EmitterPlugin kPointEmitter = {"point", EmitterPlugin::Kind::kLocal, Parse, Build,
                                            Bound};

}  // namespace irfarm
