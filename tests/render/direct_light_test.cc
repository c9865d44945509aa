// The irradiance-cache integrator's direct light against known answers:
//  - a diffuse plane under one large rectangular lamp, nothing occluded: the analytic estimator
//    renders it without noise at 1 spp (the reference is brute-force integration over the lamp,
//    independent of Lambert's formula);
//  - with an occluder casting a penumbra, the ratio estimator agrees with the plain Monte Carlo
//    estimator within the plain estimator's own noise (measured here with two seeds).
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "render/image.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/scene_loader.h"
#include "render_test_util.h"

namespace irfarm {
namespace {

// Plane z = 0 (reflectance 0.5, 200 x 200), lamp 4 x 4 at z = 1 facing down (radiance 2), the
// camera between them looking straight down (or across the plane); `extra` adds shapes.
constexpr const char* kLookDown =
    R"(<lookat origin="0.3, -0.2, 0.8" target="0.3, -0.2, 0" up="0, 1, 0"/>)";
constexpr const char* kLookAcross =
    R"(<lookat origin="0, -2.5, 0.8" target="0, 0, 0" up="0, 0, 1"/>)";

std::string PlaneUnderLampXml(int width, int height, const std::string& extra,
                              const std::string& lookat = kLookDown) {
  return R"(<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="-1"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <transform name="to_world">)" +
         lookat + R"(</transform>
    <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
    <film type="hdrfilm"><integer name="width" value=")" +
         std::to_string(width) + R"("/><integer name="height" value=")" + std::to_string(height) +
         R"("/>
      <rfilter type="box"/></film>
  </sensor>
  <bsdf type="diffuse" id="gray"><rgb name="reflectance" value="0.5"/></bsdf>
  <bsdf type="diffuse" id="black"><rgb name="reflectance" value="0"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><scale value="100"/></transform>
    <ref id="gray"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="180"/><scale value="2"/>
      <translate z="1"/></transform>
    <ref id="black"/>
    <emitter type="area"><rgb name="radiance" value="2"/></emitter>
  </shape>
)" + extra +
         "</scene>\n";
}

struct Built {
  SceneDesc desc;
  std::unique_ptr<Scene> scene;
};

Built Build(const std::string& xml) {
  Built b;
  absl::StatusOr<SceneDesc> desc = LoadSceneString(xml, ::testing::TempDir() + "/s.xml", {});
  EXPECT_TRUE(desc.ok()) << desc.status();
  b.desc = *desc;
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(b.desc);
  EXPECT_TRUE(scene.ok()) << scene.status();
  b.scene = std::move(*scene);
  return b;
}

// The image mean of `integrator` at `spp` (seeds 1 and 2 averaged; `adjust` changes the
// settings first) and the variance of that mean, from the two seeds' per-pixel differences.
std::pair<double, double> MeanAndVariance(
    const Built& b, const char* integrator, int spp,
    const std::function<void(RenderSettings&)>& adjust = nullptr) {
  RenderSettings s = *SettingsForScene(b.desc, integrator);
  s.spp = spp;
  s.firefly_filter = false;  // MeanOfTwo takes the pixels as independent
  if (adjust) adjust(s);
  s.seed = 1;
  const Image a = Render(*b.scene, s).image;
  s.seed = 2;
  const Image c = Render(*b.scene, s).image;
  const ImageMean m = MeanOfTwo(a, c);
  return {m.mean, m.std_err * m.std_err};
}

TEST(DirectLightTest, UnoccludedLampIsNoiseFreeAtOneSpp) {
  constexpr int kW = 128, kH = 96;
  // A second lamp above the first faces up, away from everything: it must cost nothing (no
  // sample, no shadow ray; counted as skipped).
  const Built b = Build(PlaneUnderLampXml(kW, kH, R"(<shape type="rectangle">
    <transform name="to_world"><translate z="1.2"/></transform>
    <ref id="black"/>
    <emitter type="area"><rgb name="radiance" value="5"/></emitter>
  </shape>)"));
  RenderSettings s = *SettingsForScene(b.desc, "irrcache");
  s.spp = 1;
  s.seed = 3;
  const RenderOutput out = Render(*b.scene, s);

  // Reference: at each pixel centre's point on the plane, irradiance by the midpoint rule over
  // the lamp (256 x 256 cells; the lamp is at least 1 away, so the rule's error is ~1e-5),
  // radiance 0.5/pi * E. The 1-spp render samples elsewhere in the pixel: over a pixel's
  // footprint (0.007) the irradiance changes by under 0.1%, i.e. relMSE ~1e-8.
  const Camera& cam = b.scene->camera();
  Image ref(kW, kH);
  constexpr int N = 256;
  const float cell = 4.0f / N;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const Vec3 d = cam.Direction(x + 0.5f, y + 0.5f);
      if (d.z >= 0) continue;
      const Vec3 p = cam.origin() + d * (-cam.origin().z / d.z);
      if (std::abs(p.x) > 100 || std::abs(p.y) > 100) continue;
      double e = 0;
      for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) {
          const Vec3 q(-2 + (i + 0.5f) * cell, -2 + (j + 0.5f) * cell, 1);
          const Vec3 v = q - p;
          const double d2 = LengthSquared(v);
          e += double(v.z) * v.z / (d2 * d2) * cell * cell;  // cos_p cos_l / d^2 dA
        }
      ref.at(x, y) = Vec3(float(2 * e * 0.5 / kPi));
    }
  const ImageError c = CompareImages(out.image, ref);
  EXPECT_LT(c.relmse, 1e-5);
  EXPECT_EQ(out.stats.counters.nonfinite_samples, 0u);
  EXPECT_GT(out.stats.counters.lights_skipped, uint64_t(kW) * kH / 2);
  // The estimator is not trivially exact: the plain Monte Carlo estimator at 1 spp is far off.
  s.irrcache.analytic_direct = false;
  const RenderOutput plain = Render(*b.scene, s);
  EXPECT_GT(CompareImages(plain.image, ref).relmse, 100 * c.relmse);
}

