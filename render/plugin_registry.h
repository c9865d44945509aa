// What the plugin registries (render/bsdfs, shapes, emitters, textures: registry.cc) share: a
// fixed list of plugins, each a struct whose `name` is its Mitsuba XML type, looked up by name.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "absl/strings/string_view.h"

namespace irfarm {

// The plugin in `plugins` named `name`, or nullptr.
template <typename Plugin, size_t N>
const Plugin* FindPluginByName(const Plugin* const (&plugins)[N], absl::string_view name) {
  for (const Plugin* p : plugins)
    if (name == p->name) return p;
  return nullptr;
}

// The names of `plugins`, in their order (for "supported: ..." messages).
template <typename Plugin, size_t N>
std::vector<std::string> PluginNamesOf(const Plugin* const (&plugins)[N]) {
  std::vector<std::string> names;
  names.reserve(N);
  for (const Plugin* p : plugins) names.emplace_back(p->name);
  return names;
}

}  // namespace irfarm
