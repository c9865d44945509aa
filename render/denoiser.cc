// Denoiser: OIDN's C API through dlopen (see denoiser.h for why), and the denoising modes.
#include "render/denoiser.h"

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>

#ifndef IRFARM_OIDN_DEFAULT_DIR
#define IRFARM_OIDN_DEFAULT_DIR "/opt/irfarm/oidn"
#endif

namespace irfarm {
namespace {

// From OIDN 2's include/OpenImageDenoise/oidn.h (enum values and signatures of the C API).
constexpr int kOidnDeviceTypeCpu = 1;  // OIDN_DEVICE_TYPE_CPU
constexpr int kOidnFormatFloat3 = 3;   // OIDN_FORMAT_FLOAT3
constexpr int kOidnErrorNone = 0;      // OIDN_ERROR_NONE
constexpr const char* kOidnLibrary = "libOpenImageDenoise.so.2";

}  // namespace

struct Denoiser::Api {
  void* (*NewDevice)(int type);
  void (*SetDeviceInt)(void* device, const char* name, int value);
  void (*SetDeviceBool)(void* device, const char* name, bool value);
  void (*CommitDevice)(void* device);
  void (*ReleaseDevice)(void* device);
  int (*GetDeviceError)(void* device, const char** message);
  void* (*NewFilter)(void* device, const char* type);
  void (*SetSharedFilterImage)(void* filter, const char* name, void* ptr, int format, size_t width,
                               size_t height, size_t byte_offset, size_t pixel_byte_stride,
                               size_t row_byte_stride);
  void (*SetFilterBool)(void* filter, const char* name, bool value);
  void (*CommitFilter)(void* filter);
  void (*ExecuteFilter)(void* filter);
  void (*ReleaseFilter)(void* filter);
};

namespace {

template <typename F>
bool Resolve(void* handle, const char* name, F* fn) {
  *fn = reinterpret_cast<F>(dlsym(handle, name));
  return *fn != nullptr;
}

}  // namespace

absl::StatusOr<std::unique_ptr<Denoiser>> Denoiser::Open(int threads) {
  std::vector<std::string> candidates;
  if (const char* dir = std::getenv("IRFARM_OIDN_DIR"); dir && *dir)
    candidates.push_back(std::string(dir) + "/lib/" + kOidnLibrary);
  candidates.push_back(std::string(IRFARM_OIDN_DEFAULT_DIR) + "/lib/" + kOidnLibrary);
  candidates.push_back(kOidnLibrary);
  return OpenFrom(candidates, threads);
}

absl::StatusOr<std::unique_ptr<Denoiser>> Denoiser::OpenFrom(
    const std::vector<std::string>& candidates, int threads) {
  std::unique_ptr<Denoiser> d(new Denoiser());
  std::string tried;
  for (const std::string& path : candidates) {
    d->handle_ = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (d->handle_) {
      d->library_ = path;
      break;
    }
    const char* err = dlerror();
    tried += "\n  " + path + ": " + (err ? err : "not found");
  }
  if (!d->handle_)
    return absl::UnavailableError(
        "denoiser unavailable: cannot load Open Image Denoise 2 (deploy/setup.sh installs it; "
        "IRFARM_OIDN_DIR=PREFIX points to it); tried:" +
        tried);
  d->api_ = std::make_unique<Api>();
  Api& a = *d->api_;
  const bool ok = Resolve(d->handle_, "oidnNewDevice", &a.NewDevice) &&
                  Resolve(d->handle_, "oidnSetDeviceInt", &a.SetDeviceInt) &&
                  Resolve(d->handle_, "oidnSetDeviceBool", &a.SetDeviceBool) &&
                  Resolve(d->handle_, "oidnCommitDevice", &a.CommitDevice) &&
                  Resolve(d->handle_, "oidnReleaseDevice", &a.ReleaseDevice) &&
                  Resolve(d->handle_, "oidnGetDeviceError", &a.GetDeviceError) &&
                  Resolve(d->handle_, "oidnNewFilter", &a.NewFilter) &&
                  Resolve(d->handle_, "oidnSetSharedFilterImage", &a.SetSharedFilterImage) &&
                  Resolve(d->handle_, "oidnSetFilterBool", &a.SetFilterBool) &&
                  Resolve(d->handle_, "oidnCommitFilter", &a.CommitFilter) &&
                  Resolve(d->handle_, "oidnExecuteFilter", &a.ExecuteFilter) &&
                  Resolve(d->handle_, "oidnReleaseFilter", &a.ReleaseFilter);
  if (!ok)
    return absl::UnavailableError("denoiser unavailable: " + d->library_ +
                                  " lacks OIDN 2 C functions (not OIDN 2?)");
  d->device_ = a.NewDevice(kOidnDeviceTypeCpu);
  if (!d->device_)
    return absl::UnavailableError("denoiser unavailable: OIDN has no CPU device (" + d->library_ +
                                  ")");
  if (threads > 0) a.SetDeviceInt(d->device_, "numThreads", threads);
  // Do not pin threads to cores: the render's TBB workers and other processes share them.
  a.SetDeviceBool(d->device_, "setAffinity", false);
  a.CommitDevice(d->device_);
  if (absl::Status st = d->DeviceError("cannot make the CPU device"); !st.ok())
    return absl::UnavailableError("denoiser unavailable: " + std::string(st.message()));
  return d;
}

Denoiser::~Denoiser() {
  if (api_ && device_) api_->ReleaseDevice(device_);
  // The library stays loaded: OIDN's CPU device leaves TBB threads and static objects behind that
  // must not outlive their code, and the process ends soon after anyway.
}

absl::Status Denoiser::DeviceError(const char* what) const {
  const char* message = nullptr;
  const int code = api_->GetDeviceError(device_, &message);
  if (code == kOidnErrorNone) return absl::OkStatus();
  return absl::InternalError(std::string("OIDN: ") + what + ": error " + std::to_string(code) +
                             ": " + (message ? message : "?"));
}

absl::StatusOr<Image> Denoiser::Denoise(const Image& color, const Image* albedo,
                                        const Image* normal, bool prefilter_aux) const {
  for (const Image* aux : {albedo, normal})
    if (aux && (aux->width != color.width || aux->height != color.height))
      return absl::InvalidArgumentError("denoiser: guide image size differs from the image");
  // OIDN sees the image and its guides mirrored kBorder pixels past each edge, and the border is
  // cut off again: unpadded, the filter's outermost pixels came out wrong by more than their
  // noise (room-b, irrcache: the 20 pixels it made worst were all on the frame, and denoising made
  // the image worse, relMSE 4.70e-5 -> 4.78e-5; padded 4.57e-5). Over the bench's 40 renders
  // (10 scenes x 4 settings) padding by 16 lowered the denoised relMSE in 31 and raised it by at
  // most 3% in the others; it costs 25% more filter time at 320 x 240.
  constexpr int kBorder = 16;
  const Image padded_color = PadMirrored(color, kBorder);
  Image padded_albedo, padded_normal;  // copies: the caller's AOVs stay as rendered
  if (albedo) padded_albedo = PadMirrored(*albedo, kBorder);
  if (normal) padded_normal = PadMirrored(*normal, kBorder);
  const int w = padded_color.width, h = padded_color.height;
  const Api& a = *api_;
  const auto set = [&](void* filter, const char* name, const Image& image) {
    a.SetSharedFilterImage(
        filter, name, const_cast<void*>(static_cast<const void*>(image.pixels.data())),
        kOidnFormatFloat3, size_t(w), size_t(h), 0, sizeof(Vec3), sizeof(Vec3) * size_t(w));
  };
  const bool prefilter = prefilter_aux && albedo && normal;
  if (prefilter) {
    for (auto [name, image] : {std::pair<const char*, Image*>{"albedo", &padded_albedo},
                               std::pair<const char*, Image*>{"normal", &padded_normal}}) {
      void* f = a.NewFilter(device_, "RT");
      set(f, name, *image);
      set(f, "output", *image);
      a.CommitFilter(f);
      a.ExecuteFilter(f);
      a.ReleaseFilter(f);
      if (absl::Status st = DeviceError("prefiltering the guide images"); !st.ok()) return st;
    }
  }
  Image out(w, h);
  void* f = a.NewFilter(device_, "RT");
  set(f, "color", padded_color);
  if (albedo) set(f, "albedo", padded_albedo);
  if (albedo && normal) set(f, "normal", padded_normal);  // OIDN takes a normal only with albedo
  set(f, "output", out);
  a.SetFilterBool(f, "hdr", true);
  a.SetFilterBool(f, "cleanAux", prefilter);
  a.CommitFilter(f);
  a.ExecuteFilter(f);
  a.ReleaseFilter(f);
  if (absl::Status st = DeviceError("denoising"); !st.ok()) return st;
  return Crop(out, kBorder, kBorder, color.width, color.height);
}

absl::StatusOr<DenoiseMode> ParseDenoiseMode(const std::string& name) {
  if (name == "image") return DenoiseMode::kImage;
  if (name == "demodulated") return DenoiseMode::kDemodulated;
  if (name == "indirect") return DenoiseMode::kIndirect;
  return absl::InvalidArgumentError("unknown denoise mode '" + name +
                                    "' (supported: image, demodulated, indirect)");
}

namespace {

// Albedo below this (per channel) is not divided by: the pixel sees an emitter, the sky or a
// near-black surface, where demodulation would amplify noise without bound.
constexpr float kMinAlbedo = 1e-3f;

float SafeDivide(float x, float a) { return a > kMinAlbedo ? x / a : 0.0f; }

}  // namespace

double EstimatedSamplingError(const Image& image, const Image& variance) {
  if (variance.width != image.width || variance.height != image.height || image.pixels.empty())
    return -1;
  double sum = 0;
  for (size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const double v = image.pixels[i][c], var = variance.pixels[i][c];
      if (std::isfinite(var) && std::isfinite(v)) sum += std::max(0.0, var) / (v * v + 0.01);
    }
  return sum / (3.0 * double(image.pixels.size()));
}

absl::StatusOr<Image> DenoiseRender(const Denoiser& denoiser, const Image& image,
                                    const AovImages& aovs, DenoiseMode mode, bool prefilter_aux) {
  if (aovs.empty() || aovs.albedo.width != image.width || aovs.albedo.height != image.height)
    return absl::InvalidArgumentError("denoiser: the render has no AOVs of its size");
  const double noise = EstimatedSamplingError(image, aovs.variance);
  if (noise >= 0 && noise < kDenoiseNoiseFloor) return image;  // nothing to remove
  if (mode == DenoiseMode::kImage)
    return denoiser.Denoise(image, &aovs.albedo, &aovs.normal, prefilter_aux);
  // Demodulated: the light arriving at the first diffuse surface (reflected radiance divided by
  // its albedo) is smooth across texture and colour edges, which the denoiser then need not keep.
  // The guide albedo becomes white there (the texture is divided out), black elsewhere.
  const size_t n = image.pixels.size();
  Image demod(image.width, image.height), guide(image.width, image.height);
  for (size_t i = 0; i < n; ++i) {
    const Vec3& alb = aovs.albedo.pixels[i];
    const Vec3 part = mode == DenoiseMode::kIndirect ? aovs.indirect.pixels[i]
                                                     : image.pixels[i] - aovs.emission.pixels[i];
    for (int c = 0; c < 3; ++c) {
      demod.pixels[i][c] = SafeDivide(part[c], alb[c]);
      guide.pixels[i][c] = alb[c] > kMinAlbedo ? 1.0f : 0.0f;
    }
  }
  absl::StatusOr<Image> den = denoiser.Denoise(demod, &guide, &aovs.normal, prefilter_aux);
  if (!den.ok()) return den.status();
  Image out(image.width, image.height);
  for (size_t i = 0; i < n; ++i) {
    const Vec3& alb = aovs.albedo.pixels[i];
    const Vec3 kept =
        mode == DenoiseMode::kIndirect ? aovs.direct.pixels[i] : aovs.emission.pixels[i];
    const Vec3 part = mode == DenoiseMode::kIndirect ? aovs.indirect.pixels[i]
                                                     : image.pixels[i] - aovs.emission.pixels[i];
    for (int c = 0; c < 3; ++c)
      out.pixels[i][c] = kept[c] + (alb[c] > kMinAlbedo ? den->pixels[i][c] * alb[c] : part[c]);
  }
  return out;
}

}  // namespace irfarm
