// Texture plugins by their Mitsuba 3 XML name. Each texture is one file in render/textures/ that
// defines a TexturePlugin and one line in registry.cc's list; nothing else names a texture type.
//   parse:  the XML loader finds the plugin by name and calls plugin.parse with a TextureParams
//           reader and the TextureDesc to fill (to_uv, which every texture has, is the loader's);
//           parameters the plugin did not ask for are then an error with file:line.
//   build:  Scene::Build calls plugin.build(desc) (LoadTexture) -> the runtime Texture.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "render/scene_desc.h"
#include "render/texture.h"

namespace irfarm {

// What a texture plugin may ask of the XML loader while parsing one <texture> element.
class TextureParams {
 public:
  virtual ~TextureParams() = default;
  virtual absl::StatusOr<bool> Bool(absl::string_view name, bool def) = 0;
  virtual absl::StatusOr<std::string> String(absl::string_view name, absl::string_view def) = 0;
  virtual absl::StatusOr<Vec3> Rgb(absl::string_view name, Vec3 def) = 0;
  // A file named relative to the scene folder, resolved; it must exist and stay inside the folder.
  virtual absl::StatusOr<std::string> File(absl::string_view name) = 0;
  // INVALID_ARGUMENT with file:line of the named parameter (of the element when not given).
  virtual absl::Status Error(absl::string_view name, absl::string_view what) const = 0;
};

struct TexturePlugin {
  const char* name;  // the XML type
  absl::Status (*parse)(TextureParams& params, TextureDesc* desc);
  absl::StatusOr<std::unique_ptr<Texture>> (*build)(const TextureDesc& desc);
};

// The plugin for an XML type name, or nullptr.
const TexturePlugin* FindTexturePlugin(absl::string_view name);
// All registered names, in registry order (for "supported: ..." messages).
std::vector<std::string> TexturePluginNames();

}  // namespace irfarm
