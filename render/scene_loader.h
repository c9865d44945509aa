// Loads a scene written in irfarm's subset of the Mitsuba 3 XML format (docs/scene-format.md)
// into a SceneDesc: parse -> describe, nothing is built here. Parsing is strict, as in Mitsuba:
// an unknown plugin type, an unknown parameter, an unknown $name or <ref> id, a duplicate id, a
// malformed or non-finite number, a spectrum, a file outside the scene folder or a bad mesh index
// are errors. Every error is one line "PATH:LINE: what is wrong" (LINE is 0 when the problem is
// the scene file as a whole, e.g. it cannot be opened): INVALID_ARGUMENT for a bad scene,
// NOT_FOUND for a missing scene, mesh or texture file. Things that are tolerated (an unsupported
// sampler type, degenerate triangles) are reported in SceneDesc::warnings.
#pragma once

#include <map>
#include <string>

#include "absl/status/statusor.h"
#include "render/scene_desc.h"

namespace irfarm {

struct LoadOptions {
  // -D name=value: overrides the scene's <default name="name" value="..."/>, or defines a
  // parameter the scene has no default for (used if some attribute says $name).
  std::map<std::string, std::string> defines;
};

// How deep <include>s may nest (Mitsuba's ParserConfig::max_include_depth): the loader refuses
// deeper ones, and service/scene_bundle.cc follows them as far.
inline constexpr int kMaxIncludeDepth = 15;

// Reads and parses the scene file at `path`. File names inside it are relative to its folder.
absl::StatusOr<SceneDesc> LoadSceneFile(const std::string& path, const LoadOptions& options);

// Parses `xml` as if it were the file `path` (used for PATH:LINE in errors and as the base
// folder of relative file names).
absl::StatusOr<SceneDesc> LoadSceneString(const std::string& xml, const std::string& path,
                                          const LoadOptions& options);

}  // namespace irfarm
