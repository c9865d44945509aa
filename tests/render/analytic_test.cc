// Scenes with known answers, for the lights and materials the shared scenes do not use. A large
// one-sided diffuse plane (reflectance 0.5) at z = 0 is seen straight down by a narrow camera;
// at its centre the radiance is rho/pi * E for irradiance E:
//   point light, intensity I at height 1:     E = I
//   spot light pointing down, on its axis:    E = I
//   directional light travelling down:        E = irradiance
//   constant sky of radiance L (or an envmap of constant value L): E = pi L (no occluder)
// and a thin dielectric with int_ior = ext_ior is invisible under the sky.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

#include "render/image.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {
namespace {

std::string SceneXml(const std::string& extra) {
  return R"(<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="-1"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="2"/>
    <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="64"/></sampler>
    <film type="hdrfilm"><integer name="width" value="5"/><integer name="height" value="5"/>
      <rfilter type="box"/></film>
  </sensor>
  <bsdf type="diffuse" id="gray"><rgb name="reflectance" value="0.5"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><scale value="100"/></transform>
    <ref id="gray"/>
  </shape>
)" + extra +
         "</scene>\n";
}

// Mean radiance of the image (all pixels see the plane's centre region).
Vec3 RenderMean(const std::string& xml, const std::string& integrator, const std::string& dir) {
  const std::string path = dir + "/scene.xml";
  absl::StatusOr<SceneDesc> desc = LoadSceneString(xml, path, LoadOptions{});
  EXPECT_TRUE(desc.ok()) << desc.status();
  if (!desc.ok()) return Vec3(-1);
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
  EXPECT_TRUE(scene.ok()) << scene.status();
  if (!scene.ok()) return Vec3(-1);
  RenderSettings settings = *SettingsForScene(*desc, integrator);
  settings.spp = 256;
  settings.irrcache.record_rays = 4096;
  const RenderOutput out = Render(**scene, settings);
  Vec3 sum;
  for (const Vec3& p : out.image.pixels) sum += p;
  return sum / float(out.image.pixels.size());
}

void ExpectRadiance(const Vec3& got, float want, float rel_tol, const std::string& what) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want, rel_tol * want) << what << " channel " << c;
}

class AnalyticTest : public ::testing::TestWithParam<std::string> {
 protected:
  std::string dir_ = ::testing::TempDir();
};

TEST_P(AnalyticTest, PointLight) {
  const std::string xml = SceneXml(R"(<emitter type="point">
    <point name="position" value="0, 0, 1"/><rgb name="intensity" value="2"/></emitter>)");
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 0.5f / kPi * 2, 0.01f, "point");
}

TEST_P(AnalyticTest, SpotLightOnItsAxis) {
  const std::string xml = SceneXml(R"(<emitter type="spot">
    <transform name="to_world"><lookat origin="0, 0, 1" target="0, 0, 0" up="0, 1, 0"/></transform>
    <rgb name="intensity" value="3"/><float name="cutoff_angle" value="30"/>
    <float name="beam_width" value="20"/></emitter>)");
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 0.5f / kPi * 3, 0.01f, "spot");
}

TEST_P(AnalyticTest, DirectionalLight) {
  const std::string xml = SceneXml(R"(<emitter type="directional">
    <vector name="direction" value="0, 0, -1"/><rgb name="irradiance" value="1.5"/></emitter>)");
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 0.5f / kPi * 1.5f, 0.01f, "directional");
}

TEST_P(AnalyticTest, ConstantSky) {
  const std::string xml =
      SceneXml(R"(<emitter type="constant"><rgb name="radiance" value="0.8"/></emitter>)");
  // E = pi * 0.8 over the open hemisphere, so L = 0.5 * 0.8; the stratified estimate is noisy.
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 0.4f, 0.02f, "constant");
}

TEST_P(AnalyticTest, ConstantEnvmap) {
  Image env(16, 8);
  for (Vec3& p : env.pixels) p = Vec3(0.8f);
  ASSERT_TRUE(WriteExr(env, dir_ + "/env.exr").ok());
  const std::string xml =
      SceneXml(R"(<emitter type="envmap"><string name="filename" value="env.exr"/></emitter>)");
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 0.4f, 0.02f, "envmap");
}

TEST_P(AnalyticTest, IndexMatchedThinDielectricIsInvisible) {
  const std::string xml = SceneXml(R"(
  <bsdf type="thindielectric" id="sheet"><float name="int_ior" value="1"/>
    <float name="ext_ior" value="1"/></bsdf>
  <shape type="rectangle"><transform name="to_world"><translate z="1.5"/></transform>
    <ref id="sheet"/></shape>
  <emitter type="constant"><rgb name="radiance" value="0.8"/></emitter>)");
  // Shadow rays stop at glass (as in Mitsuba), so the sky reaches the plane through the sheet
  // only along sampled directions: the same 0.4 as without the sheet.
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 0.4f, 0.02f, "thindielectric");
}

INSTANTIATE_TEST_SUITE_P(Integrators, AnalyticTest, ::testing::Values("path", "irrcache"));

}  // namespace
}  // namespace irfarm
