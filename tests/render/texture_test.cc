// Textures against Mitsuba 3.9.1's own values (scalar_rgb; the texture plugins evaluated at the
// same (u, v) with the same to_uv from Python): checkerboard and bitmap through to_uv.
#include "render/texture.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "render/bsdfs/bsdf.h"
#include "render/image.h"
#include "render/light.h"
#include "render/scene.h"
#include "render/scene_loader.h"
#include "render/textures/bitmap.h"

namespace irfarm {
namespace {

void ExpectColor(const Vec3& got, const Vec3& want, float tol, const std::string& what) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], tol) << what << " channel " << c;
}

// to_uv = translate(x 0.1) * scale(2, 3): (u, v) -> (2u + 0.1, 3v).
TEST(TextureTest, CheckerboardMatchesMitsuba) {
  const auto desc = LoadSceneString(R"(<scene version="3.0.0">
  <sensor type="perspective"/>
  <bsdf type="diffuse" id="d">
    <texture type="checkerboard" name="reflectance">
      <rgb name="color0" value="1, 0, 0"/>
      <rgb name="color1" value="0, 0, 1"/>
      <transform name="to_uv"><scale x="2" y="3"/><translate x="0.1"/></transform>
    </texture>
  </bsdf>
</scene>)",
                                    "s.xml", {});
  ASSERT_TRUE(desc.ok()) << desc.status();
  ASSERT_EQ(desc->textures.size(), 1u);
  const absl::StatusOr<std::unique_ptr<Texture>> t = LoadTexture(desc->textures[0]);
  ASSERT_TRUE(t.ok()) << t.status();
  const Vec3 red(1, 0, 0), blue(0, 0, 1);
  ExpectColor((*t)->Eval(0.1f, 0.1f), red, 0, "(0.1, 0.1)");
  ExpectColor((*t)->Eval(0.3f, 0.1f), blue, 0, "(0.3, 0.1)");
  ExpectColor((*t)->Eval(0.1f, 0.3f), blue, 0, "(0.1, 0.3)");
  ExpectColor((*t)->Eval(0.3f, 0.3f), red, 0, "(0.3, 0.3)");
  ExpectColor((*t)->Eval(0.05f, 0.05f), red, 0, "(0.05, 0.05)");
  ExpectColor((*t)->Eval(0.2f, 0.05f), red, 0, "(0.2, 0.05)");
  ExpectColor((*t)->Average(), Vec3(0.5f, 0, 0.5f), 1e-6f, "mean");
  float du = 1, dv = 1;
  (*t)->Gradient(0.1f, 0.1f, &du, &dv);
  EXPECT_EQ(du, 0);
  EXPECT_EQ(dv, 0);
}

// A 2 x 2 linear image [[(.1 .2 .3) (.7 .8 .9)] [(.4 .4 .4) (1 .5 0)]] (row 0 on top) through
// to_uv = translate(x 0.25) * rotate(z, 90) * scale(2, 1): (u, v) -> (0.25 - v, 2u).
TEST(TextureTest, BitmapToUvMatchesMitsuba) {
  const std::string dir = ::testing::TempDir() + "/texture_test";
  Image image(2, 2);
  image.at(0, 0) = Vec3(0.1f, 0.2f, 0.3f);
  image.at(1, 0) = Vec3(0.7f, 0.8f, 0.9f);
  image.at(0, 1) = Vec3(0.4f, 0.4f, 0.4f);
  image.at(1, 1) = Vec3(1, 0.5f, 0);
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(WriteExr(image, dir + "/t.exr").ok());
  struct Case {
    float u, v;
    Vec3 nearest, bilinear;
  };
  const Case cases[] = {{0.1f, 0.2f, Vec3(0.1f, 0.2f, 0.3f), Vec3(0.37f, 0.44f, 0.51f)},
                        {0.3f, 0.6f, Vec3(1, 0.5f, 0), Vec3(0.79f, 0.54f, 0.29f)},
                        {0.45f, 0.9f, Vec3(0.4f, 0.4f, 0.4f), Vec3(0.43f, 0.39f, 0.35f)}};
  for (const std::string filter : {"nearest", "bilinear"}) {
    TextureDesc desc;
    desc.filename = dir + "/t.exr";
    desc.filter_type = filter;
    const auto scene = LoadSceneString(
        "<scene version=\"3.0.0\"><sensor type=\"perspective\"/><texture type=\"bitmap\" "
        "id=\"t\"><string name=\"filename\" "
        "value=\"t.exr\"/><transform name=\"to_uv\"><scale x=\"2\" y=\"1\"/><rotate z=\"1\" "
        "angle=\"90\"/><translate x=\"0.25\"/></transform></texture></scene>",
        dir + "/s.xml", {});
    ASSERT_TRUE(scene.ok()) << scene.status();
    desc.to_uv = scene->textures.at(0).to_uv;
    const absl::StatusOr<std::unique_ptr<Texture>> t = LoadTexture(desc);
    ASSERT_TRUE(t.ok()) << t.status();
    for (const Case& c : cases) {
      ExpectColor((*t)->Eval(c.u, c.v), filter == "nearest" ? c.nearest : c.bilinear, 1e-5f,
                  filter + " (" + std::to_string(c.u) + ", " + std::to_string(c.v) + ")");
    }
  }
}

