// Temporary folders of service processes (service/temp_dir.h): named by the process that made
// them, and removed at a later start only where that process is gone (or had this process's
// pid), only folders, only ours.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "service/temp_dir.h"

namespace irfarm {
namespace {
namespace fs = std::filesystem;

// A pid that was a process and has exited (a child, reaped).
pid_t DeadPid() {
  const pid_t child = fork();
  if (child == 0) _exit(0);
  int status = 0;
  waitpid(child, &status, 0);
  return child;
}

// Points TMPDIR at a fresh folder for the test, and back afterwards.
class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* old = std::getenv("TMPDIR");
    had_ = old != nullptr;
    if (had_) old_ = old;
    root_ = fs::temp_directory_path() / ("irfarm-temp-dir-test-" + std::to_string(getpid()));
    fs::create_directories(root_);
    setenv("TMPDIR", root_.c_str(), 1);
  }
  void TearDown() override {
    if (had_)
      setenv("TMPDIR", old_.c_str(), 1);
    else
      unsetenv("TMPDIR");
    fs::remove_all(root_);
  }
  fs::path root_;
  bool had_ = false;
  std::string old_;
};

TEST_F(TempDirTest, NamesCarryThePidAndTheTagAndArePrivate) {
  const absl::StatusOr<std::string> dir = MakeTempDir("irfarm-test-", "job-7");
  ASSERT_TRUE(dir.ok()) << dir.status();
  const std::string name = fs::path(*dir).filename().string();
  EXPECT_EQ(name.rfind("irfarm-test-" + std::to_string(getpid()) + "-job-7-", 0), 0u) << name;
  EXPECT_EQ(fs::path(*dir).parent_path(), root_);
  struct stat st;
  ASSERT_EQ(stat(dir->c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0700u);
  const absl::StatusOr<std::string> plain = MakeTempDir("irfarm-test-");
  ASSERT_TRUE(plain.ok());
  EXPECT_EQ(fs::path(*plain).filename().string().size(),
            std::string("irfarm-test-" + std::to_string(getpid()) + "-XXXXXX").size());
}

TEST_F(TempDirTest, OnlyFoldersOfProcessesThatAreGoneAreRemoved) {
  const pid_t dead = DeadPid();
  ASSERT_GT(dead, 0);
  const std::string d = std::to_string(dead);
  // A dead worker's bundle, with a file in it.
  fs::create_directories(root_ / ("irfarm-worker-" + d + "-job-1-abcdef") / "meshes");
  std::ofstream(root_ / ("irfarm-worker-" + d + "-job-1-abcdef") / "scene.xml") << "<scene/>";
  // A live process's (this test's parent) and pid 1's (alive, maybe another user's): kept.
  const std::string parent = std::to_string(getppid());
  fs::create_directories(root_ / ("irfarm-worker-" + parent + "-job-2-abcdef"));
  fs::create_directories(root_ / "irfarm-worker-1-job-3-abcdef");
  // This process's own: called at start, a folder with its pid is a dead process's.
  const absl::StatusOr<std::string> own = MakeTempDir("irfarm-worker-", "job-5");
  ASSERT_TRUE(own.ok());
  // Under the dead pid but not a folder we made: a symlink (to a folder that must survive) and
  // a plain file.
  fs::create_directories(root_ / "precious");
  std::ofstream(root_ / "precious" / "keep") << "x";
  fs::create_directory_symlink(root_ / "precious", root_ / ("irfarm-worker-" + d + "-link-abc"));
  std::ofstream(root_ / ("irfarm-worker-" + d + "-file")) << "x";
  // Names that only look alike: no pid, another prefix, digits without the '-'.
  fs::create_directories(root_ / "irfarm-worker-job-4-abcdef");
  fs::create_directories(root_ / ("irfarm-submit-" + d + "-abcdef"));
  fs::create_directories(root_ / ("irfarm-worker-" + d));

  EXPECT_EQ(RemoveStaleTempDirs("irfarm-worker-"), 2);
  EXPECT_FALSE(fs::exists(root_ / ("irfarm-worker-" + d + "-job-1-abcdef")));
  EXPECT_FALSE(fs::exists(*own));
  EXPECT_TRUE(fs::exists(root_ / ("irfarm-worker-" + parent + "-job-2-abcdef")));
  EXPECT_TRUE(fs::exists(root_ / "irfarm-worker-1-job-3-abcdef"));
  EXPECT_TRUE(fs::is_symlink(root_ / ("irfarm-worker-" + d + "-link-abc")));
  EXPECT_TRUE(fs::exists(root_ / "precious" / "keep"));
  EXPECT_TRUE(fs::exists(root_ / ("irfarm-worker-" + d + "-file")));
  EXPECT_TRUE(fs::exists(root_ / "irfarm-worker-job-4-abcdef"));
  EXPECT_TRUE(fs::exists(root_ / ("irfarm-submit-" + d + "-abcdef")));
  EXPECT_TRUE(fs::exists(root_ / ("irfarm-worker-" + d)));
  // The coordinator's prefix finds its own.
  EXPECT_EQ(RemoveStaleTempDirs("irfarm-submit-"), 1);
  EXPECT_FALSE(fs::exists(root_ / ("irfarm-submit-" + d + "-abcdef")));
  EXPECT_EQ(RemoveStaleTempDirs("irfarm-worker-"), 0);
}

}  // namespace
}  // namespace irfarm
