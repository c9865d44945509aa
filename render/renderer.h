// Renders a built scene into an image: the image is cut into square tiles rendered in parallel
// by TBB on `threads` cores. Each pixel has its own random stream (seed, pixel index), so `path`
// gives the same image for the same seed whatever the thread count. `irrcache` first runs an
// overture (coarse-to-fine passes that fill the cache at pixel centres, as RADIANCE's rad and
// Mitsuba do) and then the final pass, which interpolates and computes any record still missing.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "cache/irradiance_cache.h"
#include "render/aov.h"
#include "render/caustic_map.h"
#include "render/image.h"
#include "render/irrcache_integrator.h"
#include "render/render_stats.h"
#include "render/scene.h"

namespace irfarm {

// Adaptive sampling's default cap on one pixel's samples, as a multiple of spp.
inline constexpr int kMaxSppFactor = 16;
// irrcache's default spp, the average its adaptive samples may spend (a budget only binds where
// the cache cannot help: glass, metal, glossy chains). At 64, living-room (glossy nearly
// everywhere) came out at 1.6e-2 in 27 s against Mitsuba's 3.6e-2 at 256 spp in 26 s; at 32 at
// 3.3e-2 in 12 s, too close to Mitsuba's error; at 48 at 2.1e-2 to 2.5e-2 in 13-17 s, below
// both Mitsuba's error and its time. materials: 9.8e-4 in 8.4 s at 64, 1.1e-3 to 1.2e-3 in
// 6.2-7.0 s at 48, against path at 256 spp 2.4e-3 in 16.5 s. The other shared scenes reach
// the sampling goal below 32 on average.
inline constexpr int kIrrcacheSpp = 48;

struct RenderSettings {
  std::string integrator = "irrcache";  // "path" or "irrcache"
  // Samples per pixel. Adaptive sampling without a target error: at most this many on average
  // over the rect (in counted work), one pixel up to max_spp; with a target error, as many as
  // reach it, one pixel up to max_spp. SettingsForScene: kIrrcacheSpp for irrcache.
  int spp = 64;
  int threads = 0;  // 0 = all cores
  uint64_t seed = 0;
  int tile_size = 16;
  bool overture = true;     // irrcache: fill the cache before the final pass
  bool record_map = false;  // also produce an image marking where records were computed
  bool progress = false;    // progress line on stderr
  // Adaptive sampling of the final pass: every pixel gets min_spp samples; then rounds double
  // the samples of the pixels with the largest estimated error per sample (from their two
  // interleaved half-images, SampleFilm) until the image's estimated sampling error (relMSE) is
  // at most sampling_error, the samples reach spp per pixel on average (no target error) or
  // every pixel its most, or time_limit is reached. Where the average is what stops them, the
  // samples go where they remove the most error (FinalPass).
  bool adaptive = false;
  int min_spp = 16;
  int max_spp = 0;  // adaptive: the most one pixel gets; 0 = kMaxSppFactor x spp
  // Adaptive with a budget: counted work this rect may spend beyond its own spp per pixel, at
  // most as much again as its own budget (a job's worker passes on what its earlier tiles left:
  // worker/job_context.h); what it does not use comes back in RenderStats::budget_left.
  double budget_carry = 0;
  double sampling_error = 1e-4;
  // > 0: --target-error, the image's total relMSE to reach (cache + sampling); overrides
  // sampling_error and the cache's accuracy (render/cache_refinement.h plans it).
  double target_error = 0;
  double time_limit = 0;  // seconds (wall) from the start of the render; 0 = none
  // Set by the caller (a worker whose job was closed or whose session broke): the render stops
  // at its next tile, row or round and returns an image that is not finished
  // (RenderStats::cancelled). Not owned; null: never.
  const std::atomic<bool>* cancel = nullptr;
  bool Cancelled() const { return cancel != nullptr && cancel->load(std::memory_order_relaxed); }
  bool sample_map = false;  // also produce an image of the samples each pixel got
  bool aovs = false;        // also accumulate the AOV images (render/aov.h)
  // Splat tent and gaussian samples into the pixels around them, as Mitsuba's film does
  // (PixelFilter::SplatReach). Off: every sample stays in its pixel, placed by the pixel's filter
  // (the same expected image, ~3x the variance, but no noise shared between neighbours: what a
  // denoiser expects; `irfarm render --denoise` turns it off).
  bool splat = true;
  // irrcache: caustics from a photon map where the scene has any (render/caustic_map.h). On by
  // default: on specular it takes a quarter off the error for an eighth more time, and a scene
  // without mirrors or smooth glass lit by an area light skips it (docs/guide/irradiance-cache.md).
  bool caustics = true;
  // Spread fireflies (render/firefly_filter.h) over the pixels around them when the image is
  // resolved. On by default: on living-room (glass and mirrors) irrcache's relMSE fell to
  // 0.54-0.62 of the unfiltered image's and no other shared scene had a pixel it changed
  // (docs/guide/direct-light-and-sampling.md, "Fireflies").
  bool firefly_filter = true;
  // Instead of spreading the fireflies, leave the image as rendered and return each pixel's
  // peak (FireflyPeak) in RenderOutput::peak, for whoever assembles the whole image: a farm
  // job's tiles (the coordinator spreads them over the assembled image; a tile alone cannot
  // see its neighbours' pixels).
  bool keep_peaks = false;
  // The image will be denoised (`irfarm render --denoise`; the service's workers leave it off,
  // see docs/guide/denoising.md, "Path for a denoised image"). With choose_integrator as well (the
  // user named no integrator), an irrcache render at default settings runs a path pilot beside its
  // own and renders with path instead where the two pilots predict it the better once denoised
  // (ChooseForDenoising, record_balance.h): at the samples per pixel that take the cache's
  // predicted time, not adaptive.
  bool denoise = false;
  bool choose_integrator = false;
  // The smallest image (pixels of the rect) it chooses for (kPathChoiceMinPixels); the tests
  // lower it to see the choice made on their small images.
  int choose_integrator_min_pixels = kPathChoiceMinPixels;
  IrrcacheSettings irrcache;  // its `path` member is used by both integrators
};

// The default settings for rendering `desc` with `integrator` ("path" or "irrcache"): max_depth
// and rr_depth from the scene's <integrator>; irrcache parameters given in the scene
// (<integrator type="irrcache"> children accuracy, record_rays, light_samples, min_spacing_px,
// max_spacing_px, spp); samples per pixel: for path the scene's sampler, for irrcache its own
// default kIrrcacheSpp (the scene's sample_count is meant for a path tracer). Bad values:
// file:line.
absl::StatusOr<RenderSettings> SettingsForScene(const SceneDesc& desc,
                                                const std::string& integrator);

// Settings for a cache covering this scene; the accuracy lookups will use is settings' a.
CacheSettings CacheSettingsFor(const Scene& scene, const RenderSettings& settings);

struct RenderOutput {
  Image image;
  Image record_map;  // when requested: the image darkened, record positions in red
  Image sample_map;  // when requested: samples per pixel, 0 (black) to spp (white), log scale
  AovImages aovs;    // when requested (settings.aovs), else empty
  Image peak;        // settings.keep_peaks: each pixel's FireflyPeak, else empty
  RenderStats stats;
};

// A rectangle of image pixels [x0, x1) x [y0, y1) (row 0 at the top).
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
};