// A scalar parameter (alpha, opacity, weight) read from a texture, as Mitsuba's eval_1: a colour
// bitmap gives its luminance, a checkerboard of rgb colours their channel mean. Expected values
// are mitsuba 3.9.1's own (scalar_rgb, eval_1): a green texel 0.71516, an orange (1, 0.5, 0) one
// 0.57025, a green/red checkerboard 1/3 (the mean gave 1/3 and 0.5 for the texels).
TEST(TextureTest, ScalarsFromTexturesMatchMitsuba) {
  const std::string dir = ::testing::TempDir() + "/texture_scalar_test";
  std::filesystem::create_directories(dir);
  Image image(2, 2);
  for (Vec3& p : image.pixels) p = Vec3(0, 1, 0);
  image.at(0, 0) = Vec3(1, 0.5f, 0);
  ASSERT_TRUE(WriteExr(image, dir + "/g.exr").ok());
  TextureDesc desc;
  desc.filename = dir + "/g.exr";
  desc.filter_type = "nearest";
  const absl::StatusOr<std::unique_ptr<Texture>> bitmap = LoadTexture(desc);
  ASSERT_TRUE(bitmap.ok()) << bitmap.status();
  TexturedColor c;
  c.texture = bitmap->get();
  EXPECT_NEAR(c.EvalScalar(BsdfContext{0.75f, 0.75f}), 0.71516f, 1e-4f);
  EXPECT_NEAR(c.EvalScalar(BsdfContext{0.25f, 0.25f}), 0.57025f, 1e-4f);
  TextureDesc checker;
  checker.type = "checkerboard";
  // A checkerboard read as one number swaps its colours (Mitsuba's eval_1: color0 where exactly
  // one fractional part is above 0.5), while its colour lookup keeps them (eval: color0 at
  // (0.25, 0.25)). Mitsuba: eval_1 0.2 at (0.25, 0.25), 0.9 at (0.75, 0.25).
  checker.color0 = Vec3(0.9f);
  checker.color1 = Vec3(0.1f, 0.2f, 0.3f);
  const absl::StatusOr<std::unique_ptr<Texture>> board = LoadTexture(checker);
  ASSERT_TRUE(board.ok()) << board.status();
  c.texture = board->get();
  EXPECT_NEAR(c.EvalScalar(BsdfContext{0.25f, 0.25f}), 0.2f, 1e-6f);
  EXPECT_NEAR(c.EvalScalar(BsdfContext{0.75f, 0.25f}), 0.9f, 1e-6f);
  ExpectColor(board->get()->Eval(0.25f, 0.25f), Vec3(0.9f), 0, "checkerboard eval");
  c.texture = nullptr;
  c.value = Vec3(0, 1, 0);  // an rgb constant: the mean, as Mitsuba's srgb eval_1
  EXPECT_NEAR(c.EvalScalar(BsdfContext{}), 1.0f / 3, 1e-6f);
}

