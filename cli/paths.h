// File names the `irfarm` command derives from the ones it is given.
#pragma once

#include <string>

namespace irfarm {

// Where `path`'s extension starts (its last '.' after the last '/'), or npos when it has none
// ("renders.d/img" has none).
inline size_t ExtensionStart(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash))
    return std::string::npos;
  return dot;
}

// `path` without its extension.
inline std::string StripExtension(const std::string& path) {
  return path.substr(0, ExtensionStart(path));
}

// `path` with "-i" before its extension: out.exr -> out-2.exr, frames/img -> frames/img-2.
inline std::string NumberedPath(const std::string& path, size_t i) {
  const size_t dot = ExtensionStart(path);
  const std::string n = "-" + std::to_string(i);
  return dot == std::string::npos ? path + n : path.substr(0, dot) + n + path.substr(dot);
}

}  // namespace irfarm
