// Emitter plugins by their Mitsuba 3 XML name. Each emitter is one file in render/emitters/ that
// defines an EmitterPlugin and one line in registry.cc's list; nothing else in the loader, in
// Scene::Build or in the coordinator's record bounds names an emitter type. An emitter:
//   parse:  the XML loader finds the plugin by name and calls plugin.parse with an EmitterParams
//           reader and the EmitterDesc to fill; parameters the plugin did not ask for are then an
//           error with file:line (Mitsuba 3's property check).
//   build:  Scene::Build calls plugin.build(desc) -> the runtime Light (render/light.h).
//   bound:  the coordinator's RecordBounds asks plugin.irradiance_bound how much light it can give
//           a surface, to reject records no scene could produce.
// `area` is attached to a shape: Scene::Build makes its Light from the shape's triangles. The
// runtime Light is one tagged struct whose sampling and evaluation LightSampler dispatches on
// LightType in one place (the way pbrt-v4 dispatches its tagged lights: no virtual call on the
// per-sample path).
#pragma once

#include <algorithm>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/math.h"
#include "render/light.h"
#include "render/scene_desc.h"
#include "render/texture.h"

namespace irfarm {

// What an emitter plugin may ask of the XML loader while parsing one <emitter> element.
class EmitterParams {
 public:
  virtual ~EmitterParams() = default;
  virtual absl::StatusOr<float> Float(absl::string_view name, float def) = 0;
  // rgb, spectrum or one number for grey.
  virtual absl::StatusOr<Vec3> Rgb(absl::string_view name, Vec3 def) = 0;
  // A point or vector, if given (float; Point: double, it may be far from the origin).
  virtual absl::StatusOr<std::optional<Vec3>> Vector(absl::string_view name) = 0;
  virtual absl::StatusOr<std::optional<std::array<double, 3>>> Point(absl::string_view name) = 0;
  // A <transform>, as written, if given.
  virtual absl::StatusOr<std::optional<Mat4>> Transform(absl::string_view name) = 0;
  // A file named relative to the scene folder, resolved; it must exist and stay inside the folder.
  virtual absl::StatusOr<std::string> File(absl::string_view name) = 0;
  // m as it goes into the scene: re-centred when the scene is far from the origin
  // (SceneDesc::world_origin). Positions in an EmitterDesc are in that frame.
  virtual Mat4 World(const Mat4& m) const = 0;
  // INVALID_ARGUMENT with file:line of the named parameter (of the element when not given).
  virtual absl::Status Error(absl::string_view name, absl::string_view what) const = 0;
};

struct EmitterPlugin {
  enum class Kind {
    kArea,         // nested in a <shape>; its light is the shape's (radiance only here)
    kLocal,        // a light of its own somewhere in the scene (point, spot, directional)
    kEnvironment,  // light from infinitely far away; at most one per scene, as in Mitsuba
  };
  const char* name;  // the XML type
  Kind kind;
  absl::Status (*parse)(EmitterParams& params, EmitterDesc* desc);
  // kLocal and kEnvironment: the runtime light. `textures` owns what the light reads (an
  // envmap's image) for the scene's lifetime.
  absl::StatusOr<Light> (*build)(const EmitterDesc& desc,
                                 std::vector<std::unique_ptr<Texture>>* textures);
  // An upper bound (W/m^2) on the irradiance the emitter gives any surface at least d_min from
  // it; +infinity when there is none worth having (an envmap's brightest texel is not read here).
  double (*irradiance_bound)(const EmitterDesc& desc, double d_min);
};

// The plugin for an XML type name, or nullptr.
const EmitterPlugin* FindEmitterPlugin(absl::string_view name);
// All registered names, in registry order (for "supported: ..." messages).
std::vector<std::string> EmitterPluginNames();

// A point source's bound: intensity (W/sr) over the squared closest distance.
inline double InverseSquareBound(const Vec3& intensity, double d_min) {
  return std::max(0.0f, MaxComponent(intensity)) / (d_min * d_min);
}

}  // namespace irfarm
