// The list of BSDF plugins (see registry.h). Adding a BSDF: write render/bsdfs/<name>.cc
// defining `const BsdfPlugin k<Name>Bsdf`, and add one X(k<Name>Bsdf) line below.
#include "render/bsdfs/registry.h"

#include "render/plugin_registry.h"

namespace irfarm {

#define IRFARM_BSDF_PLUGINS(X) \
  X(kDiffuseBsdf)              \
  X(kConductorBsdf)            \
  X(kDielectricBsdf)           \
  X(kThinDielectricBsdf)       \
  X(kTwoSidedBsdf)             \
  X(kRoughConductorBsdf)       \
  X(kPlasticBsdf)              \
  X(kRoughPlasticBsdf)         \
  X(kMaskBsdf)                 \
  X(kRoughDielectricBsdf)      \
  X(kPrincipledBsdf)           \
  X(kPrincipledThinBsdf)       \
  X(kNormalMapBsdf)            \
  X(kBumpMapBsdf)              \
  X(kBlendBsdf)                \
  X(kNullBsdf)

#define IRFARM_DECLARE_PLUGIN(p) extern const BsdfPlugin p;
IRFARM_BSDF_PLUGINS(IRFARM_DECLARE_PLUGIN)
#undef IRFARM_DECLARE_PLUGIN

namespace {
#define IRFARM_LIST_PLUGIN(p) &p,
const BsdfPlugin* const kPlugins[] = {IRFARM_BSDF_PLUGINS(IRFARM_LIST_PLUGIN)};
#undef IRFARM_LIST_PLUGIN
}  // namespace

const BsdfPlugin* FindBsdfPlugin(absl::string_view name) {
  return FindPluginByName(kPlugins, name);
}

std::vector<std::string> BsdfPluginNames() { return PluginNamesOf(kPlugins); }

}  // namespace irfarm
