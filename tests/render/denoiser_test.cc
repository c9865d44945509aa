// Denoiser (render/denoiser.h): when Open Image Denoise is installed, denoising a render lowers
// its error against the Mitsuba reference in every mode; when it is not, Open says so in the
// documented words. (The suite passes without OIDN: the denoising tests are skipped then.)
#include "render/denoiser.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "render_test_util.h"

namespace irfarm {
namespace {

std::unique_ptr<Denoiser> OpenOrSkip() {
  absl::StatusOr<std::unique_ptr<Denoiser>> d = Denoiser::Open(2);
  if (!d.ok()) {
    EXPECT_EQ(d.status().message().rfind("denoiser unavailable: ", 0), 0u) << d.status();
    return nullptr;
  }
  return std::move(*d);
}

TEST(DenoiserTest, MissingLibraryIsReportedAsUnavailable) {
  absl::StatusOr<std::unique_ptr<Denoiser>> d =
      Denoiser::OpenFrom({"/nonexistent/lib/libOpenImageDenoise.so.2"}, 1);
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(d.status().message().rfind("denoiser unavailable: ", 0), 0u) << d.status();
  EXPECT_NE(d.status().message().find("/nonexistent/lib/libOpenImageDenoise.so.2"),
            std::string::npos);
}

TEST(DenoiserTest, UnknownModeIsAnError) {
  EXPECT_FALSE(ParseDenoiseMode("bilateral").ok());
  EXPECT_TRUE(ParseDenoiseMode("demodulated").ok());
}

TEST(DenoiserTest, DenoisingLowersTheErrorOfANoisyPathRender) {
  std::unique_ptr<Denoiser> denoiser = OpenOrSkip();
  if (!denoiser) GTEST_SKIP() << "Open Image Denoise not installed";
  const LoadedScene s = LoadQuarter("cornell-box");
  const Image ref = QuarterReference("cornell-box");
  RenderSettings settings = *SettingsForScene(s.desc, "path");
  settings.spp = 16;
  settings.seed = 7;
  settings.aovs = true;
  const RenderOutput out = Render(*s.scene, settings);
  const double noisy = CompareImages(out.image, ref).relmse;
  for (const char* name : {"image", "demodulated", "indirect"}) {
    absl::StatusOr<Image> clean = DenoiseRender(*denoiser, out.image, out.aovs,
                                                *ParseDenoiseMode(name));
    ASSERT_TRUE(clean.ok()) << clean.status();
    const double e = CompareImages(*clean, ref).relmse;
    std::printf("%s: relMSE %.3g -> %.3g\n", name, noisy, e);
    // A 64x64 path render at 16 spp is noise-dominated: the denoiser must remove most of it.
    EXPECT_LT(e, 0.5 * noisy) << name;
  }
}

}  // namespace
}  // namespace irfarm
