// SceneHash (service/scene_hash.h): what a snapshot's and a seed's scene check rests on. A
// cache made in one scene must not be loaded into another: the hash changes with what records
// depend on (here: an environment map's rotation, the bytes of its image) and not with where the
// scene's folder is (a bundle is unpacked elsewhere) or with the sensor.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "render/scene_loader.h"
#include "service/scene_bundle.h"
#include "service/scene_hash.h"

namespace irfarm {
namespace {

namespace fs = std::filesystem;

// A floor under an environment map rotated `degrees` about y, seen from `eye_z`.
std::string Scene(int degrees, float eye_z = 4) {
  return "<scene version=\"3.0.0\">\n"
         "<sensor type=\"perspective\"><transform name=\"to_world\"><lookat origin=\"0, 1, " +
         std::to_string(eye_z) +
         "\" target=\"0, 0, 0\" up=\"0, 1, 0\"/></transform>\n"
         "<film type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/>"
         "<integer name=\"height\" value=\"8\"/></film></sensor>\n"
         "<shape type=\"rectangle\"><transform name=\"to_world\"><rotate x=\"1\" angle=\"-90\"/>"
         "</transform><bsdf type=\"diffuse\"/></shape>\n"
         "<emitter type=\"envmap\"><string name=\"filename\" value=\"sky.exr\"/>"
         "<transform name=\"to_world\"><rotate y=\"1\" angle=\"" +
         std::to_string(degrees) + "\"/></transform></emitter>\n</scene>\n";
}

uint64_t HashOf(const fs::path& dir, const std::string& xml) {
  std::ofstream(dir / "scene.xml") << xml;
  absl::StatusOr<SceneDesc> desc = LoadSceneFile((dir / "scene.xml").string(), LoadOptions());
  EXPECT_TRUE(desc.ok()) << desc.status();
  return desc.ok() ? SceneHash(*desc) : 0;
}

TEST(SceneHashTest, AnEnvironmentMapsRotationAndImageAreInTheHashItsFolderIsNot) {
  const fs::path a = *MakeTempDir("irfarm-hash-a-"), b = *MakeTempDir("irfarm-hash-b-");
  const fs::path sky = fs::path(IRFARM_TEST_DATA) / "scenes/materials/textures/sky.exr";
  fs::copy_file(sky, a / "sky.exr");
  fs::copy_file(sky, b / "sky.exr");
  const uint64_t base = HashOf(a, Scene(0));
  EXPECT_EQ(HashOf(b, Scene(0)), base) << "the same scene in another folder";
  EXPECT_EQ(HashOf(a, Scene(0, 7)), base) << "only the sensor moved";
  // The sky turned: its sun lights other places (the rotation was not hashed before).
  EXPECT_NE(HashOf(a, Scene(90)), base);
  // Another image under the same name (only its name was hashed before).
  std::ofstream(b / "sky.exr", std::ios::binary | std::ios::app) << "x";
  EXPECT_NE(HashOf(b, Scene(0)), base);
  fs::remove_all(a);
  fs::remove_all(b);
}

// A snapshot made with the photon map or the direct sun off holds other records (with caustics,
// with the sun) than one made with the defaults: its hash differs, so the two are not mixed; the
// defaults keep the scene hash (snapshots made before still load).
TEST(SceneHashTest, RecordSettingsOffTheDefaultsChangeTheCacheHash) {
  const uint64_t scene = 0x0123456789abcdefull;
  EXPECT_EQ(CacheHash(scene, true, true), scene);
  const uint64_t no_caustics = CacheHash(scene, false, true);
  const uint64_t no_sun = CacheHash(scene, true, false);
  const uint64_t neither = CacheHash(scene, false, false);
  EXPECT_NE(no_caustics, scene);
  EXPECT_NE(no_sun, scene);
  EXPECT_NE(neither, scene);
  EXPECT_NE(no_caustics, no_sun);
  EXPECT_NE(no_caustics, neither);
  EXPECT_NE(no_sun, neither);
  EXPECT_NE(CacheHash(scene + 1, false, true), no_caustics);
}

}  // namespace
}  // namespace irfarm
