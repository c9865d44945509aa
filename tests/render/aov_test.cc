// AOVs (render/aov.h): the layers round-trip through OpenEXR's own reader under the names OpenEXR
// tools show; direct + indirect is the image for both integrators; albedo and normal describe the
// first diffuse surface; the variance layer predicts the spread between independent renders.
#include <gtest/gtest.h>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <set>

#include "render/aov.h"
#include "render/bsdfs/bsdf.h"
#include "render/sampling.h"
#include "render_test_util.h"

namespace irfarm {
namespace {

RenderOutput RenderAovs(const LoadedScene& s, const std::string& integrator, int spp, uint64_t seed,
                        bool aovs = true) {
  RenderSettings settings = *SettingsForScene(s.desc, integrator);
  settings.spp = spp;
  settings.seed = seed;
  settings.aovs = aovs;
  return Render(*s.scene, settings);
}

// direct + indirect reproduces the image to float rounding: each sample's radiance is their sum.
void ExpectDirectPlusIndirectIsImage(const RenderOutput& out) {
  ASSERT_FALSE(out.aovs.empty());
  double direct_sum = 0, indirect_sum = 0;
  for (size_t i = 0; i < out.image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const float img = out.image.pixels[i][c];
      const float d = out.aovs.direct.pixels[i][c], ind = out.aovs.indirect.pixels[i][c];
      // Per-sample sums are rounded once per sample and once per pixel mean: a few ulps of the
      // larger of the parts (the sum of 64 samples carries ~64 roundings of 6e-8 each).
      const float tol = 1e-5f * std::max({std::abs(img), std::abs(d), std::abs(ind)}) + 1e-12f;
      ASSERT_NEAR(d + ind, img, tol) << "pixel " << i << " channel " << c;
      ASSERT_LE(out.aovs.emission.pixels[i][c], d + tol) << "emission is part of direct";
      direct_sum += d;
      indirect_sum += ind;
    }
  // Both parts carry light (cornell-box is lit by its lamp and by interreflection).
  EXPECT_GT(direct_sum, 0);
  EXPECT_GT(indirect_sum, 0.1 * direct_sum);
}

TEST(AovTest, DirectPlusIndirectIsTheImageForBothIntegrators) {
  const LoadedScene s = LoadQuarter("cornell-box");
  ExpectDirectPlusIndirectIsImage(RenderAovs(s, "path", 16, 3));
  ExpectDirectPlusIndirectIsImage(RenderAovs(s, "irrcache", 16, 3));
  const LoadedScene spec = LoadQuarter("specular");
  ExpectDirectPlusIndirectIsImage(RenderAovs(spec, "path", 8, 3));
  ExpectDirectPlusIndirectIsImage(RenderAovs(spec, "irrcache", 8, 3));
}

TEST(AovTest, AccumulatingAovsDoesNotChangeThePathImage) {
  const LoadedScene s = LoadQuarter("cornell-box");
  const RenderOutput with = RenderAovs(s, "path", 8, 11, true);
  const RenderOutput without = RenderAovs(s, "path", 8, 11, false);
  EXPECT_TRUE(without.aovs.empty());
  for (size_t i = 0; i < with.image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(with.image.pixels[i][c], without.image.pixels[i][c]);
}

TEST(AovTest, AlbedoAndNormalDescribeTheFirstDiffuseSurface) {
  const LoadedScene s = LoadQuarter("cornell-box");
  const RenderOutput out = RenderAovs(s, "irrcache", 16, 5);
  // The scene's white reflectance (scene.xml), seen on the back wall, ceiling, floor and boxes.
  const Vec3 white(0.885809f, 0.698859f, 0.666422f);
  int white_pixels = 0, unit_normals = 0, covered = 0;
  for (size_t i = 0; i < out.image.pixels.size(); ++i) {
    const Vec3 a = out.aovs.albedo.pixels[i], n = out.aovs.normal.pixels[i];
    if (MaxAbsComponent(a - white) < 1e-5f) ++white_pixels;
    if (MaxComponent(a) > 0) {
      ++covered;
      if (std::abs(Length(n) - 1) < 1e-4f) ++unit_normals;
      EXPECT_GT(out.aovs.depth.pixels[i].x, 0);
    }
  }
  const int n = int(out.image.pixels.size());
  EXPECT_GT(white_pixels, n / 4);
  // Pixels inside one flat surface have a unit normal; edge pixels average two.
  EXPECT_GT(unit_normals, covered * 8 / 10);
}

TEST(AovTest, AlbedoSeenThroughAMirrorIsTintedByIt) {
  // specular: a 0.9 mirror. Pixels seeing it have albedo 0.9 x a diffuse reflectance, so some
  // albedo is not any of the scene's diffuse reflectances but 0.9 times one.
  const LoadedScene s = LoadQuarter("specular");
  const RenderOutput out = RenderAovs(s, "path", 4, 5);
  std::set<std::tuple<float, float, float>> distinct;
  for (const Vec3& a : out.aovs.albedo.pixels)
    if (MaxComponent(a) > 0) distinct.insert({a.x, a.y, a.z});
  std::vector<Vec3> seen;
  for (const auto& [r, g, b] : distinct) seen.push_back(Vec3(r, g, b));
  int tinted = 0;
  for (const Vec3& a : seen)
    for (const Vec3& d : seen)
      if (MaxAbsComponent(a - d * 0.9f) < 1e-6f) {
        ++tinted;
        break;
      }
  EXPECT_GT(tinted, 0);
}

// A rough metal seen head-on under a uniform sky: there is no diffuse surface anywhere, so an
// albedo made of diffuse albedos alone would be 0 (it was, before 2026-12-06). irrcache's albedo
// AOV is the metal's directional albedo, int f(wo, wi) cos(theta_i) dwi, here taken by
// quadrature of the BSDF's Eval (the AOV estimates it from glossy samples' weights: Sample and
// Pdf). `path` keeps the diffuse albedos (docs/guide/denoising.md, "The albedo of glossy
// surfaces").
TEST(AovTest, AlbedoOfARoughMetalIsItsDirectionalAlbedo) {
  const std::string xml = R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="2"/>
    <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
      <rfilter type="box"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="10"/></transform>
    <bsdf type="roughconductor"><string name="distribution" value="ggx"/>
      <float name="alpha" value="0.4"/><rgb name="specular_reflectance" value="0.9, 0.6, 0.3"/>
    </bsdf>
  </shape>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
</scene>
)";
  const LoadedScene s = BuildLoaded(LoadSceneString(xml, ::testing::TempDir() + "/metal.xml", {}));
  ASSERT_NE(s.scene, nullptr);
  SurfaceHit hit;
  ASSERT_TRUE(s.scene->Intersect(Ray{Vec3(0, 0, 3), Vec3(0, 0, -1), INFINITY}, &hit));
  const Bsdf& metal = s.scene->material(hit.material);
  const Vec3 wo(0, 0, 1);
  Vec3 expected;
  // Midpoints of kTheta x kPhi cells of equal projected solid angle (pi / cells each): Eval is
  // f cos, so each cell adds Eval / cos times pi / cells.
  constexpr int kTheta = 400, kPhi = 64;
  for (int i = 0; i < kTheta; ++i)
    for (int j = 0; j < kPhi; ++j) {
      const Vec3 wi = StratifiedCosineHemisphere(i, j, kTheta, kPhi, 0.5f, 0.5f);
      expected += metal.Eval(hit.Context(), wo, wi) * (kPi / float(kTheta * kPhi) / wi.z);
    }
  ASSERT_GT(expected.x, 0.5f);  // a bright metal: the AOV had 0 here
  for (const char* integrator : {"irrcache"}) {
    const RenderOutput out = RenderAovs(s, integrator, 64, 7);
    ASSERT_FALSE(out.aovs.empty());
    Vec3 mean;
    for (const Vec3& a : out.aovs.albedo.pixels) mean += a;
    mean = mean / float(out.aovs.albedo.pixels.size());
    // 64 x 64 samples of a weight whose spread is about its mean: 1% standard error; 4%.
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(mean[c], expected[c], 0.04f * expected[c]) << integrator << " channel " << c;
  }
}

TEST(AovTest, VarianceLayerPredictsTheSpreadBetweenIndependentRenders) {
  // Two independent renders a, b: E[(a - b)^2] = var(a) + var(b), and the variance layer
  // estimates var per pixel. Pixels that see an emitter are left out: their samples are
  // stratified over the pixel, and on the lamp's edge that makes the true variance far smaller
  // than the sample variance (measured: predicted 5.7x the spread with them, 1.04-1.06x without).
  const LoadedScene s = LoadQuarter("cornell-box");
  for (uint64_t seed : {100, 300}) {
    const RenderOutput a = RenderAovs(s, "path", 16, seed), b = RenderAovs(s, "path", 16, seed + 1);
    double diff2 = 0, predicted = 0;
    for (size_t i = 0; i < a.image.pixels.size(); ++i) {
      if (MaxComponent(a.aovs.emission.pixels[i]) > 0 ||
          MaxComponent(b.aovs.emission.pixels[i]) > 0)
        continue;
      for (int c = 0; c < 3; ++c) {
        const double d = a.image.pixels[i][c] - b.image.pixels[i][c];
        diff2 += d * d;
        predicted += a.aovs.variance.pixels[i][c] + b.aovs.variance.pixels[i][c];
      }
    }
    std::printf("seed %d: measured sum (a-b)^2 %.4g, predicted %.4g, ratio %.3f\n", int(seed),
                diff2, predicted, diff2 / predicted);
    EXPECT_GT(diff2 / predicted, 0.75);
    EXPECT_LT(diff2 / predicted, 1.33);
  }
}

TEST(AovTest, LayersRoundTripThroughOpenExrsReader) {
  const LoadedScene s = LoadQuarter("cornell-box");
  const RenderOutput out = RenderAovs(s, "irrcache", 4, 9);
  const std::string path = ::testing::TempDir() + "/aov_test_" + std::to_string(getpid()) + ".exr";
  ASSERT_TRUE(WriteExr(out.image, path, out.aovs.Layers()).ok());

  Imf::InputFile file(path.c_str());
  std::set<std::string> names;
  for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
    names.insert(it.name());
    EXPECT_EQ(it.channel().type, Imf::FLOAT) << it.name();
  }
  const std::set<std::string> expected = {
      "R",          "G",          "B",          "albedo.R",  "albedo.G",   "albedo.B",
      "normal.X",   "normal.Y",   "normal.Z",   "depth.Z",   "emission.R", "emission.G",
      "emission.B", "direct.R",   "direct.G",   "direct.B",  "indirect.R", "indirect.G",
      "indirect.B", "variance.R", "variance.G", "variance.B"};
  EXPECT_EQ(names, expected);
  // OpenEXR's layer API groups them as layers.
  std::set<std::string> layers;
  file.header().channels().layers(layers);
  EXPECT_EQ(layers, (std::set<std::string>{"albedo", "normal", "depth", "emission", "direct",
                                           "indirect", "variance"}));

