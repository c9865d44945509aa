// Scenes with known answers, for the lights and materials the shared scenes do not use. A large
// one-sided diffuse plane (reflectance 0.5) at z = 0 is seen straight down by a narrow camera;
// at its centre the radiance is rho/pi * E for irradiance E:
//   point light, intensity I at height 1:     E = I
//   spot light pointing down, on its axis:    E = I
//   directional light travelling down:        E = irradiance
//   constant sky of radiance L (or an envmap of constant value L): E = pi L (no occluder)
// and a thin dielectric with int_ior = ext_ior is invisible under the sky; under a pane of glass
// the sky arrives through it, a sun does not (as in Mitsuba).
#include <gtest/gtest.h>
#include <stb_image_write.h>

#include <algorithm>
#include <cmath>
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

// Mean radiance of the image (all pixels see the plane's centre region); cache_levels > 0 sets
// irrcache's cache levels (else the pilot chooses).
Vec3 RenderMean(const std::string& xml, const std::string& integrator, const std::string& dir,
                int cache_levels = 0) {
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
  if (cache_levels > 0) {
    settings.irrcache.cache_levels = cache_levels;
    settings.irrcache.choose_cache_levels = false;
  }
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

// beam_width 0 (Mitsuba accepts it; its Blender exporter writes it for a spot blend of 1): the
// falloff is linear in angle from the axis to the cutoff, (30 - 15) / 30 = 0.5 at 15 degrees off
// the axis, where the plane is lit (irradiance 3 at distance 1, straight down). It was refused.
TEST_P(AnalyticTest, SpotLightWithoutABeamFallsOffFromItsAxis) {
  const std::string xml = SceneXml(R"(<emitter type="spot">
    <transform name="to_world"><lookat origin="0, 0, 1" target="0.267949, 0, 0" up="0, 1, 0"/>
    </transform><rgb name="intensity" value="3"/><float name="cutoff_angle" value="30"/>
    <float name="beam_width" value="0"/></emitter>)");
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 0.5f / kPi * 3 * 0.5f, 0.02f, "spot, no beam");
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

// The same sky as a Radiance RGBE file (.hdr): linear radiance, not an 8-bit image (which would
// be cut at 1 and tone-mapped: 2.4 must stay 2.4).
TEST_P(AnalyticTest, ConstantEnvmapFromRadianceHdr) {
  std::vector<float> rgb(16 * 8 * 3, 2.4f);
  ASSERT_TRUE(stbi_write_hdr((dir_ + "/env.hdr").c_str(), 16, 8, 3, rgb.data()));
  const std::string xml =
      SceneXml(R"(<emitter type="envmap"><string name="filename" value="env.hdr"/></emitter>)");
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 1.2f, 0.02f, "envmap .hdr");
}

TEST_P(AnalyticTest, IndexMatchedThinDielectricIsInvisible) {
  const std::string xml = SceneXml(R"(
  <bsdf type="thindielectric" id="sheet"><float name="int_ior" value="1"/>
    <float name="ext_ior" value="1"/></bsdf>
  <shape type="rectangle"><transform name="to_world"><translate z="1.5"/></transform>
    <ref id="sheet"/></shape>
  <emitter type="constant"><rgb name="radiance" value="0.8"/></emitter>)");
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), 0.4f, 0.02f, "thindielectric");
}

// A thin pane of glass (relative index 1.5), written out from the Fresnel equations: its
// reflectance with the interreflections inside it, 2 F / (1 + F), at |cos| = mu; and the
// cosine-weighted hemispherical average of its transmittance, 2 int T(mu) mu dmu.
double PaneReflectance(double mu) {
  const double eta = 1.5, sin2_t = (1 - mu * mu) / (eta * eta), ct = std::sqrt(1 - sin2_t);
  const double rs = (mu - eta * ct) / (mu + eta * ct), rp = (eta * mu - ct) / (eta * mu + ct);
  const double f = 0.5 * (rs * rs + rp * rp);
  return 2 * f / (1 + f);
}
double PaneHemisphericalTransmittance() {
  const int n = 100000;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double mu = (i + 0.5) / n;
    sum += (1 - PaneReflectance(mu)) * mu;
  }
  return 2 * sum / n;
}

