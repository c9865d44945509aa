#include "service/temp_dir.h"

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <vector>

namespace irfarm {
namespace fs = std::filesystem;

absl::StatusOr<std::string> MakeTempDir(const std::string& prefix, const std::string& tag) {
  std::error_code ec;
  const fs::path tmp = fs::temp_directory_path(ec);
  if (ec) return absl::InternalError("no temporary directory: " + ec.message());
  const std::string name =
      prefix + std::to_string(getpid()) + "-" + (tag.empty() ? "" : tag + "-") + "XXXXXX";
  std::string templ = (tmp / name).string();
  std::vector<char> buf(templ.begin(), templ.end());
  buf.push_back('\0');
  if (mkdtemp(buf.data()) == nullptr) return absl::InternalError("mkdtemp failed for " + templ);
  return std::string(buf.data());
}

void RemoveTree(const std::string& dir) {
  std::error_code ec;
  fs::remove_all(dir, ec);
}

int RemoveStaleTempDirs(const std::string& prefix) {
  std::error_code ec;
  const fs::path tmp = fs::temp_directory_path(ec);
  if (ec) return 0;
  fs::directory_iterator it(tmp, ec);
  if (ec) return 0;
  std::vector<fs::path> stale;
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) break;
    const std::string name = it->path().filename().string();
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    // PREFIX<pid>-...: at most 10 digits, then '-'.
    size_t i = prefix.size();
    long long pid = 0;
    while (i < name.size() && i - prefix.size() < 10 && name[i] >= '0' && name[i] <= '9')
      pid = pid * 10 + (name[i++] - '0');
    if (i == prefix.size() || i >= name.size() || name[i] != '-') continue;
    // This process's own pid counts as gone: called at start, before it made any, a folder
    // with its pid is a dead process's whose pid it was given again (a container's pid 1).
    if (pid <= 0 || pid > 0x7fffffff) continue;
    if (pid != getpid() && (kill(pid_t(pid), 0) == 0 || errno != ESRCH)) continue;
    struct stat st;
    if (lstat(it->path().c_str(), &st) != 0 || !S_ISDIR(st.st_mode) || st.st_uid != geteuid())
      continue;
    stale.push_back(it->path());
  }
  for (const fs::path& p : stale) RemoveTree(p.string());
  return int(stale.size());
}

}  // namespace irfarm
