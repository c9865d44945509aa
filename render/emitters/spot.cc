// `spot`: a point light at to_world's origin shining along its +z, of `intensity` (W/sr, default
// 1) inside `beam_width` degrees (default 3/4 of the cutoff) falling off linearly in angle to 0 at
// `cutoff_angle` (default 20), as Mitsuba's spot (render/light.h: SpotFalloff).
#include <cmath>

#include "render/emitters/registry.h"

namespace irfarm {
namespace {

absl::Status Parse(EmitterParams& p, EmitterDesc* d) {
  absl::StatusOr<std::optional<Mat4>> to_world = p.Transform("to_world");
  if (!to_world.ok()) return to_world.status();
  const Mat4 m = p.World(to_world->value_or(Mat4()));
  d->position = m.ApplyPoint(Vec3(0.0f));
  const Vec3 axis = m.ApplyVector(Vec3(0, 0, 1));
  if (!(LengthSquared(axis) > 0) || !IsFinite(axis))
    return p.Error("to_world", "the spot's to_world takes its axis (+z) to zero");
  d->direction = Normalize(axis);
  absl::StatusOr<Vec3> intensity = p.Rgb("intensity", Vec3(1.0f));
  if (!intensity.ok()) return intensity.status();
  d->intensity = *intensity;
  absl::StatusOr<float> cutoff = p.Float("cutoff_angle", 20);
  if (!cutoff.ok()) return cutoff.status();
  d->cutoff_angle_deg = *cutoff;
  absl::StatusOr<float> beam = p.Float("beam_width", d->cutoff_angle_deg * 0.75f);
  if (!beam.ok()) return beam.status();
  d->beam_width_deg = *beam;
  // beam_width 0 (all falloff) is valid in Mitsuba; its Blender exporter writes it for a spot
  // blend of 1.
  if (!(d->cutoff_angle_deg > 0 && d->beam_width_deg >= 0)) {
    return p.Error("", "spot cutoff_angle must be positive and beam_width not negative");
  }
  return absl::OkStatus();
}

absl::StatusOr<Light> Build(const EmitterDesc& d, std::vector<std::unique_ptr<Texture>>*) {
  Light l;
  l.type = LightType::kSpot;
  l.position = d.position;
  l.direction = Normalize(d.direction);
  l.intensity = d.intensity;
  const float cutoff = d.cutoff_angle_deg * kPi / 180, beam = d.beam_width_deg * kPi / 180;
  l.cutoff = cutoff;
  l.cos_cutoff = std::cos(cutoff);
  l.cos_beam = std::cos(beam);
  l.inv_transition = cutoff > beam ? 1 / (cutoff - beam) : 0;
  return l;
}

// As a point light: I / d^2 at the closest distance allowed.
double Bound(const EmitterDesc& d, double d_min) { return InverseSquareBound(d.intensity, d_min); }

}  // namespace

extern const EmitterPlugin kSpotEmitter = {"spot", EmitterPlugin::Kind::kLocal, Parse, Build,
                                           Bound};

}  // namespace irfarm
