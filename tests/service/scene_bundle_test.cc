// Scene bundles (service/scene_bundle.h): what a client's bundle cannot do to the coordinator's or
// a worker's disk gets INVALID_ARGUMENT naming the client's own path, never the server's folder;
// MakeBundle takes every file the scene loader will read.
#include "service/scene_bundle.h"

#include <gtest/gtest.h>

#include "render/scene_loader.h"

#include <algorithm>
#include <filesystem>
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

// A scene with <include>s travels whole: the included files (an include found next to the file
// that names it, as the loader finds it) and what they name are in the bundle, and the written
// bundle loads.
TEST(SceneBundleTest, IncludedFilesAndWhatTheyNameAreBundled) {
  absl::StatusOr<std::string> dir = MakeTempDir("irfarm-bundle-include-");
  ASSERT_TRUE(dir.ok());
  std::filesystem::create_directories(*dir + "/src/parts");
  const auto write = [&](const std::string& path, const std::string& text) {
    std::ofstream(*dir + "/src/" + path, std::ios::binary) << text;
  };
  write("parts/room.xml", R"(<scene version="3.0.0">
  <shape type="obj"><string name="filename" value="parts/tri.obj"/>
    <include filename="paint.xml"/></shape>
</scene>
)");
  write("parts/paint.xml", "<bsdf type=\"diffuse\" version=\"3.0.0\"/>\n");
  write("parts/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write("scene.xml", R"(<scene version="3.0.0">
  <include filename="parts/room.xml"/>
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/>
    <integer name="height" value="4"/></film></sensor>
</scene>
)");
  absl::StatusOr<v1::SceneBundle> bundle = MakeBundle(*dir + "/src/scene.xml");
  ASSERT_TRUE(bundle.ok()) << bundle.status();
  std::vector<std::string> paths;
  for (const v1::BundleFile& f : bundle->files()) paths.push_back(f.path());
  std::sort(paths.begin(), paths.end());
  EXPECT_EQ(paths, (std::vector<std::string>{"parts/paint.xml", "parts/room.xml", "parts/tri.obj",
                                             "scene.xml"}));
  absl::StatusOr<std::string> main = WriteBundle(*bundle, *dir + "/dst");
  ASSERT_TRUE(main.ok()) << main.status();
  absl::StatusOr<SceneDesc> scene = LoadSceneFile(*main, {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->shapes.size(), 1u);
  EXPECT_EQ(scene->shapes[0].mesh.positions.size(), 3u);
  RemoveTree(*dir);
}

}  // namespace
}  // namespace irfarm
