#include "render/renderer.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <thread>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "render/cache_check.h"
#include "render/cache_refinement.h"
#include "render/caustic_map.h"
#include "render/final_pass.h"
#include "render/overture.h"
#include "render/pilot.h"
#include "render/record_balance.h"
#include "render/render_request.h"

namespace irfarm {
namespace {

// Caustic photons stored: two per pixel of the image, within these bounds; and emitted: at most
// kCausticEmitRatio per photon wanted. Where fewer photons find a mirror or smooth glass, the
// caustics carry little of the light: materials (1.6% of the photons stored) rendered the same
// with the map at 16x or 40x and without it (seeds 3 and 4: 4.11e-3 / 4.00e-3 / 4.03e-3 and
// 3.30e-3 / 3.26e-3 / 3.31e-3), and 40x cost 1.5 CPU s more; specular stores 1 in 12.
constexpr long kFewestCausticPhotons = 50000, kMostCausticPhotons = 1000000;
constexpr long kCausticEmitRatio = 16;
// A map of glossy caustics only (no mirror or smooth glass: CausticMap::Lobes), which are
// broad, stores a quarter as many: on make_room 401 (a spot's highlight on a metal box, seeds
// 7-9 at defaults) relMSE 1.10-1.26e-3 with 2 photons per pixel, 1.09-1.27e-3 with 1/2 and
// 1.12-1.25e-3 with 1/4, the map's build 0.9, 0.46 and 0.23 CPU s.
constexpr long kGlossyOnlyPhotonsDivisor = 4;

}  // namespace

absl::StatusOr<RenderSettings> SettingsForScene(const SceneDesc& desc,
                                                const std::string& integrator) {
  RenderSettings s;
  s.integrator = integrator;
  s.irrcache.path.max_depth = desc.integrator.max_depth;
  s.irrcache.path.rr_depth = desc.integrator.rr_depth;
  s.irrcache.path.env_importance = integrator == "path";  // PathSettings::env_importance
  IrrcacheSettings& ic = s.irrcache;
  double spp = kIrrcacheSpp;
  if (desc.integrator.type == "irrcache") {
    static constexpr const char* kKnown[] = {"accuracy",       "record_rays",    "light_samples",
                                             "min_spacing_px", "max_spacing_px", "spp",
                                             "cache_levels"};
    std::map<std::string, double> values;
    for (const auto& [name, text] : desc.integrator.params) {
      bool found = false;
      for (const char* k : kKnown) found |= name == k;
      double v = 0;
      if (!found)
        return absl::InvalidArgumentError(desc.integrator.loc.ToString() +
                                          ": unknown irrcache parameter '" + name +
                                          "' (supported: accuracy, record_rays, light_samples, "
                                          "min_spacing_px, max_spacing_px, spp, cache_levels)");
      // Counts are bounded as the command's flags are (kMaxRequestCount): 1e300 rays made int()
      // undefined, and spp x light samples overflowed.
      const bool count = name == "record_rays" || name == "light_samples" || name == "spp";
      if (!absl::SimpleAtod(text, &v) || !std::isfinite(v) || v <= 0 ||
          (name == "accuracy" && v > 1) || (count && v > kMaxRequestCount) ||
          (name == "cache_levels" && v != 1 && v != 2 && v != 3))
        return absl::InvalidArgumentError(
            desc.integrator.loc.ToString() + ": irrcache parameter '" + name +
            "' must be a positive number" + (name == "accuracy" ? " <= 1" : "") +
            (count ? " up to " + std::to_string(kMaxRequestCount) : "") +
            (name == "cache_levels" ? " (1, 2 or 3)" : "") + ", got '" + text + "'");
      values[name] = v;
    }
    if (values.count("accuracy")) ic.accuracy = float(values["accuracy"]);
    if (values.count("record_rays")) {
      ic.record_rays = int(values["record_rays"]);
      ic.balance_record_rays = false;  // the scene's rays, as asked
    }
    if (values.count("light_samples")) ic.light_samples = int(values["light_samples"]);
    if (values.count("min_spacing_px")) ic.min_spacing_px = float(values["min_spacing_px"]);
    if (values.count("max_spacing_px")) ic.max_spacing_px = float(values["max_spacing_px"]);
    if (ic.min_spacing_px > ic.max_spacing_px)  // std::clamp's order, as the records use it
      return absl::InvalidArgumentError(
          desc.integrator.loc.ToString() + ": min_spacing_px (" + absl::StrCat(ic.min_spacing_px) +
          ") must not exceed max_spacing_px (" + absl::StrCat(ic.max_spacing_px) + ")");
    if (values.count("spp")) spp = values["spp"];
    if (values.count("cache_levels")) {
      ic.cache_levels = int(values["cache_levels"]);
      ic.choose_cache_levels = false;  // the scene's levels, as asked
    }
  }
  s.spp = integrator == "path" ? desc.camera.spp : std::max(1, int(spp));
  s.adaptive = integrator == "irrcache";
  return s;
}

CacheSettings CacheSettingsFor(const Scene& scene, const RenderSettings& settings) {
  CacheSettings cs;
  cs.bounds = scene.bounds();
  const float a = settings.target_error > 0 ? std::max(settings.irrcache.accuracy,
                                                       float(TargetAccuracy(settings.target_error)))
                                            : settings.irrcache.accuracy;
  cs.max_accuracy = std::min(1.0f, a * std::max({1.0f, settings.irrcache.relaxed_factor,
                                                 settings.irrcache.lookup_factor}));
  cs.neighbour_slope = settings.irrcache.neighbour_slope;
  cs.linear_fit = settings.irrcache.linear_fit && !(settings.target_error > 0);
  return cs;
}

namespace {
// The render's threads: the settings', or all cores. Under ThreadSanitizer (.ci/sanitizers thread)
// one: Debian's oneTBB is not instrumented, so TBB handing a parallel loop's tasks to its worker
// threads is invisible to TSan, and every loop would be reported as a race on the data its body
// reads. There TSan checks the service's own threads (sessions, publishers, stores, leases and
// the render thread against them); the cache's concurrent inserts and lookups are checked by
// cache_tests on std::threads.
int RenderThreads(const RenderSettings& settings) {
#if defined(__SANITIZE_THREAD__)
  (void)settings;
  return 1;
#else
  return settings.threads > 0 ? settings.threads
                              : int(std::max(1u, std::thread::hardware_concurrency()));
#endif
}
}  // namespace

RenderSettings BalancedSettings(const Scene& scene, const RenderSettings& settings,
                                IrradianceCache* cache, BalanceResult* result) {
  RenderSettings out = settings;
  if (settings.integrator != "irrcache" || settings.target_error > 0 ||
      !settings.irrcache.balance_record_rays || cache == nullptr || cache->size() > 0)
    return out;
  tbb::task_arena arena(RenderThreads(settings));
  tbb::enumerable_thread_specific<RenderCounters> counters;
  const Camera& cam = scene.camera();
  const BalanceResult b = PilotSettings(scene, settings, PixelRect{0, 0, cam.width(), cam.height()},
                                        arena, counters, &out.irrcache);
  out.irrcache.balance_record_rays = false;
  out.irrcache.choose_cache_levels = false;
  if (result) *result = b;
  return out;
}

namespace {
std::unique_ptr<CausticMap> BuildCausticMap(const Scene& scene, const RenderSettings& settings,
                                            tbb::task_arena& arena, CausticMapStats* stats) {
  *stats = CausticMapStats();
  if (settings.integrator != "irrcache" || !settings.caustics ||
      settings.irrcache.path.max_depth >= 0)
    return nullptr;
  const Camera& cam = scene.camera();
  CausticMapSettings cs;
  cs.seed = settings.seed;
  const long divisor = (CausticMap::Lobes(scene) & (kDeltaReflection | kDeltaTransmission)) != 0
                           ? 1
                           : kGlossyOnlyPhotonsDivisor;
  cs.target_photons =
      std::clamp(2L * cam.width() * cam.height(), kFewestCausticPhotons, kMostCausticPhotons) /
      divisor;
  cs.max_emitted = kCausticEmitRatio * cs.target_photons;
  return CausticMap::Build(scene, cs, arena, stats);
}
}  // namespace

std::unique_ptr<CausticMap> BuildCausticMap(const Scene& scene, const RenderSettings& settings,
                                            CausticMapStats* stats) {
  tbb::task_arena arena(RenderThreads(settings));
  return BuildCausticMap(scene, settings, arena, stats);
}

RenderOutput Render(const Scene& scene, const RenderSettings& settings, IrradianceCache* cache) {
  const Camera& cam = scene.camera();
  return RenderRect(scene, settings, cache, PixelRect{0, 0, cam.width(), cam.height()});
}

RenderOutput RenderRect(const Scene& scene, const RenderSettings& settings_in,
                        IrradianceCache* cache, const PixelRect& rect) {
  const auto start_time = std::chrono::steady_clock::now();
  RenderOutput out;
  const Camera& cam = scene.camera();
  const int rw = rect.width(), rh = rect.height();
  bool irrcache = settings_in.integrator == "irrcache";  // path where the pilot chooses it
  const int threads = RenderThreads(settings_in);
  tbb::task_arena arena(threads);
  // Caustics from a photon map (render/caustic_map.h), where the scene has a delta surface and an
  // area light and paths are unbounded (a bounded depth would cut photons' paths where
  // the records' would not be cut), unless the caller built it (BuildCausticMap: a job, once for
  // all of its tiles).
  RenderSettings settings = settings_in;
  // --target-error spaces records by Ward's split sphere: its error model, its coarsest cache and
  // its switch to the wider lookups were calibrated with it. With Hessian spacing (the default
  // elsewhere) it landed 18 of 18 in [E/2, 2E] on the nine shared scenes at full size (seed 7,
  // 2026-12-03), but just outside the band on a quarter-size scene and on mesh-lamps (the
  // TargetError tests).
  //
  // Likewise its records take no environment-map samples (IrrcacheSettings::environment_samples):
  // its cross-validation and stop rules were calibrated on records of strata alone. With them,
  // on the envmap rooms (bench/make_room.py 501-504, 511-513, 601, 602; both E, seeds 7-10) 69
  // of 72 renders landed in [E/2, 2E] against 72 of 72 before them: room-511 at 4e-3 stopped as
  // stalled at 2.3 E, room-602 at 4e-3 at its cost limit at 2.45 E, room-512 at 1e-3 just under
  // E/2; without them here, 71 of 72 (docs/bench/envmap-record-samples-2026-12-04/).
  if (settings.target_error > 0) {
    settings.irrcache.spacing = RecordSpacing::kSplitSphere;
    settings.irrcache.environment_samples = 0;
    settings.irrcache.linear_fit = false;  // Ward's weighted mean, as calibrated
  }
  std::unique_ptr<CausticMap> caustics;
  if (settings.irrcache.caustics == nullptr) {
    PhaseTimer timer("caustics");
    CausticMapStats cst;
    caustics = BuildCausticMap(scene, settings, arena, &cst);
    settings.irrcache.caustics = caustics.get();
    out.stats.caustic_photons = cst.stored;
    out.stats.caustic_photons_emitted = cst.emitted;
    if (cst.emitted > 0) out.stats.phases.push_back(timer.Stop());  // none: nothing to time
  }
  std::unique_ptr<IrradianceCache> own_cache;
  if (irrcache && !cache) {
    own_cache = std::make_unique<IrradianceCache>(CacheSettingsFor(scene, settings));
    cache = own_cache.get();
  }
  IrrcacheIntegrator integrator(scene, cache, settings.irrcache);
  out.image = Image(rw, rh);
  if (settings.aovs) out.aovs = AovImages(rw, rh);
  std::vector<uint8_t> marks(settings.record_map ? size_t(rw) * rh : 0);
  tbb::enumerable_thread_specific<RenderCounters> counters;
  const std::vector<Tile> tiles = MakeTiles(rect, settings.tile_size);
  const bool tty = settings.progress && isatty(STDERR_FILENO);

  // --target-error: the cache's accuracy is chosen for the error asked, then lowered until the
  // cross-validated cache error is at most half of it; the samples take the rest.
  IrrcacheSettings ic = settings.irrcache;
  double cache_error = -1;
  const char* cache_stop = nullptr;  // why the cache's refinement ended above its share
  double cache_budget_final = 0;
  // --target-error: the final pass's starting samples per pixel and the error asked of it.
  int final_min_spp = 0;
  double final_target_error = 0;
  // The pilot. At the defaults it balances the record rays and chooses the cache levels. A cache
  // that already holds records (--cache-in, the service's) keeps the settings' rays: the pilot's
  // records would mostly repeat what it has.
  //
  // --target-error: it chooses only the cache levels, where the settings leave them to the
  // renderer, from the one-level records' noise N1 (at the settings' rays R0) against the cache's
  // share. Two levels when one level would need more than the most rays (4 R0) to bring its noise
  // under half of that share (N1 > 2 x share); the two-level pilot's noise then gives the starting
  // rays. Measured (N1 at defaults): veach-ajar 2.2e-2 (one level ends at 0.2 against E = 4e-3:
  // its light comes through a door gap that few of a record's rays find); the other eight scenes
  // 4e-5 (room-b) to 6e-4 (specular), all one level even at E = 1e-3. And only where the records'
  // noise is what the image's error is made of (PrefersTwoLevels, the defaults' gate until
  // 2026-12-05):
  // living-room's N1 is above 2 x share, but its error is its glossy samples' (N1 / S1 0.97), and
  // two levels took it from 20 s to 300 s at E = 4e-3 for no lower error (2.4e-2 against 3.2e-2
  // at one level). And only where the two pilots' model predicts them cheaper (TwoLevelsPay, as
  // at defaults; since 2026-12-05): a still life's records are noisy but its second level costs
  // more than it saves (layered_kitchen at E = 4e-3: one level 16 s, two 110-250 s, the same
  // error).
  const bool target_mode = settings.target_error > 0;
  int pilot_rays = 0;       // target: the two-level pilot's starting rays, when it chose two levels
  uint64_t pilot_work = 0;  // its rays and lookups (RenderCounters::Work)
  if (irrcache && cache->size() == 0 &&
      (target_mode ? own_cache != nullptr && ic.choose_cache_levels && ic.cache_levels == 1
                   : ic.balance_record_rays)) {
    PhaseTimer timer("pilot");
    // Its own counters: its records are not the render's (they stay out of its cache).
    tbb::enumerable_thread_specific<RenderCounters> pilot_counters;
    BalanceResult b;
    if (!target_mode) {
      b = PilotSettings(scene, settings, rect, arena, pilot_counters, &ic);
    } else {
      const double cache_budget = 0.5 * settings.target_error;  // as the refinement starts
      IrrcacheSettings chosen = ic;
      b = PilotSettings(scene, settings, rect, arena, pilot_counters, &chosen, 2 * cache_budget);
      if (chosen.cache_levels == 2) {
        ic.cache_levels = 2;
        const double base = std::max(4, settings.irrcache.record_rays);
        // The records' noise at half of the share (two levels' error is mostly interpolation: on
        // veach-ajar at E = 1e-3 a quarter of it started at 4 R0 rays, and the rounds then
        // lowered only a, each at 4x the rays of a default render).
        pilot_rays =
            int(std::lround(std::clamp(base * b.record_noise / cache_budget, 128.0, 4 * base)));
        b.record_rays = pilot_rays;
      } else {
        b.record_rays = TargetRecordRays(settings.target_error, settings.irrcache.record_rays);
      }
    }
    for (const RenderCounters& c : pilot_counters) {
      b.pilot_records += long(c.records_computed);
      pilot_work += c.Work();
    }
    out.stats.balance = b;
    out.stats.balanced = true;
    if (!target_mode && settings.denoise && settings.choose_integrator) {
      const PathPilotFigures path = PathPilot(scene, settings, rect, arena, pilot_counters);
      const double pixels = double(rw) * rh;
      const int rays = settings.irrcache.record_rays;
      const DenoisedChoice choice =
          ChooseForDenoising(b, rays, path, pixels, settings.choose_integrator_min_pixels);
      out.stats.integrator_chosen = true;
      out.stats.path_pilot = path;
      out.stats.denoised_choice = choice;
      if (choice.path_pays) {
        settings.spp =
            PathSppForSeconds(choice.cache_seconds, path, pixels, std::max(1, settings.min_spp),
                              kMaxSppFactor * std::max(1, settings.spp));
        settings.integrator = "path";
        settings.adaptive = false;
        irrcache = false;
      }
    }
    out.stats.phases.push_back(timer.Stop());
  }
  if (irrcache) {
    PhaseTimer timer("overture");
    if (settings.target_error > 0) {
      RefinementStart start;
      start.target_error = settings.target_error;
      start.settings_rays = settings.irrcache.record_rays;
      start.settings_accuracy = settings.irrcache.accuracy;
      start.settings_min_spp = settings.min_spp;
      start.wider_factor = settings.irrcache.lookup_factor;
      // Only a cache this render made itself may be dropped (rebuilt coarser, or renewed for
      // more rays).
      start.may_rebuild = own_cache != nullptr && cache->size() == 0;
      start.pilot_rays = pilot_rays;
      start.cache_levels = ic.cache_levels;
      start.pilot_work = double(pilot_work);
      start.time_limit = settings.time_limit;
      CacheRefinement refinement(start);
      // The cache the refinement asks for next (after the last round: the one it ended with).
      const auto take_round_settings = [&] {
        ic.accuracy = refinement.accuracy();
        ic.record_rays = refinement.record_rays();
        ic.lookup_factor = refinement.lookup_factor();
      };
      take_round_settings();
      for (;;) {
        const uint64_t streams = uint64_t(refinement.streams());
        const IrrcacheIntegrator trial(scene, cache, ic);
        if (settings.overture)
          RunOverture(cam, trial, rect, settings.seed, streams, threads, tty, arena, counters,
                      &marks, settings.cancel);
        if (settings.Cancelled()) break;
        const CacheErrorEstimate estimate = EstimateCacheError(
            trial, ic.cache_levels, cam, settings.seed, streams, refinement.checks(), rect, arena,
            counters, refinement.other_factor());
        double sampling = 0;
        if (refinement.measures_sampling()) {
          sampling = EstimateSamplingError(
              trial, cam, settings.seed, TargetMinSpp(settings.target_error, settings.min_spp),
              std::max(1, ic.light_samples), settings.splat, rect, arena, counters);
        }
        const double elapsed =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
        uint64_t counted = pilot_work;
        for (const RenderCounters& c : counters) counted += c.Work();
        CacheRound round;
        const CacheRefinement::Next next =
            refinement.AfterRound(estimate, sampling, double(counted), elapsed, &round);
        out.stats.cache_rounds.push_back(round);
        take_round_settings();
        cache_error = refinement.cache_error();
        if (next == CacheRefinement::Next::kDone) break;
        if (next == CacheRefinement::Next::kRebuild || next == CacheRefinement::Next::kRenew) {
          RenderSettings coarse = settings;  // the cache's largest accuracy follows a
          coarse.irrcache.accuracy = ic.accuracy;
          own_cache = std::make_unique<IrradianceCache>(CacheSettingsFor(scene, coarse));
          cache = own_cache.get();
        }
      }
      cache_stop = refinement.stop_reason();
      cache_budget_final = refinement.cache_budget();
      final_min_spp = refinement.FinalMinSpp();
      final_target_error = refinement.FinalTargetError();
    } else if (settings.overture) {
      RunOverture(cam, IrrcacheIntegrator(scene, cache, ic), rect, settings.seed, 0, threads, tty,
                  arena, counters, &marks, settings.cancel);
    }
    out.stats.phases.push_back(timer.Stop());
    for (const RenderCounters& c : counters) out.stats.records_overture += c.records_computed;
  }
  const IrrcacheIntegrator final_integrator(scene, cache, ic);
  out.stats.estimated_cache_relmse = cache_error;
  RenderSettings final_settings = settings;
  final_settings.irrcache = ic;
  if (settings.target_error > 0) {
    final_settings.min_spp = final_min_spp;
    final_settings.target_error = final_target_error;
  }

  {
    PhaseTimer timer("render");
    FinalPass(scene, final_settings, final_integrator, rect, tty, arena, counters, &marks, &out,
              start_time);
    out.stats.phases.push_back(timer.Stop());
  }

  RenderStats& st = out.stats;
  st.cancelled = settings.Cancelled();
  for (const RenderCounters& c : counters) st.counters.Add(c);
  st.integrator = settings.integrator;
  st.width = rw;
  st.height = rh;
  st.spp = settings.spp;
  st.target_error = settings.target_error;
  const double estimate = st.estimated_sampling_relmse + std::max(0.0, cache_error);
  if (cache_stop && estimate > settings.target_error) {
    // Said, not hidden: the estimate in the stats is the render's, not the error asked.
    char text[256];
    std::snprintf(text, sizeof text,
                  "--target-error %.3g not reached: estimated relMSE %.3g, the cache's %.3g "
                  "(its share %.3g; refinement stopped: %s)",
                  settings.target_error, estimate, cache_error, cache_budget_final, cache_stop);
    st.warnings.push_back(text);
  }
  st.threads = threads;
  st.seed = settings.seed;
  st.tiles = int(tiles.size());
  st.tile_size = settings.tile_size;
  if (irrcache) {
    st.accuracy = ic.accuracy;
    st.record_rays = final_integrator.strata_theta() * final_integrator.strata_phi();
    st.strata_theta = final_integrator.strata_theta();
    st.strata_phi = final_integrator.strata_phi();
    st.light_samples = settings.irrcache.light_samples;
    st.cache_levels = ic.cache_levels;
    st.min_spacing_px = settings.irrcache.min_spacing_px;
    st.max_spacing_px = settings.irrcache.max_spacing_px;
    st.lookup_factor = ic.lookup_factor;
    st.spacing = RecordSpacingName(ic.spacing);
    st.interpolation = ic.linear_fit && !(settings.target_error > 0) ? "linear" : "ward";
    st.records_in_cache = cache->size();
  }
  double m[3] = {0, 0, 0};
  for (const Vec3& p : out.image.pixels) {
    if (!IsFinite(p)) ++st.nonfinite_pixels;
    for (int k = 0; k < 3; ++k) m[k] += p[k];
  }
  const double n = double(out.image.pixels.size());
  st.mean_rgb = Vec3(float(m[0] / n), float(m[1] / n), float(m[2] / n));
  if (settings.record_map) {
    out.record_map = out.image;
    for (size_t i = 0; i < marks.size(); ++i)
      out.record_map.pixels[i] = marks[i] ? Vec3(1e3f, 0, 0) : out.record_map.pixels[i] * 0.5f;
  }
  return out;
}

}  // namespace irfarm