// The plane (reflectance rho = 0.5) under a pane at z = 1.5 that covers it, seen through the
// pane at normal incidence. Light reaches the plane through the pane; the plane's own light comes
// back off the pane's underside (rho_p = 1 - tau of it on average), so its radiance is
// B = rho / pi * E_through / (1 - rho rho_p). A lamp or sky behind a pane is reached by shadow
// rays through it (a thin pane's transmission leaves the direction unchanged): no path needs to
// find it by chance.
constexpr char kPane[] = R"(
  <bsdf type="thindielectric" id="pane"><float name="int_ior" value="1.5"/>
    <float name="ext_ior" value="1"/></bsdf>
  <shape type="rectangle"><transform name="to_world"><scale value="100"/>%s<translate z="1.5"/>
    </transform><ref id="pane"/></shape>
)";
std::string Pane(const std::string& turn) {
  char buf[512];
  std::snprintf(buf, sizeof(buf), kPane, turn.c_str());
  return buf;
}

// A constant sky through the pane: the camera sees the sky in the pane (R(1) L) and the plane
// through it, B = rho L tau / (1 - rho rho_p). The pane is turned over, so the sky's light
// enters it from its back: a thin pane is the same from both sides (no total internal
// reflection beyond 42 degrees, which one interface seen from the glass side would have).
TEST_P(AnalyticTest, SkyThroughAThinPane) {
  const std::string xml = SceneXml(Pane(R"(<rotate x="1" angle="180"/>)") +
                                   R"(<emitter type="constant"><rgb name="radiance" value="0.8"/>
    </emitter>)");
  const double rho = 0.5, tau = PaneHemisphericalTransmittance();
  const double b = rho * 0.8 * tau / (1 - rho * (1 - tau));
  ExpectRadiance(RenderMean(xml, GetParam(), dir_),
                 float(PaneReflectance(1) * 0.8 + (1 - PaneReflectance(1)) * b), 0.02f,
                 "sky through a pane");
}

// A lamp behind the pane: a large emitting plane (radiance 0.8, facing down) at z = 2.5 above the
// pane, the camera at z = 1 under it, looking down at the plane, which sees the lamp through the
// pane as it saw the sky above: B = rho L tau / (1 - rho rho_p). With two cache levels as well:
// a record ray through the pane that meets the lamp finds the record point's direct light, which
// the record must leave out (counted twice before).
TEST_P(AnalyticTest, LampThroughAThinPane) {
  std::string xml = SceneXml(Pane("") + R"(<shape type="rectangle">
    <transform name="to_world"><scale value="100"/><rotate x="1" angle="180"/>
      <translate z="2.5"/></transform>
    <emitter type="area"><rgb name="radiance" value="0.8"/></emitter></shape>)");
  xml.replace(xml.find("origin=\"0, 0, 3\""), 16, "origin=\"0, 0, 1\"");
  const double rho = 0.5, tau = PaneHemisphericalTransmittance();
  const float want = float(rho * 0.8 * tau / (1 - rho * (1 - tau)));
  ExpectRadiance(RenderMean(xml, GetParam(), dir_), want, 0.02f, "lamp through a pane");
  if (GetParam() == "irrcache")
    ExpectRadiance(RenderMean(xml, GetParam(), dir_, 2), want, 0.02f, "two cache levels");
}

// A delta light behind the pane lights nothing through it: no path can reach such a light, and
// shadow rays towards it stop at the pane, as Mitsuba 3's do (its path tracer renders this scene
// black: 3.9.1, scalar_rgb, 256 spp).
TEST_P(AnalyticTest, SunBehindAThinPaneLightsNothingAsInMitsuba) {
  const std::string xml = SceneXml(Pane("") + R"(<emitter type="directional">
    <vector name="direction" value="0.6, 0, -0.8"/><rgb name="irradiance" value="1.5"/></emitter>)");
  const Vec3 got = RenderMean(xml, GetParam(), dir_);
  for (int c = 0; c < 3; ++c) EXPECT_LT(got[c], 1e-4f) << "channel " << c;
}

INSTANTIATE_TEST_SUITE_P(Integrators, AnalyticTest, ::testing::Values("path", "irrcache"));