// An environment map is looked up as Mitsuba 3's envmap emitter does: column u*w - 0.5 (wrapping),
// row v*(h-1) (row 0 at the pole v = 0). The expected values are mitsuba 3.9.1's own (scalar_rgb,
// envmap.eval) for a 16 x 8 map lit at texels (col 5, row 3) = 1, (9, 0) = 2 and (15, 7) = 4,
// at the directions of these (u, v) (EnvmapDirection; the poles themselves are left out, where
// u is undefined). A bitmap's row convention, v*h - 0.5, gives 0.9375 at the first point and
// 1 at the second.
TEST(TextureTest, EnvmapLookupMatchesMitsuba) {
  const std::string dir = ::testing::TempDir() + "/texture_envmap_test";
  std::filesystem::create_directories(dir);
  Image image(16, 8);
  image.at(5, 3) = Vec3(1, 1, 1);
  image.at(9, 0) = Vec3(2, 2, 2);
  image.at(15, 7) = Vec3(4, 4, 4);
  ASSERT_TRUE(WriteExr(image, dir + "/env.exr").ok());
  TextureDesc desc;
  desc.filename = dir + "/env.exr";
  desc.raw = true;
  const absl::StatusOr<std::unique_ptr<BitmapTexture>> t = BitmapTexture::Load(desc);
  ASSERT_TRUE(t.ok()) << t.status();
  struct Case {
    float u, v, mitsuba;
  };
  const Case cases[] = {{0.343750f, 0.428571f, 0.999999f}, {0.343750f, 0.437500f, 0.937499f},
                        {0.328125f, 0.457143f, 0.600000f}, {0.593750f, 0.050000f, 1.300001f},
                        {0.562500f, 0.020000f, 0.859998f}, {0.006250f, 0.970000f, 1.264000f},
                        {0.993750f, 0.990000f, 2.231995f}, {0.343750f, 0.357143f, 0.500000f}};
  for (const Case& c : cases) {
    float u, v;
    EnvmapUv(EnvmapDirection(c.u, c.v), &u, &v);
    EXPECT_NEAR((*t)->EvalLatLong(u, v).x, c.mitsuba, 2e-4f)
        << "(u, v) = (" << c.u << ", " << c.v << ")";
  }
}

// An environment map's float image with a NaN or infinite texel (a half-float sky's clipped sun) is
// refused with the texel named: it made the sampling table, and so every image, black (a review).
// A surface texture keeps them (its poisoned samples are counted and dropped, direct_light_test).
TEST(TextureTest, NonFiniteTexelsAreRefusedInEnvironmentMaps) {
  const std::string dir = ::testing::TempDir() + "/texture_nonfinite_test";
  std::filesystem::create_directories(dir);
  for (const float bad : {INFINITY, NAN}) {
    Image image(4, 2);
    image.at(3, 1) = Vec3(1, bad, 1);
    ASSERT_TRUE(WriteExr(image, dir + "/env.exr").ok());
    TextureDesc desc;
    desc.filename = dir + "/env.exr";
    desc.raw = true;
    const absl::StatusOr<std::unique_ptr<BitmapTexture>> t = BitmapTexture::Load(desc, true);
    ASSERT_FALSE(t.ok());
    EXPECT_NE(std::string(t.status().message()).find("texel (3, 1) is not finite"),
              std::string::npos)
        << t.status();
    EXPECT_TRUE(BitmapTexture::Load(desc).ok());  // a surface texture
    image.at(3, 1) = Vec3(1, 3e38f, 1);           // large but finite: read
    ASSERT_TRUE(WriteExr(image, dir + "/env.exr").ok());
    EXPECT_TRUE(BitmapTexture::Load(desc, true).ok());
  }
}

