// The list of emitter plugins (see registry.h). Adding an emitter: write
// render/emitters/<name>.cc defining `const EmitterPlugin k<Name>Emitter`, and add one
// X(k<Name>Emitter) line below (and its sampling to LightSampler if it is a new kind of light).
#include "render/emitters/registry.h"

#include "render/plugin_registry.h"

namespace irfarm {

#define IRFARM_EMITTER_PLUGINS(X) \
  X(kAreaEmitter)                 \
  X(kPointEmitter)                \
  X(kSpotEmitter)                 \
  X(kDirectionalEmitter)          \
  X(kConstantEmitter)             \
  X(kEnvmapEmitter)

#define IRFARM_DECLARE_PLUGIN(p) extern const EmitterPlugin p;
IRFARM_EMITTER_PLUGINS(IRFARM_DECLARE_PLUGIN)
#undef IRFARM_DECLARE_PLUGIN

namespace {
#define IRFARM_LIST_PLUGIN(p) &p,
const EmitterPlugin* const kPlugins[] = {IRFARM_EMITTER_PLUGINS(IRFARM_LIST_PLUGIN)};
#undef IRFARM_LIST_PLUGIN
}  // namespace

const EmitterPlugin* FindEmitterPlugin(absl::string_view name) {
  return FindPluginByName(kPlugins, name);
}

std::vector<std::string> EmitterPluginNames() { return PluginNamesOf(kPlugins); }

}  // namespace irfarm