  // Every value read back by OpenEXR itself equals what was written.
  const int w = out.image.width, h = out.image.height;
  for (const ExrLayer& layer : out.aovs.Layers())
    for (size_t c = 0; c < layer.channels.size(); ++c) {
      std::vector<float> values(size_t(w) * h);
      Imf::FrameBuffer fb;
      const std::string name = layer.name + "." + layer.channels[c];
      fb.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(values.data()), sizeof(float),
                                 sizeof(float) * w));
      file.setFrameBuffer(fb);
      file.readPixels(0, h - 1);
      for (size_t i = 0; i < values.size(); ++i)
        ASSERT_EQ(values[i], layer.image->pixels[i][int(c)]) << name << " pixel " << i;
    }
  // And our own reader gives the same images back.
  absl::StatusOr<AovImages> back = AovImages::Read(path);
  ASSERT_TRUE(back.ok()) << back.status();
  for (size_t i = 0; i < out.image.pixels.size(); ++i) {
    ASSERT_EQ(back->indirect.pixels[i].y, out.aovs.indirect.pixels[i].y);
    ASSERT_EQ(back->depth.pixels[i].x, out.aovs.depth.pixels[i].x);
  }
  absl::StatusOr<Image> rgb = ReadExr(path);
  ASSERT_TRUE(rgb.ok());
  EXPECT_EQ(rgb->pixels[100].x, out.image.pixels[100].x);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace irfarm
