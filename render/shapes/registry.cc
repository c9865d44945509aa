// The list of shape plugins (see registry.h). Adding a shape: write render/shapes/<name>.cc
// defining `const ShapePlugin k<Name>Shape`, and add one X(k<Name>Shape) line below.
#include "render/shapes/registry.h"

#include "render/plugin_registry.h"

namespace irfarm {

#define IRFARM_SHAPE_PLUGINS(X) \
  X(kObjShape)                  \
  X(kPlyShape)                  \
  X(kSerializedShape)           \
  X(kRectangleShape)            \
  X(kCubeShape)                 \
  X(kSphereShape)               \
  X(kDiskShape)                 \
  X(kCylinderShape)

#define IRFARM_DECLARE_PLUGIN(p) extern const ShapePlugin p;
IRFARM_SHAPE_PLUGINS(IRFARM_DECLARE_PLUGIN)
#undef IRFARM_DECLARE_PLUGIN

namespace {
#define IRFARM_LIST_PLUGIN(p) &p,
const ShapePlugin* const kPlugins[] = {IRFARM_SHAPE_PLUGINS(IRFARM_LIST_PLUGIN)};
#undef IRFARM_LIST_PLUGIN
}  // namespace

const ShapePlugin* FindShapePlugin(absl::string_view name) {
  return FindPluginByName(kPlugins, name);
}

std::vector<std::string> ShapePluginNames() { return PluginNamesOf(kPlugins); }

}  // namespace irfarm
