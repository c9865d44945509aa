// WriteBundle (service/scene_bundle.h): what a client's bundle cannot do to the coordinator's or a
// worker's disk gets INVALID_ARGUMENT naming the client's own path, never the server's folder.
#include "service/scene_bundle.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

namespace irfarm {
namespace {

v1::SceneBundle Bundle(const std::vector<std::string>& paths) {
  v1::SceneBundle b;
  b.set_main_file("scene.xml");
  for (const std::string& p : paths) {
    v1::BundleFile* f = b.add_files();
    f->set_path(p);
    f->set_content("x");
  }
  return b;
}

TEST(SceneBundleTest, ClientMistakesAreInvalidArgumentsThatNameTheClientsPath) {
  absl::StatusOr<std::string> dir = MakeTempDir("irfarm-bundle-test-");
  ASSERT_TRUE(dir.ok());
  // "a" is a file and a folder at once.
  absl::StatusOr<std::string> st = WriteBundle(Bundle({"scene.xml", "a", "a/b"}), *dir);
  EXPECT_EQ(st.status().code(), absl::StatusCode::kInvalidArgument) << st.status();
  EXPECT_NE(st.status().message().find("'a/b'"), std::string::npos) << st.status();
  EXPECT_EQ(st.status().message().find(*dir), std::string::npos) << st.status();
  // A name longer than the file system allows.
  st = WriteBundle(Bundle({"scene.xml", std::string(300, 'n')}), *dir);
  EXPECT_EQ(st.status().code(), absl::StatusCode::kInvalidArgument) << st.status();
  EXPECT_EQ(st.status().message().find(*dir), std::string::npos) << st.status();
  // Too many files: refused before one is written.
  std::vector<std::string> many = {"scene.xml"};
  for (int i = 0; i < kMaxBundleFiles; ++i) many.push_back("f" + std::to_string(i));
  const std::string many_dir = *dir + "/many";
  st = WriteBundle(Bundle(many), many_dir);
  EXPECT_EQ(st.status().code(), absl::StatusCode::kInvalidArgument) << st.status();
  EXPECT_NE(st.status().message().find("over the limit of 16384"), std::string::npos);
  EXPECT_FALSE(std::ifstream(many_dir + "/scene.xml").good());
  // A sound bundle is written.
  st = WriteBundle(Bundle({"scene.xml", "meshes/a.obj"}), *dir + "/ok");
  ASSERT_TRUE(st.ok()) << st.status();
  EXPECT_TRUE(std::ifstream(*dir + "/ok/meshes/a.obj").good());
  RemoveTree(*dir);
}

}  // namespace
}  // namespace irfarm
