// Denoiser: OIDN's C API through dlopen (see denoiser.h for why), and the denoising modes.
#include "render/denoiser.h"

#include <dlfcn.h>

#include <algorithm>
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
  const int w = color.width, h = color.height;
  for (const Image* aux : {albedo, normal})
    if (aux && (aux->width != w || aux->height != h))
      return absl::InvalidArgumentError("denoiser: guide image size differs from the image");
  const Api& a = *api_;
  const auto set = [&](void* filter, const char* name, const Image& image) {
    a.SetSharedFilterImage(
        filter, name, const_cast<void*>(static_cast<const void*>(image.pixels.data())),
        kOidnFormatFloat3, size_t(w), size_t(h), 0, sizeof(Vec3), sizeof(Vec3) * size_t(w));
  };
  // Prefiltered guides are written to copies (the caller's AOVs stay as rendered).
  Image clean_albedo, clean_normal;
  const bool prefilter = prefilter_aux && albedo && normal;
  if (prefilter) {
    clean_albedo = *albedo;
    clean_normal = *normal;
    for (auto [name, image] : {std::pair<const char*, Image*>{"albedo", &clean_albedo},
                               std::pair<const char*, Image*>{"normal", &clean_normal}}) {
      void* f = a.NewFilter(device_, "RT");
      set(f, name, *image);
      set(f, "output", *image);
      a.CommitFilter(f);
      a.ExecuteFilter(f);
      a.ReleaseFilter(f);
      if (absl::Status st = DeviceError("prefiltering the guide images"); !st.ok()) return st;
    }
    albedo = &clean_albedo;
    normal = &clean_normal;
  }
  Image out(w, h);
  void* f = a.NewFilter(device_, "RT");
  set(f, "color", color);
  if (albedo) set(f, "albedo", *albedo);
  if (albedo && normal) set(f, "normal", *normal);  // OIDN takes a normal only with an albedo
  set(f, "output", out);
  a.SetFilterBool(f, "hdr", true);
  a.SetFilterBool(f, "cleanAux", prefilter);
  a.CommitFilter(f);
  a.ExecuteFilter(f);
  a.ReleaseFilter(f);
  if (absl::Status st = DeviceError("denoising"); !st.ok()) return st;
  return out;
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

absl::StatusOr<Image> DenoiseRender(const Denoiser& denoiser, const Image& image,
                                    const AovImages& aovs, DenoiseMode mode, bool prefilter_aux) {
  if (aovs.empty() || aovs.albedo.width != image.width || aovs.albedo.height != image.height)
    return absl::InvalidArgumentError("denoiser: the render has no AOVs of its size");
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
