// Mitsuba's <spectrum> values (render/spectrum.h) against Mitsuba 3.9.1's own conversions in its
// RGB mode: the expected values are what Mitsuba gives each spectrum where the test puts it,
// printed by spectrum_mitsuba_values.py beside this file (mi.traverse of the loaded scene; 6
// significant digits). A reflectance, a conductor's eta and an emitter's radiance are converted
// differently (D65-weighted or not; a uniform radiance is equal-energy white, not grey).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "render/scene_loader.h"
#include "render/spectrum.h"

namespace irfarm {
namespace {

struct MitsubaCase {
  const char* name;  // where Mitsuba read it: "radiance" is an emitter's
  const char* value;
  double rgb[3];
};
// Printed by spectrum_mitsuba_values.py (Mitsuba 3.9.1, scalar_rgb).
const MitsubaCase kMitsuba[] = {
    {"reflectance", "0.5", {0.5, 0.5, 0.5}},
    {"reflectance", "400:0.1, 500:0.5, 600:0.7, 700:0.9", {0.775405, 0.593508, 0.277033}},
    {"reflectance", "400:0.5, 700:0.5", {0.497671, 0.499878, 0.497455}},
    {"eta", "400:1.5, 700:2.5", {2.29716, 1.97609, 1.62841}},
    {"radiance", "1", {1.20479, 0.948291, 0.908916}},
    {"radiance", "0.3", {0.361438, 0.284487, 0.272675}},
    {"radiance", "400:0, 500:8, 600:15.6, 700:18.4", {20.7108, 10.8546, 2.77115}},
    {"radiance", "400:1, 700:1", {1.19969, 0.94952, 0.903443}},
    {"radiance", "550:5, 560:5", {0.0614455, 0.665407, 0}},  // Mitsuba clamps its -0.08 blue
    {"reflectance", "380:0.05, 450:0.8, 520:0.2, 610:0.6, 780:0.3", {0.640302, 0.302878, 0.669687}},
};

TEST(SpectrumTest, ConvertsAsMitsubaDoes) {
  for (const MitsubaCase& c : kMitsuba) {
    const bool emission = std::string(c.name) == "radiance";
    absl::StatusOr<Vec3> rgb = SpectrumToRgb(c.value, emission);
    ASSERT_TRUE(rgb.ok()) << c.value << ": " << rgb.status();
    const Vec3 got = Max(*rgb, Vec3(0.0f));  // the loader's clamp, as Mitsuba's
    for (int ch = 0; ch < 3; ++ch) {
      // Mitsuba's figures have 6 significant digits.
      EXPECT_NEAR(got[ch], c.rgb[ch], 2e-5 * std::max(1.0, std::abs(c.rgb[ch])))
          << c.name << " " << c.value << " channel " << ch;
    }
  }
  // Pairs separated by white space alone read the same (Mitsuba splits on both).
  const Vec3 spaced = *SpectrumToRgb("400:0.1 500:0.5\n600:0.7\t700:0.9", false);
  EXPECT_NEAR(spaced.x, 0.775405, 2e-5);
  EXPECT_NEAR(spaced.z, 0.277033, 2e-5);
  // Without the D65 weighting (a reflectance taken as light) the figures are far off: the
  // reflectance case above would come out (0.918, 0.565, 0.242).
  const Vec3 as_light = *SpectrumToRgb("400:0.1, 500:0.5, 600:0.7, 700:0.9", true);
  EXPECT_GT(std::abs(as_light.x - 0.775405), 0.05);
}

TEST(SpectrumTest, SceneLoaderReadsSpectraInBsdfsAndEmitters) {
  const std::string xml =
      "<scene version=\"3.0.0\">\n"
      "<sensor type=\"perspective\"/>\n"
      "<shape type=\"sphere\"><bsdf type=\"diffuse\">\n"
      "  <spectrum name=\"reflectance\" value=\"400:0.1, 500:0.5, 600:0.7, 700:0.9\"/></bsdf>\n"
      "  <emitter type=\"area\"><spectrum name=\"radiance\" value=\"550:5, 560:5\"/></emitter>\n"
      "</shape>\n"
      "</scene>\n";
  absl::StatusOr<SceneDesc> d = LoadSceneString(xml, "spectra.xml", {});
  ASSERT_TRUE(d.ok()) << d.status();
  ASSERT_EQ(d->shapes.size(), 1u);
  const Vec3 refl = d->bsdfs[size_t(d->shapes[0].bsdf)].colors.at("reflectance").value;
  EXPECT_NEAR(refl.x, 0.775405, 2e-5);
  EXPECT_NEAR(refl.z, 0.277033, 2e-5);
  ASSERT_TRUE(d->shapes[0].area_radiance.has_value());
  EXPECT_NEAR(d->shapes[0].area_radiance->y, 0.665407, 2e-5);
  EXPECT_EQ(d->shapes[0].area_radiance->z, 0.0f);
  bool warned = false;
  for (const std::string& w : d->warnings)
    warned |= w.find("spectra.xml:5:") != std::string::npos &&
              w.find("outside sRGB") != std::string::npos;
  EXPECT_TRUE(warned) << "the clamped blue is not reported";
}

TEST(SpectrumTest, BadSpectraAreErrorsWithFileLine) {
  const char* bad[] = {
      R"(value="blue")",         R"(value="400:0.1")",          R"(value="500:0.1, 400:0.2")",
      R"(value="400:0.1, 500")", R"(value="400:0.1, 700:nan")", R"(filename="cie.spd")",
  };
  for (const char* attrs : bad) {
    const std::string xml =
        std::string("<scene version=\"3.0.0\">\n<sensor type=\"perspective\"/>\n") +
        "<bsdf type=\"diffuse\">\n  <spectrum name=\"reflectance\" " + attrs +
        "/>\n</bsdf>\n</scene>\n";
    absl::StatusOr<SceneDesc> d = LoadSceneString(xml, "bad.xml", {});
    ASSERT_FALSE(d.ok()) << attrs;
    EXPECT_NE(d.status().message().find("bad.xml:4:"), std::string::npos)
        << attrs << ": " << d.status();
  }
}

}  // namespace
}  // namespace irfarm