// A reflectance texture with a NaN texel (an EXR can hold one): the samples it poisons are
// counted and left out, and no pixel of the image is NaN. The analytic direct light is kept
// apart from the sample's radiance (DirectTerms), so it needs its own check: before it had one,
// the pixels over the texel were NaN while the counter said their samples were dropped.
TEST(DirectLightTest, NanTexelIsCountedAndKeptOutOfTheImage) {
  Image tex(2, 2);
  tex.at(0, 0) = tex.at(1, 0) = tex.at(0, 1) = Vec3(0.5f);
  tex.at(1, 1) = Vec3(std::nanf(""));
  const std::string path = ::testing::TempDir() + "/nan-texel.exr";
  ASSERT_TRUE(WriteExr(tex, path).ok());
  std::string xml = PlaneUnderLampXml(32, 24, "");
  const std::string gray = R"(<rgb name="reflectance" value="0.5"/></bsdf>)";
  xml.replace(xml.find(gray), gray.size(),
              R"(<texture type="bitmap" name="reflectance"><string name="filename" value=")" +
                  std::string("nan-texel.exr") + R"("/></texture></bsdf>)");
  const Built b = Build(xml);
  RenderSettings s = *SettingsForScene(b.desc, "irrcache");
  s.spp = 4;
  s.seed = 3;
  const RenderOutput out = Render(*b.scene, s);
  int nonfinite = 0;
  for (const Vec3& v : out.image.pixels) nonfinite += !IsFinite(v);
  std::printf("MEASURED non-finite samples %llu, non-finite pixels %d\n",
              static_cast<unsigned long long>(out.stats.counters.nonfinite_samples), nonfinite);
  EXPECT_EQ(nonfinite, 0);
  EXPECT_GT(out.stats.counters.nonfinite_samples, 0u);
}

TEST(DirectLightTest, RatioEstimatorAgreesWithPlainEstimatorInPenumbrae) {
  // A box between lamp and plane casts a soft shadow. Direct light only (max_depth 2), so the
  // two estimators differ in nothing but how the rectangle's samples are combined.
  const std::string box = R"(<shape type="cube">
    <transform name="to_world"><scale x="0.3" y="0.3" z="0.1"/><translate z="0.5"/></transform>
    <ref id="gray"/></shape>)";
  const Built b = Build(PlaneUnderLampXml(48, 36, box, kLookAcross));
  RenderSettings s = *SettingsForScene(b.desc, "irrcache");
  s.spp = 64;
  s.irrcache.path.max_depth = 2;
  s.seed = 1;
  const RenderOutput ratio = Render(*b.scene, s);
  s.irrcache.analytic_direct = false;
  const RenderOutput plain1 = Render(*b.scene, s);
  s.seed = 2;
  const RenderOutput plain2 = Render(*b.scene, s);
  // The plain estimator's error against itself (two seeds) is twice its error against the
  // truth, so diff = err(ratio) + err(plain) < noise = 2 err(plain) says the ratio estimator
  // (biased by O(1/spp) in penumbrae only) is at least as close to the truth as the plain one.
  const double noise = CompareImages(plain1.image, plain2.image).relmse;
  const double diff = CompareImages(ratio.image, plain2.image).relmse;
  EXPECT_GT(noise, 0);
  EXPECT_LT(diff, noise);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(ratio.stats.mean_rgb[c], plain2.stats.mean_rgb[c], 0.01 * plain2.stats.mean_rgb[c]);
}

