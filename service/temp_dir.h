// Private temporary directories of a service process (scene bundles a worker or a coordinator
// writes, results it assembles), named by the process that made them, so that a process started
// later can remove those of one that died without cleaning up (SIGKILL, a crash, power loss).
// The names are PREFIX<pid>-[TAG-]XXXXXX under the temporary directory ($TMPDIR, else /tmp), which
// must be this machine's own: a pid is only meaningful in its pid namespace, and a directory
// shared with another namespace (containers sharing a volume as /tmp) would show its live
// processes' directories as dead ones'.
#pragma once

#include <string>

#include "absl/status/statusor.h"

namespace irfarm {

// A fresh private directory (mkdtemp, mode 0700) named PREFIX<pid>-TAG-XXXXXX (no TAG- when
// `tag` is empty). `tag` must be a valid file-name part (a checked job id).
absl::StatusOr<std::string> MakeTempDir(const std::string& prefix, const std::string& tag = "");

// Removes `dir` and everything under it; errors are ignored (best-effort clean-up).
void RemoveTree(const std::string& dir);

// Removes the directories MakeTempDir(prefix, ...) made in processes that are gone: names
// PREFIX<pid>-... whose pid is not a running process (kill(pid, 0) answers ESRCH; another user's
// live process answers EPERM and is left alone) or is this process's own, that are directories
// (not symlinks) owned by this user. Call it at start, before this process makes any (its own
// pid's are then a dead process's, e.g. an earlier pid 1 of a container). Returns how many it
// removed.
int RemoveStaleTempDirs(const std::string& prefix);

}  // namespace irfarm
