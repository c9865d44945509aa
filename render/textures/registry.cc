// The list of texture plugins (see registry.h). Adding a texture: write
// render/textures/<name>.cc defining `const TexturePlugin k<Name>Texture`, and add one
// X(k<Name>Texture) line below.
#include "render/textures/registry.h"

#include "render/plugin_registry.h"

#include "absl/strings/str_cat.h"

namespace irfarm {

#define IRFARM_TEXTURE_PLUGINS(X) \
  X(kBitmapTexture)               \
  X(kCheckerboardTexture)

#define IRFARM_DECLARE_PLUGIN(p) extern const TexturePlugin p;
IRFARM_TEXTURE_PLUGINS(IRFARM_DECLARE_PLUGIN)
#undef IRFARM_DECLARE_PLUGIN

namespace {
#define IRFARM_LIST_PLUGIN(p) &p,
const TexturePlugin* const kPlugins[] = {IRFARM_TEXTURE_PLUGINS(IRFARM_LIST_PLUGIN)};
#undef IRFARM_LIST_PLUGIN
}  // namespace

const TexturePlugin* FindTexturePlugin(absl::string_view name) {
  return FindPluginByName(kPlugins, name);
}

std::vector<std::string> TexturePluginNames() { return PluginNamesOf(kPlugins); }

absl::StatusOr<std::unique_ptr<Texture>> LoadTexture(const TextureDesc& desc) {
  const TexturePlugin* plugin = FindTexturePlugin(desc.type);
  if (plugin == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat(desc.loc.ToString(), ": unknown texture type '", desc.type, "'"));
  }
  return plugin->build(desc);
}

}  // namespace irfarm
