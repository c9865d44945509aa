// Denoiser (render/denoiser.h): when Open Image Denoise is installed, denoising a render lowers
// its error against the Mitsuba reference in every mode; when it is not, Open says so in the
// documented words. (The suite passes without OIDN: the denoising tests are skipped then.)
#include "render/denoiser.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

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
    absl::StatusOr<Image> clean =
        DenoiseRender(*denoiser, out.image, out.aovs, *ParseDenoiseMode(name));
    ASSERT_TRUE(clean.ok()) << clean.status();
    const double e = CompareImages(*clean, ref).relmse;
    std::printf("%s: relMSE %.3g -> %.3g\n", name, noisy, e);
    // A 64x64 path render at 16 spp is noise-dominated: the denoiser must remove most of it.
    EXPECT_LT(e, 0.5 * noisy) << name;
  }
}

TEST(DenoiserTest, PadMirroredReflectsAboutTheEdgePixelsAndCropUndoesIt) {
  for (const auto& [w, h] :
       {std::pair{5, 3}, std::pair{1, 4}, std::pair{2, 1}, std::pair{40, 30}}) {
    Image image(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) image.at(x, y) = Vec3(float(x), float(y), float(x * 100 + y));
    const int b = 16;  // wider than most of these images: reflected again past the far edge
    const Image padded = PadMirrored(image, b);
    ASSERT_EQ(padded.width, w + 2 * b);
    ASSERT_EQ(padded.height, h + 2 * b);
    // Reflection about the first and last pixel: ... 2 1 [0 1 2 ... n-1] n-2 ...
    const auto reflect = [](int i, int n) {
      while (n > 1 && (i < 0 || i >= n)) i = i < 0 ? -i : 2 * (n - 1) - i;
      return n > 1 ? i : 0;
    };
    for (int y = 0; y < padded.height; ++y)
      for (int x = 0; x < padded.width; ++x)
        for (int c = 0; c < 3; ++c)
          ASSERT_EQ(padded.at(x, y)[c], image.at(reflect(x - b, w), reflect(y - b, h))[c])
              << w << "x" << h << " at " << x << "," << y;
    const Image back = Crop(padded, b, b, w, h);
    for (size_t i = 0; i < image.pixels.size(); ++i)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(back.pixels[i][c], image.pixels[i][c]);
  }
}

// A smooth image with noise of known size, flat guides: the filter must remove most of the noise
// on the image's outermost pixels too, not only inside. Their neighbourhood is half the
// interior's, so they stay noisier; unpadded, OIDN 2.5 left the frame with 27% of its noise
// (12x the interior's error; this test fails with the border set to 0), padded 7% (3.8x), as on
// the frame of room-b's irrcache render (render/denoiser.cc).
TEST(DenoiserTest, TheImageFrameIsDenoisedAsWellAsItsInterior) {
  std::unique_ptr<Denoiser> denoiser = OpenOrSkip();
  if (!denoiser) GTEST_SKIP() << "Open Image Denoise not installed";
  const int w = 160, h = 120;
  Image truth(w, h), noisy(w, h), albedo(w, h), normal(w, h);
  std::mt19937 gen(3);
  std::normal_distribution<float> noise(0.0f, 0.1f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float v = 0.5f + 0.3f * std::sin(float(x) / 17) * std::cos(float(y) / 13);
      truth.at(x, y) = Vec3(v, 0.8f * v, 0.6f * v);
      for (int c = 0; c < 3; ++c) noisy.at(x, y)[c] = truth.at(x, y)[c] * (1 + noise(gen));
      albedo.at(x, y) = Vec3(0.7f, 0.7f, 0.7f);
      normal.at(x, y) = Vec3(0, 0, 1);
    }
  absl::StatusOr<Image> clean = denoiser->Denoise(noisy, &albedo, &normal, false);
  ASSERT_TRUE(clean.ok()) << clean.status();
  const int frame = 2;  // the outermost pixels
  double frame_err = 0, inner_err = 0, noisy_err = 0;
  long frame_n = 0, inner_n = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool on_frame = x < frame || y < frame || x >= w - frame || y >= h - frame;
      for (int c = 0; c < 3; ++c) {
        const double t = truth.at(x, y)[c];
        const double e = std::pow(clean->at(x, y)[c] - t, 2) / (t * t + 0.01);
        noisy_err += std::pow(noisy.at(x, y)[c] - t, 2) / (t * t + 0.01);
        (on_frame ? frame_err : inner_err) += e;
        ++(on_frame ? frame_n : inner_n);
      }
    }
  frame_err /= double(frame_n);
  inner_err /= double(inner_n);
  noisy_err /= double(frame_n + inner_n);
  std::printf("relMSE: noisy %.3g, denoised interior %.3g, frame %.3g (%.2fx)\n", noisy_err,
              inner_err, frame_err, frame_err / inner_err);
  EXPECT_LT(inner_err, 0.1 * noisy_err);
  EXPECT_LT(frame_err, 0.15 * noisy_err);
}

// A render whose variance AOV says its pixel noise is below kDenoiseNoiseFloor comes back as it
// is; the same render with a variance above it is filtered.
TEST(DenoiserTest, ARenderBelowTheNoiseFloorIsReturnedAsItIs) {
  std::unique_ptr<Denoiser> denoiser = OpenOrSkip();
  if (!denoiser) GTEST_SKIP() << "Open Image Denoise not installed";
  const LoadedScene s = LoadQuarter("cornell-box");
  RenderSettings settings = *SettingsForScene(s.desc, "path");
  settings.spp = 16;
  settings.seed = 7;
  settings.aovs = true;
  RenderOutput out = Render(*s.scene, settings);
  const double noise = EstimatedSamplingError(out.image, out.aovs.variance);
  EXPECT_GT(noise, 100 * kDenoiseNoiseFloor);  // a 16-spp path render is noisy
  absl::StatusOr<Image> filtered =
      DenoiseRender(*denoiser, out.image, out.aovs, DenoiseMode::kImage);
  ASSERT_TRUE(filtered.ok()) << filtered.status();
  EXPECT_GT(CompareImages(*filtered, out.image).relmse, 0);
  // Scale the variance so that the estimate lands just below the floor.
  const float scale = float(0.5 * kDenoiseNoiseFloor / noise);
  for (Vec3& v : out.aovs.variance.pixels) v = v * scale;
  EXPECT_LT(EstimatedSamplingError(out.image, out.aovs.variance), kDenoiseNoiseFloor);
  absl::StatusOr<Image> kept = DenoiseRender(*denoiser, out.image, out.aovs, DenoiseMode::kImage);
  ASSERT_TRUE(kept.ok()) << kept.status();
  EXPECT_EQ(CompareImages(*kept, out.image).relmse, 0);
}

}  // namespace
}  // namespace irfarm
