// Denoising with Intel Open Image Denoise 2 (OIDN) on the CPU, loaded at run time.
// Debian 12 has no OIDN package; the official prebuilt library (no headers) is unpacked by
// deploy/setup.sh from the `pyoidn` wheel. irfarm therefore does not link it: Denoiser::Open
// dlopen()s libOpenImageDenoise.so.2 and resolves the few C functions it uses, declared here from
// OIDN's public header (include/OpenImageDenoise/oidn.h). Without the library irfarm builds and
// runs as before, and Open says why the denoiser is unavailable.
// OIDN's own libtbb.so.12 is not loaded: irfarm has already loaded Debian's libtbb.so.12 (same
// soname, same oneTBB ABI; every TBB symbol OIDN's CPU device imports is defined there, checked
// with nm), so the dynamic loader binds OIDN to that one and one TBB runtime serves both.
//
// DenoiseRender applies the filter to a rendered image with its AOVs (render/aov.h) in one of the
// ways the bench compares: the whole image, or the radiance demodulated by albedo.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "render/aov.h"
#include "render/image.h"

namespace irfarm {

class Denoiser {
 public:
  // Loads OIDN and makes a committed CPU device using `threads` threads (0 = all cores). Looks
  // for libOpenImageDenoise.so.2 in $IRFARM_OIDN_DIR/lib, then in the directory configured at
  // build time (IRFARM_OIDN_DIR, default /opt/irfarm/oidn), then on the loader's path. Errors
  // start with "denoiser unavailable: ".
  static absl::StatusOr<std::unique_ptr<Denoiser>> Open(int threads = 0);
  // The same from an explicit list of library files to try in order.
  static absl::StatusOr<std::unique_ptr<Denoiser>> OpenFrom(
      const std::vector<std::string>& libraries, int threads);
  ~Denoiser();
  Denoiser(const Denoiser&) = delete;
  Denoiser& operator=(const Denoiser&) = delete;

  // OIDN's "RT" filter on HDR `color`, guided by `albedo` and `normal` when given (same size).
  // With `prefilter_aux`, albedo and normal are first denoised by their own RT filters and the
  // main filter is told they are clean (cleanAux), as OIDN recommends for noisy guides.
  absl::StatusOr<Image> Denoise(const Image& color, const Image* albedo, const Image* normal,
                                bool prefilter_aux) const;
  const std::string& library() const { return library_; }

 private:
  struct Api;
  Denoiser() = default;
  absl::Status DeviceError(const char* what) const;

  void* handle_ = nullptr;  // dlopen handle
  std::unique_ptr<Api> api_;
  void* device_ = nullptr;  // OIDNDevice
  std::string library_;
};

enum class DenoiseMode {
  kImage,        // the whole image, guided by albedo + normal
  kDemodulated,  // (image - emission) / albedo, then times albedo plus emission
  kIndirect,     // only indirect / albedo; direct kept as rendered
};
// "image", "demodulated", "indirect".
absl::StatusOr<DenoiseMode> ParseDenoiseMode(const std::string& name);

// The render's sampling error (relMSE as the benchmarks define it: the mean over pixels and
// channels of var / (v^2 + 0.01)) estimated from its variance AOV; -1 when it has none.
double EstimatedSamplingError(const Image& image, const Image& variance);
// DenoiseRender returns a render whose estimated sampling error is below this as it is: its
// pixel noise (an RMS relative error of 0.3%) is under 8-bit display quantization (1/255), there
// is nothing for the filter to remove, and it can only add its own error. Measured on room-b's
// irrcache renders at two cache levels (this estimate 1.9e-6): denoising changed relMSE by
// +0.04% and +0.2%; the next-cleanest shared renders (sunlit-room and cornell-box irrcache,
// 1.7e-4 and 2.0e-4) gained 2-3%.
constexpr double kDenoiseNoiseFloor = 1e-5;
// Denoises `image` rendered with `aovs` (non-empty) in `mode`. The guides are used as rendered
// by default: averaged over the pixel's samples they are nearly clean, and prefiltering them
// measured worse and 7x slower (cornell-box irrcache 16 spp: relMSE 1.25e-3 in 2.5 s with,
// 1.15e-3 in 0.36 s without).
absl::StatusOr<Image> DenoiseRender(const Denoiser& denoiser, const Image& image,
                                    const AovImages& aovs, DenoiseMode mode,
                                    bool prefilter_aux = false);

}  // namespace irfarm
