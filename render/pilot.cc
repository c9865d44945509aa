#include "render/pilot.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <vector>

#include "render/final_pass.h"
#include "render/path_tracer.h"
#include "render/pixel_sampler.h"
#include "render/render_stats.h"
#include "render/render_streams.h"
#include "render/sample_film.h"

namespace irfarm {
namespace {

// A random pixel of `rect` (two draws of rng).
void RandomPixel(const PixelRect& rect, Rng& rng, int* x, int* y) {
  *x = rect.x0 + std::min(rect.width() - 1, int(rng.Next() * float(rect.width())));
  *y = rect.y0 + std::min(rect.height() - 1, int(rng.Next() * float(rect.height())));
}

// Camera sample s of pixel (x, y) as the final pass takes it unsplatted: its film point from
// `points`, its lens point (thinlens) from rng.
Ray PixelRay(const Camera& cam, int x, int y, const PixelSampler& points, int s, Rng& rng) {
  float fu, fv;
  points.Get(s, &fu, &fv);
  return cam.SampleRay(cam.SampleDirection(x, y, fu, fv), rng);
}

// `spp` camera samples of pixel (x, y) taken as the final pass takes them (stratified film and
// light points, one lookup region for the pixel), added to slot i of `film`. A non-finite sample
// adds 0 here: the final pass, which renders the pixel again, counts it.
void SamplePixel(const IrrcacheIntegrator& integrator, const Camera& cam, int x, int y, int spp,
                 int light_samples, Rng& rng, RenderCounters& c, SampleFilm* film, size_t i) {
  PixelSampler film_points(spp, rng), light_points(spp * light_samples, rng);
  PixelReuse reuse;
  for (int s = 0; s < spp; ++s) {
    const Ray ray = PixelRay(cam, x, y, film_points, s, rng);
    IrrcacheShade shade;
    shade.reuse = &reuse;
    DirectTerms terms;
    Vec3 L =
        integrator.Li(ray, LightStrata{&light_points, s * light_samples}, rng, c, &shade, &terms);
    if (!IsFinite(L) || !terms.Finite()) {  // left out, as the final pass does
      L = Vec3();
      terms = DirectTerms{};
    }
    film->Add(i, s, L, &terms);
  }
}

// The pilot of record_balance.h: kPilotPixels random pixels of `rect`, each a record and
// kPilotSamples camera samples, timed apart, all on a scratch cache that is then dropped. The
// pilot's records do not go into the render's cache: placed at random pixels before the
// overture's coarse-to-fine grid, they made cornell-box worse (seed 7: relMSE 2.5e-4 -> 9.4e-4,
// a blotch by the lamp; 2.5e-4 again with the same pilot kept apart). They are made with a
// quarter of the rays (their noise and time scaled back to the settings' rays: noise ~ 1 / rays,
// time ~ rays), so the pilot costs about 64 records of the render's.
// With time_cap > 0, pixels not yet started once the pilot's thread time has passed time_cap are
// skipped, and the result is `capped` (its figures are not to be used).
BalanceResult BalanceRecordRays(const Scene& scene, const RenderSettings& settings,
                                const PixelRect& rect, tbb::task_arena& arena,
                                tbb::enumerable_thread_specific<RenderCounters>& counters,
                                double time_cap = 0) {
  constexpr int kPilotPixels = 256, kPilotSamples = 16;
  const Camera& cam = scene.camera();
  const int light_samples = std::max(1, settings.irrcache.light_samples);
  PilotFigures pilot;
  pilot.samples = kPilotSamples;
  pilot.pixels.resize(kPilotPixels);
  std::vector<IrrcacheIntegrator::PilotRecord> records(kPilotPixels);
  std::vector<double> record_seconds(kPilotPixels, 0), sample_seconds(kPilotPixels, 0);
  // Thread CPU time, not wall time: under load a wall-clock interval also holds the time the
  // thread waited for the CPU, and the rays chosen varied with it (veach-ajar at quarter size,
  // two CPU-bound processes beside: the two-level image 0.006 to 0.017).
  IrradianceCache scratch(CacheSettingsFor(scene, settings));
  const IrrcacheIntegrator full(scene, &scratch, settings.irrcache);
  IrrcacheSettings quarter = settings.irrcache;
  quarter.record_rays = std::max(96, settings.irrcache.record_rays / 4);
  const IrrcacheIntegrator integrator(scene, &scratch, quarter);
  // Rays the strata actually trace, at the settings' count and at the pilot's.
  const double rays_scale =
      double(full.strata_theta() * full.strata_phi()) /
      double(std::max(1, integrator.strata_theta() * integrator.strata_phi()));
  SampleFilm film(kPilotPixels, integrator.ratio_slots());
  std::atomic<int64_t> spent_ns{0};  // the pixels' thread time so far
  std::atomic<bool> capped{false};
  arena.execute([&] {
    tbb::parallel_for(0, kPilotPixels, [&](int i) {
      if (time_cap > 0 && double(spent_ns.load(std::memory_order_relaxed)) * 1e-9 > time_cap) {
        capped.store(true, std::memory_order_relaxed);
        return;
      }
      RenderCounters& c = counters.local();
      Rng rng(HashCombine(settings.seed, uint64_t(i)), kStreamPilot);
      int x, y;
      RandomPixel(rect, rng, &x, &y);
      const double t0 = ThreadCpuSeconds();
      const Ray centre = cam.PinholeRay(cam.Direction(x + 0.5f, y + 0.5f));
      pilot.pixels[size_t(i)].has_record = integrator.Pilot(centre, rng, c, &records[size_t(i)]);
      if (pilot.pixels[size_t(i)].has_record) scratch.Insert(records[size_t(i)].record);
      const double t1 = ThreadCpuSeconds();
      const double made_before = c.record_seconds;
      SamplePixel(integrator, cam, x, y, kPilotSamples, light_samples, rng, c, &film, size_t(i));
      record_seconds[size_t(i)] = t1 - t0;
      // Records the samples made (glossy paths reaching new surfaces) count as record time.
      const double made = c.record_seconds - made_before;
      sample_seconds[size_t(i)] = std::max(0.0, ThreadCpuSeconds() - t1 - made);
      record_seconds[size_t(i)] += made;
      spent_ns.fetch_add(int64_t((ThreadCpuSeconds() - t0) * 1e9), std::memory_order_relaxed);
    });
  });
  if (capped.load()) {
    BalanceResult r;
    r.record_rays = settings.irrcache.record_rays;
    r.pilot_seconds = double(spent_ns.load()) * 1e-9;
    r.capped = true;
    return r;
  }
  for (int i = 0; i < kPilotPixels; ++i) {
    PilotPixel& px = pilot.pixels[size_t(i)];
    px.sampling_error =
        film.RelativeError(size_t(i)) * (settings.splat ? cam.filter().SplatVarianceFactor() : 1.0);
    pilot.sample_seconds += sample_seconds[size_t(i)];
    pilot.sample_count += kPilotSamples;
    pilot.record_seconds += record_seconds[size_t(i)] * rays_scale;
    if (!px.has_record) continue;
    ++pilot.records;
    const IrrcacheIntegrator::PilotRecord& r = records[size_t(i)];
    const Vec3 v = film.Value(size_t(i));
    double n = 0;
    for (int ch = 0; ch < 3; ++ch)
      n += double(r.weight[ch]) * r.weight[ch] * r.irradiance_variance[ch] /
           (double(v[ch]) * v[ch] + 0.01);
    px.record_noise = n / 3 / rays_scale;
    const double fp = std::max(1e-3, double(r.footprint_px));
    px.records_per_px = 1 / (kPi * fp * fp);
  }
  BalanceInputs in;
  in.record_rays = settings.irrcache.record_rays;
  in.image_pixels = double(rect.width()) * rect.height();
  in.adaptive = settings.adaptive && settings.spp > 2;
  in.min_spp = settings.min_spp;
  in.max_spp = settings.spp;
  in.sampling_goal = settings.sampling_error;
  BalanceResult r = ChooseRecordRays(pilot, in);
  r.pilot_seconds = double(spent_ns.load()) * 1e-9;
  return r;
}

}  // namespace

// The sampling error the final pass will estimate after its first round: `spp` samples at each
// of kSamplingChecks random pixels, averaged as FinalPass averages SampleFilm::RelativeError and
// scaled by what splatting saves (PixelFilter::SplatVarianceFactor)
// (the same estimator at the same spp, so its bias at low spp is the same). Per-pixel errors
// are heavy-tailed (a rare bright sample), so many pixels with few samples: 4096 pixels are 5%
// of a 320 x 240 image.
double EstimateSamplingError(const IrrcacheIntegrator& integrator, const Camera& cam, uint64_t seed,
                             int spp, int light_samples, bool splat, const PixelRect& rect,
                             tbb::task_arena& arena,
                             tbb::enumerable_thread_specific<RenderCounters>& counters) {
  constexpr int kSamplingChecks = 4096;
  SampleFilm film(kSamplingChecks, integrator.ratio_slots());
  arena.execute([&] {
    tbb::parallel_for(0, kSamplingChecks, [&](int i) {
      Rng rng(HashCombine(seed, uint64_t(i)), kStreamSamplingCheck);
      int x, y;
      RandomPixel(rect, rng, &x, &y);
      SamplePixel(integrator, cam, x, y, spp, light_samples, rng, counters.local(), &film,
                  size_t(i));
    });
  });
  double sum = 0;
  for (int i = 0; i < kSamplingChecks; ++i) sum += film.RelativeError(size_t(i));
  // These pixels keep their own samples; the final pass splats (PixelFilter).
  return sum / kSamplingChecks * (splat ? cam.filter().SplatVarianceFactor() : 1.0);
}

BalanceResult PilotSettings(const Scene& scene, const RenderSettings& settings,
                            const PixelRect& rect, tbb::task_arena& arena,
                            tbb::enumerable_thread_specific<RenderCounters>& counters,
                            IrrcacheSettings* ic, double two_levels_above) {
  BalanceResult b = BalanceRecordRays(scene, settings, rect, arena, counters);
  ic->record_rays = b.record_rays;
  if (!settings.irrcache.choose_cache_levels || settings.irrcache.cache_levels != 1) return b;
  b.cache_levels = 1;
  b.one_level_record_noise = b.record_noise;
  b.one_level_sampling_error = b.sampling_error;
  const bool target = two_levels_above > 0;
  if (target ? !PrefersTwoLevels(b) || b.record_noise <= two_levels_above : !MayPreferTwoLevels(b))
    return b;
  RenderSettings two = settings;
  two.irrcache.cache_levels = 2;
  // The two-level pilot's secondary records, and those of them one ray made (ThreeLevelsPay).
  const auto total = [&counters] {
    RenderCounters t;
    for (const RenderCounters& c : counters) t.Add(c);
    return t;
  };
  const RenderCounters before = total();
  BalanceResult b2 =
      BalanceRecordRays(scene, two, rect, arena, counters,
                        settings.irrcache.two_level_pilot_cost_cap * b.pilot_seconds);
  const RenderCounters after = total();
  if (b2.capped) {  // two levels would cost what their pilot did: one level
    b.two_level_pilot_capped = true;
    return b;
  }
  const uint64_t made = after.records_secondary - before.records_secondary;
  const uint64_t heavy = after.records_secondary_heavy - before.records_secondary_heavy;
  b.secondary_heavy_share = made > 0 ? double(heavy) / double(made) : 0.0;
  if (!TwoLevelsPay(b, b2, settings.irrcache.record_rays)) return b;
  b2.cache_levels = 2;
  b2.one_level_record_noise = b.record_noise;
  b2.one_level_sampling_error = b.sampling_error;
  b2.secondary_heavy_share = b.secondary_heavy_share;
  ic->cache_levels = 2;
  ic->record_rays = b2.record_rays;
  // --target-error keeps at most two: its refinement was calibrated with them.
  if (!target && ThreeLevelsPay(made, heavy, settings.irrcache.accuracy)) {
    b2.cache_levels = ic->cache_levels = 3;
    b2.record_rays = ic->record_rays =
        ThreeLevelsRecordRays(b2.record_rays, settings.irrcache.record_rays);
  }
  return b2;
}

PathPilotFigures PathPilot(const Scene& scene, const RenderSettings& settings,
                           const PixelRect& rect, tbb::task_arena& arena,
                           tbb::enumerable_thread_specific<RenderCounters>& counters) {
  // Four times the cache pilot's pixels (BalanceRecordRays), at its samples: about 16,000 path
  // samples, 55 ms of one thread on living-room (0.2% of its render). Its per-sample error varied
  // 2.2x over six seeds there with 256 pixels.
  constexpr int kPathPilotPixels = 1024, kPathPilotSamples = 16;
  const Camera& cam = scene.camera();
  const PathSettings path = PathIntegratorSettings(scene, settings);
  SampleFilm film(kPathPilotPixels, 0);
  std::vector<double> seconds(kPathPilotPixels, 0);
  arena.execute([&] {
    tbb::parallel_for(0, kPathPilotPixels, [&](int i) {
      RenderCounters& c = counters.local();
      Rng rng(HashCombine(settings.seed, uint64_t(i)), kStreamPathPilot);
      int x, y;
      RandomPixel(rect, rng, &x, &y);
      PixelSampler film_points(kPathPilotSamples, rng);
      const double t0 = ThreadCpuSeconds();
      for (int s = 0; s < kPathPilotSamples; ++s) {
        const Ray ray = PixelRay(cam, x, y, film_points, s, rng);
        Vec3 L = TracePath(scene, ray, 1, false, path, rng, c, nullptr, nullptr);
        if (!IsFinite(L)) L = Vec3();  // as SamplePixel: the final pass counts it
        film.Add(size_t(i), s, L, nullptr);
      }
      seconds[size_t(i)] = ThreadCpuSeconds() - t0;
    });
  });
  std::vector<double> errors(kPathPilotPixels);
  double total_seconds = 0;
  const double splat = settings.splat ? cam.filter().SplatVarianceFactor() : 1.0;
  for (int i = 0; i < kPathPilotPixels; ++i) {
    errors[size_t(i)] = film.RelativeError(size_t(i)) * splat * kPathPilotSamples;
    total_seconds += seconds[size_t(i)];
  }
  PathPilotFigures f;
  f.per_sample_error = TrimmedMean(std::move(errors));
  f.seconds_per_sample = total_seconds / double(kPathPilotPixels * kPathPilotSamples);
  return f;
}

}  // namespace irfarm