// A coated plane (roughplastic, white base, GGX 0.05: the coating lets in less light at grazing
// angles than on average) under the lamp, direct light only: irrcache's diffuse vertex must
// weigh the light by the BSDF's own diffuse lobe, not by its albedo as a Lambertian lobe (that
// made this plane 2.7% dark; the glossy lobe is path traced the same way in both). Held to the
// path tracer's image mean (path agrees with Mitsuba on the material scenes, golden tests)
// within 5 standard errors of the difference, each render's from its two seeds' pixels.
TEST(DirectLightTest, CoatedPlaneMatchesPathTracer) {
  std::string xml = PlaneUnderLampXml(64, 48, "");
  const std::string gray = "<ref id=\"gray\"/>";
  xml.replace(xml.find(gray), gray.size(), "<ref id=\"coat\"/>");
  const std::string first_shape = "  <shape";
  xml.insert(xml.find(first_shape), R"(  <bsdf type="roughplastic" id="coat">
    <string name="distribution" value="ggx"/><float name="alpha" value="0.05"/>
    <float name="int_ior" value="1.46"/><rgb name="diffuse_reflectance" value="1"/>
  </bsdf>
)");
  const Built b = Build(xml);
  const auto max_depth_2 = [](RenderSettings& s) { s.irrcache.path.max_depth = 2; };
  const auto [path, path_var] = MeanAndVariance(b, "path", 64, max_depth_2);
  const auto [irr, irr_var] = MeanAndVariance(b, "irrcache", 16, max_depth_2);
  const double se = std::sqrt(path_var + irr_var);
  std::printf("MEASURED path %.5f irrcache %.5f (se %.2e)\n", path, irr, se);
  EXPECT_GT(se, 0);
  EXPECT_NEAR(irr, path, 5 * se);
}

// A floor seen in a rough mirror, lit by a lamp whose zenith part a small shelf hides: its
// direct light at that later vertex (no per-pixel sums there) is the plain estimate, not one
// sample's shadowed / unshadowed ratio times the analytic term, which weighs the lamp's visible
// part by solid angle instead of by cosine and does not converge (max_depth 3: direct light only,
// so nothing else differs from path). The ratio came out 0.59% bright (12 standard errors);
// irrcache's mean must be within 4 standard errors of path's (+0.09% now).
TEST(DirectLightTest, ShadowedLampSeenInARoughMirrorMatchesPathTracer) {
  const Built b = Build(R"(<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="3"/></integrator>
  <sensor type="perspective"><float name="fov" value="8"/>
    <transform name="to_world"><lookat origin="0,0,0.4" target="1,0,0.2" up="0,0,1"/></transform>
    <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/>
      <rfilter type="box"/></film></sensor>
  <shape type="rectangle"><transform name="to_world"><scale value="2"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate y="1" angle="-90"/><translate x="1" z="0.5"/></transform>
    <bsdf type="roughconductor"><float name="alpha" value="0.02"/></bsdf></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.15"/><translate z="0.5"/>
    </transform><bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0"/>
    </bsdf></bsdf></shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="180"/><translate z="1"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
    <emitter type="area"><rgb name="radiance" value="5"/></emitter></shape>
</scene>
)");
  const auto [path, path_var] = MeanAndVariance(b, "path", 256);
  const auto [irr, irr_var] = MeanAndVariance(b, "irrcache", 256);
  const double se = std::sqrt(path_var + irr_var);
  std::printf("MEASURED path %.5f irrcache %.5f (%+.2f%%, se %.2e)\n", path, irr,
              100 * (irr / path - 1), se);
  EXPECT_GT(se, 0);
  EXPECT_NEAR(irr, path, 4 * se);
}

}  // namespace
}  // namespace irfarm