// Normal mapping on the plane (its dp/du is +x), lit by a directional light, path traced:
// radiance rho/pi E cos(n', L) T with n' the mapped normal and T Mitsuba's shadow-terminator
// term 2 / (1 + sqrt(1 + a^2 tan^2 theta_L)), a^2 = min(1, tan^2(tilt) / 8). A flat map
// (0.5, 0.5, 1) renders the same image as no map.
std::string NormalMapXml(const std::string& bsdf, float light_deg) {
  const float b = light_deg * kPi / 180;
  return R"(<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="-1"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="2"/>
    <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
    <film type="hdrfilm"><integer name="width" value="5"/><integer name="height" value="5"/>
      <rfilter type="box"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="100"/></transform>
    )" + bsdf +
         R"(
  </shape>
  <emitter type="directional"><vector name="direction" value=")" +
         std::to_string(-std::sin(b)) + ", 0, " + std::to_string(-std::cos(b)) +
         R"("/><rgb name="irradiance" value="1.5"/></emitter>
</scene>
)";
}

Image RenderXml(const std::string& xml, const std::string& dir) {
  absl::StatusOr<SceneDesc> desc = LoadSceneString(xml, dir + "/scene.xml", LoadOptions{});
  EXPECT_TRUE(desc.ok()) << desc.status();
  if (!desc.ok()) return Image();
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
  EXPECT_TRUE(scene.ok()) << scene.status();
  if (!scene.ok()) return Image();
  RenderSettings settings = *SettingsForScene(*desc, "path");
  settings.seed = 5;
  return Render(**scene, settings).image;
}

std::string MappedGray(Vec3 n) {
  const Vec3 c = (Normalize(n) + Vec3(1.0f)) * 0.5f;
  return "<bsdf type=\"normalmap\"><rgb name=\"normalmap\" value=\"" + std::to_string(c.x) + ", " +
         std::to_string(c.y) + ", " + std::to_string(c.z) +
         "\"/><bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.5\"/></bsdf></bsdf>";
}

TEST(NormalMapTest, FlatMapRendersLikeNoMap) {
  const std::string dir = ::testing::TempDir();
  const std::string gray = R"(<bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>)";
  const Image plain = RenderXml(NormalMapXml(gray, 30), dir);
  const Image flat = RenderXml(NormalMapXml(MappedGray(Vec3(0, 0, 1)), 30), dir);
  ASSERT_EQ(plain.pixels.size(), flat.pixels.size());
  ASSERT_GT(plain.pixels[0].x, 0.1f);  // rho/pi E cos 30 = 0.21
  for (size_t i = 0; i < plain.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(flat.pixels[i][c], plain.pixels[i][c], 1e-5f * plain.pixels[i][c]) << i;
}

TEST(NormalMapTest, TiltedMapShadesByTheMappedNormal) {
  const std::string dir = ::testing::TempDir();
  const float alpha = 40 * kPi / 180, beta = 30 * kPi / 180;
  const float a2 = std::min(1.0f, std::tan(alpha) * std::tan(alpha) / 8);
  const float t = 2 / (1 + std::sqrt(1 + a2 * std::tan(beta) * std::tan(beta)));
  struct Case {
    Vec3 n;        // tangent-space normal
    float cos_nl;  // cosine between the mapped normal and the light
    float light;   // light angle from the normal, degrees, towards +x
  };
  const Case cases[] = {
      {Vec3(std::sin(alpha), 0, std::cos(alpha)), std::cos(alpha - beta), 30},   // towards it
      {Vec3(-std::sin(alpha), 0, std::cos(alpha)), std::cos(alpha + beta), 30},  // away
      {Vec3(0, std::sin(alpha), std::cos(alpha)), std::cos(alpha) * std::cos(beta), 30},
  };
  for (const Case& c : cases) {
    const Image img = RenderXml(NormalMapXml(MappedGray(c.n), c.light), dir);
    Vec3 mean;
    for (const Vec3& p : img.pixels) mean += p;
    mean = mean / float(img.pixels.size());
    const float want = 0.5f / kPi * 1.5f * c.cos_nl * t;
    for (int ch = 0; ch < 3; ++ch)
      EXPECT_NEAR(mean[ch], want, 1e-3f * want) << "n=(" << c.n.x << ", " << c.n.y << ")";
  }
}

// Bump mapping with a height ramp h = 16 u (an EXR of texels 0..15, so dh/du = 16 inside it):
// the plane (dp/du = 200 x, dp/dv = 200 y) tilts to the normal (-scale 16, 0, 200), i.e. by
// atan(scale 16 / 200) away from +x; the same radiance as the equal normal map.
TEST(NormalMapTest, BumpRampTiltsLikeItsNormal) {
  const std::string dir = ::testing::TempDir();
  Image ramp(16, 4);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 16; ++x) ramp.pixels[size_t(y * 16 + x)] = Vec3(float(x));
  ASSERT_TRUE(WriteExr(ramp, dir + "/ramp.exr").ok());
  const float alpha = 40 * kPi / 180, beta = 30 * kPi / 180;
  const float scale = 200 * std::tan(alpha) / 16;
  const std::string bump =
      R"(<bsdf type="bumpmap"><texture type="bitmap"><string name="filename" value="ramp.exr"/>
      </texture><float name="scale" value=")" +
      std::to_string(scale) +
      R"("/><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf>)";
  const Image img = RenderXml(NormalMapXml(bump, 30), dir);
  Vec3 mean;
  for (const Vec3& p : img.pixels) mean += p;
  mean = mean / float(img.pixels.size());
  const float a2 = std::min(1.0f, std::tan(alpha) * std::tan(alpha) / 8);
  const float t = 2 / (1 + std::sqrt(1 + a2 * std::tan(beta) * std::tan(beta)));
  const float want = 0.5f / kPi * 1.5f * std::cos(alpha + beta) * t;
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(mean[ch], want, 2e-3f * want);
}

