// Scene bundles: a scene.xml and the files it references, uploaded with a job. Builds a bundle
// from a scene file on disk (the client side), checks every path stays inside the bundle, and
// writes a bundle into a folder (coordinator and worker side) so the scene loader can read it.
#pragma once

#include <cstddef>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "irfarm/v1/common.pb.h"
#include "service/temp_dir.h"

namespace irfarm {

// OK when `path` is a relative path inside the bundle: not empty, not absolute, no "..", "." or
// empty components, no backslash or NUL. INVALID_ARGUMENT naming the path otherwise.
absl::Status CheckBundlePath(const std::string& path);

// Total bytes of the bundle's file contents.
size_t BundleBytes(const v1::SceneBundle& bundle);

// The scene file plus every file it names (<string name="filename" value="..."/>, <include
// filename="..."/>, and what included files name, found where the scene loader finds them),
// relative to its folder. Errors: the scene or a referenced file cannot be read (NOT_FOUND), or a
// referenced file lies outside the scene's folder (INVALID_ARGUMENT).
absl::StatusOr<v1::SceneBundle> MakeBundle(const std::string& scene_path);

// Checks every path, then writes the files under `dir` (created if needed). Returns the path of
// the main scene file. INVALID_ARGUMENT, naming the bundle's path (never `dir`), for a bad path,
// a missing main file, more than kMaxBundleFiles files, or a file that cannot be written where
// the client put it (a path that is a file and a folder at once, a name too long).
inline constexpr int kMaxBundleFiles = 16384;
absl::StatusOr<std::string> WriteBundle(const v1::SceneBundle& bundle, const std::string& dir);

}  // namespace irfarm
