// RenderRequest: what a user asks of one render beyond the scene file. The `irfarm render` flags
// and a job's wire settings (service/job_settings.h) both become one, and SettingsFor turns it
// into RenderSettings over the scene's own defaults after the one validation both share
// (ValidateRequest): a value out of range is INVALID_ARGUMENT naming the setting, its range and
// the value, whether it came from a flag or from the network. Zero or empty means "the default".
#pragma once

#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "render/renderer.h"
#include "render/scene_desc.h"

namespace irfarm {

// The most spp, record rays or light samples a request (or a scene's irrcache integrator) may ask.
inline constexpr int kMaxRequestCount = 1 << 20;

struct RenderRequest {
  // "path" or "irrcache"; "" = irrcache, which a denoised render may swap for path where the
  // pilots predict path the better once denoised (RenderSettings::choose_integrator).
  std::string integrator;
  int spp = 0;  // samples per pixel (adaptive: on average)
  int threads = 0;
  uint64_t seed = 0;
  // irrcache.
  float accuracy = 0;   // Ward's a, (0, 1]
  int record_rays = 0;  // hemisphere rays per record, as asked (no balancing)
  int light_samples = 0;
  std::string light_sampling;  // "all", "one"
  std::string spacing;         // RecordSpacingName: "hessian", "split-sphere"
  std::string interpolation;   // "linear", "ward"
  int cache_levels = 0;        // 1-3, as asked (not chosen by the pilots)
  float min_spacing_px = 0, max_spacing_px = 0;
  float lookup_factor = 0;  // [1, 4]
  bool overture = true, caustics = true, direct_sun = true;
  bool firefly_filter = true;  // SpreadFireflies when the image is resolved
  // Adaptive sampling.
  std::string adaptive;  // "on", "off"
  int min_spp = 0, max_spp = 0;
  double sampling_error = 0;
  double target_error = 0;  // (0, 1]: --target-error (turns adaptive on)
  double time_limit = 0;    // wall seconds
  // Outputs.
  bool record_map = false, sample_map = false, progress = false;
  bool aovs = false;     // accumulate the AOV images (a denoiser's guides)
  bool denoise = false;  // the image will be denoised here (no splatting; aovs on)
};

// OK, or INVALID_ARGUMENT for the first value out of its range ("accuracy must be in (0, 1],
// got 3"). Ranges: what the renderer handles, and no more than a render farm should accept from
// a client (spp and rays at most 2^20, threads at most 4096).
absl::Status ValidateRequest(const RenderRequest& request);

// The settings for rendering `desc` as requested: SettingsForScene's defaults (with the scene's
// own bad values as file:line errors), then every value the request gives. Validates first.
absl::StatusOr<RenderSettings> SettingsFor(const SceneDesc& desc, const RenderRequest& request);

}  // namespace irfarm
