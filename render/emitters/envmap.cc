// `envmap`: radiance from a latitude-longitude image `filename` (EXR, HDR, PNG; linear),
// times `scale` (default 1), oriented by `to_world` (render/light.h: EnvmapUv). The image is read
// when the scene is built; LightSampler samples it by importance (EnvironmentMapSampler).
#include <cmath>
#include <limits>

#include "render/emitters/registry.h"

namespace irfarm {
namespace {

// Mean radiance of the map over the sphere (the light's selection weight against local lights).
Vec3 AverageEnvironmentRadiance(const Light& l) {
  constexpr int kN = 64;
  Vec3 sum;
  double wsum = 0;
  for (int j = 0; j < kN; ++j) {
    const float theta = (j + 0.5f) * kPi / kN;
    const float w = std::sin(theta);
    for (int i = 0; i < 2 * kN; ++i) {
      sum += l.envmap->EvalLatLong((i + 0.5f) / (2 * kN), (j + 0.5f) / kN) * (w * l.scale);
      wsum += w;
    }
  }
  return sum / float(wsum);
}

absl::Status Parse(EmitterParams& p, EmitterDesc* d) {
  absl::StatusOr<std::string> filename = p.File("filename");
  if (!filename.ok()) return filename.status();
  d->filename = *filename;
  absl::StatusOr<float> scale = p.Float("scale", 1);
  if (!scale.ok()) return scale.status();
  d->scale = *scale;
  absl::StatusOr<std::optional<Mat4>> to_world = p.Transform("to_world");
  if (!to_world.ok()) return to_world.status();
  d->to_world = to_world->value_or(Mat4());
  const double det = d->to_world.Determinant3();
  if (!(det != 0) || !std::isfinite(det))
    return p.Error("to_world", "the envmap's to_world is singular");
  return absl::OkStatus();
}

absl::StatusOr<Light> Build(const EmitterDesc& d, std::vector<std::unique_ptr<Texture>>* textures) {
  Light l;
  l.type = LightType::kEnvmap;
  TextureDesc td;
  td.filename = d.filename;
  td.raw = false;  // 8-bit images are sRGB-encoded, as Mitsuba decodes them (EXR and HDR: linear)
  td.loc = d.loc;
  absl::StatusOr<std::unique_ptr<BitmapTexture>> tex =
      BitmapTexture::Load(td, /*finite_only=*/true);
  if (!tex.ok()) return tex.status();
  l.envmap = tex->get();
  textures->push_back(*std::move(tex));
  l.world_to_env = d.to_world.Inverse();
  l.scale = d.scale;
  l.average_radiance = AverageEnvironmentRadiance(l);
  return l;
}

double Bound(const EmitterDesc&, double) { return std::numeric_limits<double>::infinity(); }

}  // namespace

extern const EmitterPlugin kEnvmapEmitter = {"envmap", EmitterPlugin::Kind::kEnvironment, Parse,
                                             Build, Bound};

}  // namespace irfarm
