// BSDF plugins by their Mitsuba 3 XML name. Each BSDF is one file in render/bsdfs/ that defines
// a BsdfPlugin (its parse and build functions) and one line in registry.cc's list; nothing else
// in the renderer names a BSDF type. The path of a <bsdf type="..."> element:
//   parse:  the XML loader finds the plugin by name and calls plugin.parse with a BsdfParams
//           reader; each getter reads one parameter (or its default), marks it read and records
//           the value in the BsdfDesc under the same name. Parameters the plugin did not ask for
//           are then an error with file:line (Mitsuba 3's property check).
//   build:  Scene::Build calls plugin.build(desc) -> the runtime Bsdf.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "render/bsdfs/bsdf.h"
#include "render/scene_desc.h"
#include "render/texture.h"

namespace irfarm {

// What a BSDF plugin may ask of the XML loader while parsing one <bsdf> element.
class BsdfParams {
 public:
  virtual ~BsdfParams() = default;
  virtual absl::StatusOr<float> Float(absl::string_view name, float def) = 0;
  virtual absl::StatusOr<bool> Bool(absl::string_view name, bool def) = 0;
  virtual absl::StatusOr<std::string> String(absl::string_view name, absl::string_view def) = 0;
  // rgb (or one number for grey); no texture.
  virtual absl::StatusOr<Vec3> Rgb(absl::string_view name, Vec3 def) = 0;
  // rgb, one number, or a bitmap texture (nested or <ref>).
  virtual absl::StatusOr<ColorParam> Color(absl::string_view name, Vec3 def) = 0;
  // A number or one of Mitsuba's named indices of refraction ("bk7", "air", ...).
  virtual absl::StatusOr<float> Ior(absl::string_view name, float def) = 0;
  // Whether the element gives the parameter (does not mark it read).
  virtual bool Has(absl::string_view name) const = 0;
  // The nested <bsdf> children (inline, parsed and added to the scene first, or <ref>), as
  // indices into SceneDesc::bsdfs; every index is lower than the one being parsed.
  virtual absl::StatusOr<std::vector<int>> NestedBsdfs() = 0;
  virtual const BsdfDesc& Nested(int index) const = 0;
  // The nested <texture> children not read as named parameters (bumpmap's height map).
  virtual absl::StatusOr<std::vector<ColorParam>> NestedTextures() = 0;
  // An error with file:line of the named parameter (of the element when it is not given).
  virtual absl::Status Error(absl::string_view name, absl::string_view what) const = 0;
  // The description being filled (for values a plugin derives itself, e.g. named materials).
  virtual BsdfDesc& desc() = 0;
};

struct BsdfBuildContext {
  const std::vector<std::unique_ptr<Texture>>* textures = nullptr;  // SceneDesc::textures, built
  const std::vector<std::unique_ptr<Bsdf>>* bsdfs = nullptr;        // built so far
  TexturedColor Color(const ColorParam& c) const {
    TexturedColor t;
    t.value = c.value;
    if (c.texture >= 0) t.texture = (*textures)[size_t(c.texture)].get();
    return t;
  }
  const Bsdf* Nested(int index) const { return (*bsdfs)[size_t(index)].get(); }
};

struct BsdfPlugin {
  const char* name;  // the XML type
  absl::Status (*parse)(BsdfParams& params);
  std::unique_ptr<Bsdf> (*build)(const BsdfDesc& desc, const BsdfBuildContext& ctx);
};

// The plugin for an XML type name, or nullptr.
const BsdfPlugin* FindBsdfPlugin(absl::string_view name);
// All registered names, in registry order (for "supported: ..." messages).
std::vector<std::string> BsdfPluginNames();

}  // namespace irfarm