// Default irrcache settings (irrcache.balance_record_rays, no target error) and an empty
// `cache`: runs the pilot of render/record_balance.h over the whole image (on a scratch cache)
// and returns `settings` with the rays it chose and the balance off (RenderRect balances by
// itself; the service's workers call this once per job, so that all of its tiles use the same
// rays). Otherwise, or for a cache that already holds records, `settings` come back unchanged.
RenderSettings BalancedSettings(const Scene& scene, const RenderSettings& settings,
                                IrradianceCache* cache, BalanceResult* result = nullptr);

// The caustic photon map (render/caustic_map.h) a render with `settings` uses, or nullptr where
// it uses none (integrator path, caustics off, a bounded max_depth, or a scene with nothing that
// makes caustics). Sized by the whole image and seeded by the settings, so every worker of a job
// builds the same one. RenderRect builds it itself unless settings.irrcache.caustics is set: a
// job builds it once for all of its tiles (worker/job_context.cc).
std::unique_ptr<CausticMap> BuildCausticMap(const Scene& scene, const RenderSettings& settings,
                                            CausticMapStats* stats);

// Renders the pixels of `rect` only (the overture too covers only `rect`); the output images
// are rect-sized. A pixel's value does not depend on the rect it was rendered in (its random
// stream is keyed by its position in the whole image), so tiles rendered on different machines
// assemble into the image one process would make (exactly, for path).
// `cache` (irrcache) may already hold records, e.g. from a snapshot or other workers; a null
// cache makes a fresh one for this call.
RenderOutput RenderRect(const Scene& scene, const RenderSettings& settings, IrradianceCache* cache,
                        const PixelRect& rect);

// The whole image.
RenderOutput Render(const Scene& scene, const RenderSettings& settings,
                    IrradianceCache* cache = nullptr);

}  // namespace irfarm