// Anisotropic roughness follows the surface's u direction (the shading frame's s is dp/du, as
// in Mitsuba): turning the plane and the light together by 90 degrees about the normal gives
// the same radiance, and light arriving across the rough direction (v) reflects more towards
// the camera than light arriving along the smooth one (u). (A 0.1 degree view: across a wider
// one the pixels see the narrow lobe from directions that the turn does not map onto each
// other; at 2 degrees that alone differs by 0.3%.)
float AnisotropicPlaneRadiance(float plane_deg, float light_azimuth_deg) {
  const float b = 30 * kPi / 180, phi = light_azimuth_deg * kPi / 180;
  const std::string xml = R"(<scene version="3.0.0">
  <integrator type="path"/>
  <sensor type="perspective">
    <float name="fov" value="0.1"/>
    <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="hdrfilm"><integer name="width" value="5"/><integer name="height" value="5"/>
      <rfilter type="box"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="100"/><rotate z="1" angle=")" +
                          std::to_string(plane_deg) + R"("/></transform>
    <bsdf type="roughconductor"><string name="distribution" value="ggx"/>
      <float name="alpha_u" value="0.05"/><float name="alpha_v" value="0.5"/></bsdf>
  </shape>
  <emitter type="directional"><vector name="direction" value=")" +
                          std::to_string(-std::sin(b) * std::cos(phi)) + ", " +
                          std::to_string(-std::sin(b) * std::sin(phi)) + ", " +
                          std::to_string(-std::cos(b)) +
                          R"("/><rgb name="irradiance" value="1"/></emitter>
</scene>
)";
  const Image img = RenderXml(xml, ::testing::TempDir());
  float sum = 0;
  for (const Vec3& p : img.pixels) sum += p.y;
  return sum / float(std::max<size_t>(1, img.pixels.size()));
}

TEST(AnisotropyTest, RoughnessFollowsTheTextureU) {
  const float along_u = AnisotropicPlaneRadiance(0, 0), across = AnisotropicPlaneRadiance(0, 90);
  const float turned_u = AnisotropicPlaneRadiance(90, 90);
  const float turned_across = AnisotropicPlaneRadiance(90, 180);
  EXPECT_GT(across, 2 * along_u);
  EXPECT_NEAR(turned_u, along_u, 1e-3f * along_u);
  EXPECT_NEAR(turned_across, across, 1e-3f * across);
}

}  // namespace
}  // namespace irfarm