// 8-bit files are kept as their bytes: each texel is exactly the table's value for its byte
// (sRGB decoded, or byte / 255 with `raw`), and the mean is the mean of those values.
TEST(TextureTest, EightBitImagesAreReadAsTheirBytes) {
  const std::string dir = ::testing::TempDir() + "/texture_bytes_test";
  std::filesystem::create_directories(dir);
  Image image(3, 2);
  for (int i = 0; i < 6; ++i)
    image.pixels[size_t(i)] = Vec3(0.02f * float(i), 0.1f + 0.15f * float(i), 1.0f - 0.13f * i);
  absl::StatusOr<std::string> png = EncodePng(image, 1.0f);
  ASSERT_TRUE(png.ok());
  const std::string path = dir + "/t.png";
  std::ofstream(path, std::ios::binary) << *png;

  Image floats;
  ByteImage bytes;
  ASSERT_TRUE(ReadTextureImage(path, false, &floats, &bytes).ok());
  EXPECT_TRUE(floats.pixels.empty());
  ASSERT_EQ(bytes.width, 3);
  ASSERT_EQ(bytes.height, 2);
  ASSERT_EQ(bytes.rgb.size(), 18u);
  for (size_t i = 0; i < 6; ++i)
    for (int c = 0; c < 3; ++c)  // EncodePng's own rounding of the sRGB value
      EXPECT_EQ(int(bytes.rgb[3 * i + size_t(c)]),
                int(std::lround(LinearToSrgb(image.pixels[i][c]) * 255.0f)))
          << i << " " << c;

  for (const bool raw : {false, true}) {
    TextureDesc desc;
    desc.filename = path;
    desc.filter_type = "nearest";
    desc.raw = raw;
    const absl::StatusOr<std::unique_ptr<Texture>> t = LoadTexture(desc);
    ASSERT_TRUE(t.ok()) << t.status();
    double sum[3] = {0, 0, 0};
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 3; ++x) {
        const uint8_t* b = &bytes.rgb[3 * size_t(y * 3 + x)];
        Vec3 want;
        for (int c = 0; c < 3; ++c) {
          want[c] = raw ? b[c] / 255.0f : SrgbToLinear(b[c] / 255.0f);
          sum[c] += double(want[c]);
        }
        const Vec3 got = (*t)->Eval((x + 0.5f) / 3, (y + 0.5f) / 2);
        for (int c = 0; c < 3; ++c) EXPECT_EQ(got[c], want[c]) << x << " " << y << " " << raw;
      }
    for (int c = 0; c < 3; ++c) EXPECT_NEAR((*t)->Average()[c], sum[c] / 6, 1e-7) << raw;
  }
}

// A 16-bit PNG keeps its 16 bits (decoded from sRGB unless raw, at half precision) and an EXR's
// colour may sit in a layer ("diffuse.R"): mitsuba 3.9.1's bitmap (nearest) at the centres of
// tests/data/textures' fixtures. Before: the PNG's low byte was dropped (0x00ff read as 0) and the
// layer-only EXR read as black; an EXR without colour channels is refused, as Mitsuba refuses it.
TEST(TextureTest, SixteenBitPngsAndLayeredExrsMatchMitsuba) {
  const std::string dir = std::string(IRFARM_TEST_DATA) + "/textures/";
  const auto eval = [&](const std::string& file, bool raw, float u) -> Vec3 {
    TextureDesc desc;
    desc.filename = dir + file;
    desc.filter_type = "nearest";
    desc.raw = raw;
    const absl::StatusOr<std::unique_ptr<Texture>> t = LoadTexture(desc);
    EXPECT_TRUE(t.ok()) << t.status();
    return t.ok() ? (*t)->Eval(u, 0.5f) : Vec3(NAN);
  };
  ExpectColor(eval("sixteen-bit.png", false, 0.25f), Vec3(0.2176514f, 0.0003011227f, 1), 1e-7f,
              "16-bit sRGB texel 0");
  ExpectColor(eval("sixteen-bit.png", false, 0.75f), Vec3(0, 0.00610733f, 0.9897461f), 1e-7f,
              "16-bit sRGB texel 1");
  ExpectColor(eval("sixteen-bit.png", true, 0.25f), Vec3(0.5039062f, 0.003890991f, 1), 1e-7f,
              "16-bit raw texel 0");
  ExpectColor(eval("sixteen-bit.png", true, 0.75f), Vec3(0, 0.07110596f, 0.9956055f), 1e-7f,
              "16-bit raw texel 1");
  ExpectColor(eval("layer-only.exr", false, 0.25f), Vec3(0.5f, 0.25f, 0.125f), 0, "layer");
  TextureDesc depth;
  depth.filename = dir + "depth-only.exr";
  const absl::StatusOr<std::unique_ptr<Texture>> t = LoadTexture(depth);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("no R, G, B or Y channels (it has: Z)"), std::string::npos)
      << t.status();
}

// An image's size is checked from its header before it is decoded: a 16-bit PNG of a few bytes
// that claims 12000 x 12000 texels (stb_image's own 1 GB check passes it; 864 MB as 16 bits and
// 1.7 GB as floats) is refused at once, over the 2^27 texels a float image may have.
TEST(TextureTest, AnImageClaimingAHugeSizeIsRefusedBeforeDecoding) {
  const std::string dir = ::testing::TempDir() + "/texture_huge_test";
  std::filesystem::create_directories(dir);
  // Signature, then an IHDR chunk (12000 x 12000, 16-bit RGB) with its CRC; nothing after.
  const unsigned char png[] = {0x89, 'P',  'N', 'G', '\r', '\n', 0x1a, '\n', 0,    0,    0,
                               13,   'I',  'H', 'D', 'R',  0,    0,    0x2e, 0xe0, 0,    0,
                               0x2e, 0xe0, 16,  2,   0,    0,    0,    0x8e, 0xb7, 0xc7, 0xe5};
  const std::string path = dir + "/huge.png";
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(png), sizeof(png));
  TextureDesc desc;
  desc.filename = path;
  const absl::StatusOr<std::unique_ptr<Texture>> t = LoadTexture(desc);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("12000 x 12000 texels is larger than"), std::string::npos)
      << t.status();
}

// An 8-bit environment map is sRGB-encoded, as Mitsuba 3.9.1's envmap decodes it: a grey PNG of
// byte 128 gives radiance 0.2159 there (measured), where reading the byte as linear gave 0.502.
TEST(TextureTest, EightBitEnvironmentMapsAreSrgb) {
  const std::string dir = ::testing::TempDir() + "/envmap_srgb_test";
  std::filesystem::create_directories(dir);
  Image image(8, 4);
  for (Vec3& p : image.pixels) p = Vec3(SrgbToLinear(128 / 255.0f));
  absl::StatusOr<std::string> png = EncodePng(image, 1.0f);
  ASSERT_TRUE(png.ok());
  std::ofstream(dir + "/grey.png", std::ios::binary) << *png;
  const auto desc = LoadSceneString(
      R"(<scene version="3.0.0"><sensor type="perspective"/>
  <emitter type="envmap"><string name="filename" value="grey.png"/></emitter></scene>)",
      dir + "/s.xml", {});
  ASSERT_TRUE(desc.ok()) << desc.status();
  absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
  ASSERT_TRUE(scene.ok()) << scene.status();
  for (const Vec3& d : {Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0, -1, 0)}) {
    const Vec3 l = (*scene)->EvalEnvironment(d);
    EXPECT_NEAR(l.x, 0.2159f, 2e-4f) << d.x << " " << d.y << " " << d.z;
  }
}

// Textures load in parallel; a file that cannot be read is still reported at its own line, the
// first such texture in the file when there are several.
TEST(TextureTest, AnUnreadableTextureIsReportedAtItsLine) {
  const std::string dir = ::testing::TempDir() + "/texture_missing_test";
  std::filesystem::create_directories(dir);
  Image image(2, 2);
  ASSERT_TRUE(WriteExr(image, dir + "/good.exr").ok());
  // Present (the loader checks that) but not images.
  for (const char* bad : {"/bad-1.png", "/bad-2.png"})
    std::ofstream(dir + bad, std::ios::binary) << "not an image";
  const auto texture = [](const std::string& file) {
    return "<bsdf type=\"diffuse\"><texture type=\"bitmap\" name=\"reflectance\"><string "
           "name=\"filename\" value=\"" +
           file + "\"/></texture></bsdf>\n";
  };
  const std::string xml = "<scene version=\"3.0.0\">\n<sensor type=\"perspective\"/>\n" +
                          texture("good.exr") + texture("bad-1.png") + texture("bad-2.png") +
                          "</scene>\n";
  const absl::StatusOr<SceneDesc> desc = LoadSceneString(xml, dir + "/s.xml", {});
  ASSERT_TRUE(desc.ok()) << desc.status();
  ASSERT_EQ(desc->textures.size(), 3u);
  const absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
  ASSERT_FALSE(scene.ok());
  const std::string message(scene.status().message());
  EXPECT_NE(message.find("s.xml:4"), std::string::npos) << message;
  EXPECT_NE(message.find("bad-1.png"), std::string::npos) << message;
  EXPECT_NE(message.find("cannot read image"), std::string::npos) << message;
}

}  // namespace
}  // namespace irfarm
