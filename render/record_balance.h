// Balancing the irradiance cache's record rays against the camera samples, at default settings.
//
// A default irrcache image has two errors: the cache's (interpolation, plus the noise of each
// record's hemisphere estimate, which falls as 1 / rays) and the camera samples' (direct light,
// glossy and specular paths, anti-aliasing). Where records dominate the time and the samples the
// error - a real interior full of glass, metal and rough plastic - rays spent on records buy
// nothing; in a diffuse room the records' noise is a visible part of the error. The renderer
// therefore measures, before the overture, on a pilot of random pixels: the relative noise a
// record made with the settings' rays leaves in the pixel, the sampling error of that pixel's
// camera samples, and the time of each; and picks the rays that minimise error x time (the cost
// at which a given error is reached).
//
// Model (per pixel of the image, relMSE units): error(R) = I + N R0 / R + S, time(R) = C R / R0 +
// D, with N the record noise at R0 rays, I the interpolation error, S the sampling error at the
// samples adaptive sampling is expected to take, C the records' time at R0 and D the samples'.
// d(error x time)/dR = 0 gives R* = R0 sqrt(N / (I + S) * D / C). I is not measured by the pilot
// (it needs a filled cache) and is taken as kInterpolationFloor N. R* is kept within [R0 / 8, R0]:
// the balance only ever lowers the rays.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace irfarm {

// One pilot pixel: a record made at its first diffuse hit with R0 rays, and `samples` camera
// samples of the pixel rendered with the cache (the record now in it).
struct PilotPixel {
  bool has_record = false;
  double record_noise = 0;    // the record's noise in the pixel: w^2 Var(E) / (v^2 + 0.01)
  double records_per_px = 0;  // 1 / (pi footprint^2): records per pixel its validity area implies
  double sampling_error = 0;  // the pixel's estimated relMSE from its `samples` camera samples
};

struct PilotFigures {
  std::vector<PilotPixel> pixels;
  int samples = 0;            // camera samples per pilot pixel
  double record_seconds = 0;  // thread time of the pilot records
  int records = 0;            // pilot records made
  double sample_seconds = 0;  // thread time of the pilot camera samples (records they made out)
  long sample_count = 0;      // pilot camera samples
};

struct BalanceInputs {
  int record_rays = 1536;  // R0: the settings' rays
  double image_pixels = 0;
  // Adaptive sampling as the final pass will run it.
  bool adaptive = true;
  int min_spp = 16, max_spp = 64;
  double sampling_goal = 1e-4;
};

struct BalanceResult {
  int record_rays = 0;          // the rays chosen
  double record_noise = 0;      // N: the records' noise in the image at R0 (relMSE)
  double sampling_error = 0;    // S: the final pass's expected sampling error (relMSE)
  double expected_spp = 0;      // the final pass's expected mean samples per pixel
  double record_seconds = 0;    // C: the records' expected thread time at R0
  double sampling_seconds = 0;  // D: the camera samples' expected thread time
  long pilot_records = 0;       // records the pilot made (set by the renderer; not kept)
  // Set by the renderer when it chose the cache levels (IrrcacheSettings::choose_cache_levels):
  // the levels chosen, and the one-level pilot's figures that decided it.
  int cache_levels = 0;
  double one_level_record_noise = 0, one_level_sampling_error = 0;
  // The two-level pilot's share of secondary records with one ray bringing more than
  // kHeavyRayShare of their sum (ThreeLevelsPay); -1 where no two-level pilot ran.
  double secondary_heavy_share = -1;
  // This pilot's own thread time (its records and camera samples, unscaled).
  double pilot_seconds = 0;
  // The pilot stopped at its time cap (BalanceRecordRays) before all its pixels were done: its
  // figures are not to be used. For a render: whether the two-level pilot did.
  bool capped = false;
  bool two_level_pilot_capped = false;
};

// Records per pixel, as a factor on the plain tiling by the pilot records' validity areas
// (1 / (pi footprint^2) each): the overture's records overlap (a pixel needs a record whose
// validity sphere reaches it, and neighbour clamping shrinks radii). Checked against the records'
// measured thread time on the ten shared scenes (128-pixel pilot at full rays): predicted within
// 0.9-1.1x on cornell-box, veach-ajar, room-c and living-room, up to 2x high on thin-panels,
// room-a, room-b and room-d (a high C can only lower R*).
constexpr double kRecordOverlap = 4.0;

// Share of the pilot's pixels with the largest sampling error left out of S (fireflies).
constexpr double kTrimmed = 0.02;

// The interpolation error I as a share of the pilot's record noise N. Measured at default levels
// by rendering each shared scene at 1536 and 384 fixed rays (seeds 7 and 8): the image's record
// noise from the difference, and what remains at 1536 rays (I plus the samples' error) against
// the pilot's N: veach-ajar 1.0-1.6, sunlit-room 1.9-2.1, room-a 1.8-2.8, living-room about 2,
// room-d 2.6-4.0, room-c 4.5-5.6, specular 7.6-8.2, cornell-box 11-14, room-b 12-14, thin-panels
// 23-33. Taking I = 0 (as until 2026-12-02) kept 1536 rays wherever the pilot's S is near 0 (a
// room lit by rectangles, whose direct light has no noise outside penumbrae), and on cornell-box
// made R* follow S, which 256 pilot pixels measure only within 10x (3.7e-6 to 4.2e-5 over seeds
// 7-14): 257 to 1202 rays, 1.5 to 5.1 s. Error x wall time at defaults, mean of seeds 7 and 8,
// factor 0.5 against 0: room-a 0.42x, room-b 0.44x, sunlit-room 0.47x, thin-panels 0.37x, room-c
// 0.65x, room-d 0.69x, specular 0.73x, living-room 0.88x; seeds 9-11 alike on the first five
// (0.41-0.97x), room-d and specular 0.92-1.06x; veach-ajar 1.09x over seeds 7-11 (its error is its
// records' noise at the door gap), cornell-box 1.04x over seeds 7-14 (with
// IrrcacheSettings::occluder_plane; rays 192 to 592). Factor 1 was worse than 0.5 on 6 of 10 scenes
// (cornell-box 1.27x, room-c 1.21x, specular 1.28x).
constexpr double kInterpolationFloor = 0.5;

// R* as the model above gives it, from the pilot's figures.
BalanceResult ChooseRecordRays(const PilotFigures& pilot, const BalanceInputs& in);

// The mean of `values` without their largest kTrimmed share (at least one value is kept); 0 for
// none.
double TrimmedMean(std::vector<double> values);

// Cache levels at default settings. A second level (records' rays shaded from a cache of
// secondary records at the surfaces they reach, IrrcacheSettings::cache_levels) smooths the
// records' noise and makes them cheaper, but adds secondary records, which pay off only where the
// records' noise is what the image's error is made of. So two levels when the one-level pilot's
// record noise N is above kTwoLevelsNoiseRatio times its expected sampling error S. Measured at
// defaults, one level against two (relMSE, wall seconds; N / S from the pilot):
//   veach-ajar 2.2e-2 / 4.8e-3, 6.8 / 4.5 s (N/S 221); sunlit-room 3.9e-4 / 2.2e-4, 3.9 / 4.1 s
//   (2500); room-b 4.7e-5 / 2.7e-5, 2.0 / 2.9 s (1200); specular 1.11e-3 / 9.7e-4, 6.6 / 5.2 s
//   (6.4); thin-panels 4.5e-4 / 3.5e-4, 4.4 / 4.9 s; cornell-box 2.6e-4 / 2.3e-4, 3.8 / 2.0 s;
//   room-a 5.1e-4 / 5.2e-4, 7.6 / 6.0 s; room-c 3.4e-4 / 3.5e-4, 4.1 / 3.4 s (6.7); and where two
//   levels lose: room-d 4.8e-4 / 5.4e-4 (N/S 1.15) and living-room 2.9e-2 in 21 s / 3.1e-2 in
//   34 s (0.97: its rough plastic, metal and glass make the samples' error).
// Again at 46c3e93 (docs/bench/cache-levels-2026-12-04, seeds 7-9, 21 scenes with the unseen
// rooms): two levels are no worse in error x time on 18 of 21, within 2% on room-c and room-201,
// room-d now even (0.98); room-226 1.13 (the pilot picks two there); living-room still loses
// (same error in 13.5 s against 10 s; its N/S 0.48-1.01 over seeds 7-12). The pilot's S varies
// up to 7x between seeds (a few percent of the pixels carry it), so room-221 (two levels 17%
// better) had N/S 1.0-6.7 and got two levels on only 2 of 6 seeds at a ratio of 3; the mesh-lamp
// rooms 301 and 302 (N/S 1.3-2.3, two levels 0.85 and 0.75 in error x time) never did. At 1.5,
// defaults against 3, seeds 7-9 (lvcmp.txt): error x time room-221 0.94, room-301 0.90, room-302
// 0.81, room-d 0.94, room-c 1.02, living-room 1.00 (one level on every seed).
// --target-error gates the second pilot by this ratio (and by the records' noise against the
// cache's share, renderer.cc), then, since 2026-12-05, takes two levels only where TwoLevelsPay
// agrees, as the defaults do (docs/bench/target-renew-2026-12-05/: layered_kitchen at E = 4e-3
// 0.92 E in 16 s with one level, against 0.94-0.98 E in 110-250 s with the two the ratio chose;
// one level needed the cache's renewal, CacheRefinement::Next::kRenew, to get there). The
// defaults use it only as the gate to a second pilot, below.
constexpr double kTwoLevelsNoiseRatio = 1.5;
inline bool PrefersTwoLevels(const BalanceResult& one_level) {
  return one_level.record_noise > kTwoLevelsNoiseRatio * one_level.sampling_error;
}

// The defaults, since 2026-12-05: the ratio alone gave two levels to a still life (Mitsuba's
// layered_kitchen; N/S 2.1-3.2) where they lose 1.45-1.6x in error x time (15,000 secondary
// records for 8,000 primary ones in a cluttered scene), and one level to rooms where two win
// (make_room 504 and 602, N/S 1.1-1.2: 0.70-0.80x). Both pilots' figures tell: the model's
// error x time at each pilot's chosen rays, PredictedErrorTime, with the two-level pilot's record
// time C including the secondary records its records made. So a second pilot wherever the records'
// noise is at least the samples' error (N > kTwoLevelsPilotRatio S; below that, on living-room and
// a glossy shoe scene, two levels lose and the second pilot would cost 7% of the render), and two
// levels when the model predicts them cheaper (TwoLevelsPay). The model does not see the second
// level's own interpolation error, so it is optimistic for two levels: over 27 scenes (the shared
// nine, living-room, 17 unseen rooms and two Mitsuba scenes; seeds 7 and 8, forced one and two
// levels, docs/bench/cache-levels-model-2026-12-05) its ratio two / one was 0.02-0.99 wherever
// two levels measured 0.18-0.94, 1.16-1.41 on room-c (measured 0.95-1.08), 1.22-2.63 where they
// lose (living-room 1.20-1.25, the kitchen 1.45-1.62, the shoes 1.14-1.20), and 0.05-0.06 on the
// one miss, room-503 (measured 1.03-1.11).
// Since later on 2026-12-06 the gate is 0.5, with the second pilot capped in time
// (IrrcacheSettings::two_level_pilot_cost_cap): make_room 961 (a closed glossy room lit by bulbs;
// N/S 0.57-0.85) and specular (0.74-0.93) flipped between one level and two with the seed, and two
// are 1.3x and 1.1-1.2x better in error x time there (docs/bench/two-level-gate-2026-12-06).
constexpr double kTwoLevelsPilotRatio = 0.5;
inline bool MayPreferTwoLevels(const BalanceResult& one_level) {
  return one_level.record_noise > kTwoLevelsPilotRatio * one_level.sampling_error;
}

// The model's error x time at the rays a pilot chose (ChooseRecordRays): error = I + N R0 / R + S,
// time = C R / R0 + D, with R0 = `settings_rays`. 0 where the pilot measured nothing.
inline double PredictedErrorTime(const BalanceResult& b, int settings_rays) {
  const double r0 = std::max(1, settings_rays), r = std::max(1, b.record_rays);
  const double error =
      kInterpolationFloor * b.record_noise + b.record_noise * r0 / r + b.sampling_error;
  const double time = b.record_seconds * r / r0 + b.sampling_seconds;
  return error * time;
}

// Two cache levels when the two-level pilot's figures predict a lower error x time than the
// one-level pilot's; never when either pilot measured nothing to go on.
inline bool TwoLevelsPay(const BalanceResult& one_level, const BalanceResult& two_levels,
                         int settings_rays) {
  const double one = PredictedErrorTime(one_level, settings_rays);
  const double two = PredictedErrorTime(two_levels, settings_rays);
  if (!(one > 0) || !(two > 0) || !(two_levels.record_seconds > 0)) return false;
  return two < one;
}

// Three cache levels: the second level's records' rays shaded from a third level's records, as
// RADIANCE caches every ambient bounce. Where light reaches the second level's records through a
// narrow opening (veach-ajar: through the door gap, two or three bounces down their paths), each
// of them is made of a few lucky rays, and the primary records that average them inherit that
// noise as blotches a few hundred pixels wide, different in every render. A third level gives
// their rays records to average in turn. It is chosen where the two-level pilot's secondary
// records are mostly such: more than kThreeLevelsHeavyShare of them have one ray bringing more
// than kHeavyRayShare of their sum. Measured at seed 7, seeds 7-9 for veach-ajar
// (docs/bench/three-levels-2026-12-06/): veach-ajar 63-66% of them; room-242 (a photographed sky
// through a window) 36%; living-room's pilot 27% (one level is chosen there); at most 6% on
// cornell-box, room-a, room-b, room-d, sunlit-room, thin-panels and rooms 221-225, 241 and 244.
// Three levels against two, forced, at the pilot's rays: veach-ajar (seeds 103-114) relMSE
// 6.8e-3 against 1.03e-2 mean, 9.5e-3 against 2.4e-2 worst, for 13% more CPU; on the other
// scenes above (seeds 7-9) error x time 0.97-1.07 (room-242 1.00).
// Only at the default accuracy or finer (kThreeLevelsMaxAccuracy): at coarse accuracies the
// third level's records are few and wide, and on veach-ajar (indirect only, the default run's
// rays, means of seeds 7-9) three levels then came out erratic, 7.5e-3 to 4.6e-2 at a = 0.2 and
// 1.4e-2 to 5.4e-2 at a = 0.3 in two runs, where two levels gave 1.5e-2 and 1.4e-2; at a <= 0.1
// three levels were the lower (4.3e-3 to 6.7e-3 against 4.9e-3 to 9.4e-3).
constexpr double kHeavyRayShare = 0.4;
constexpr double kThreeLevelsHeavyShare = 0.25;
constexpr float kThreeLevelsMaxAccuracy = 0.1f;  // as IrrcacheSettings::accuracy, a float
inline bool ThreeLevelsPay(uint64_t secondary_records, uint64_t heavy_records, float accuracy) {
  return secondary_records > 0 && accuracy <= kThreeLevelsMaxAccuracy &&
         double(heavy_records) > kThreeLevelsHeavyShare * double(secondary_records);
}

// Record rays with three levels: at least kThreeLevelsMinRayShare of the settings' rays (R0). The
// balance's model takes a record's noise as its pilot variance, falling as 1 / R; where three
// levels are chosen, the secondary records are mostly one lucky ray's light (a door gap), their
// noise is heavy-tailed, and a render at the balance's rays is sometimes far off, a whole region
// too bright or too dark (one secondary record feeds many primary ones). The pilot also times its
// records in an almost empty cache, where each makes its own secondary records (veach-ajar: about
// five each, against 1.3 in the render): its record time was twice the render's there.
// Forced rays, three levels, veach-ajar seeds 3, 5, 8 (docs/bench/three-level-rays-2026-12-06):
// 384 and 512 rays 4.8e-3 to 1.5e-2; 768 rays 3.5e-3 to 3.8e-3; 1024 and 1536 3.0e-3 to 4.6e-3 for
// 1.3x and 1.9x the CPU of 768. At defaults, before and after, alternately: veach-ajar (seeds 1-8)
// relMSE 4.2e-3 mean, 7.0e-3 worst, against 8.2e-3 and 1.8e-2, for 1.72x the CPU (error x time
// 0.87x); room-242 (a photographed sky through a window; seeds 7-15, the balance chose 505-773
// rays there) 4.44e-4 against 4.59e-4 for 1.13x the CPU (error x time 1.09x, its reference's own
// error 2.25e-4 included); veach-ajar at 640 x 360 (seeds 7-10, box-filtered to the reference's
// size) 2.7e-3 mean, 2.9e-3 worst, against 3.9e-3 and 4.9e-3 for 1.51x the CPU (1.06x).
constexpr double kThreeLevelsMinRayShare = 0.5;
inline int ThreeLevelsRecordRays(int chosen, int settings_rays) {
  return std::max(chosen, int(std::lround(kThreeLevelsMinRayShare * settings_rays)));
}

// A path tracer instead of the cache, for an image that will be denoised (`irfarm render
// --denoise` without --integrator). A denoiser removes most of a path-traced image's noise but
// little of an irradiance cache's own error, records' noise (blotches a few pixels wide that look
// like detail) and interpolation: denoised relMSE / raw relMSE, irrcache defaults against path at
// 64 spp (docs/denoise/summary-2026-12-06-57a2d88.txt): irrcache 1.00-1.40 on the ten shared
// scenes, path 5.1 (room-c) to 168 (veach-ajar). So the denoised errors are taken as
//   cache: I + N R0 / R + S / g,   path at the cache's time: P / g,
// (the model of ChooseRecordRays; P from the path pilot), and path is chosen where P / g is the
// smaller: P - S < g (I + N R0 / R). g = kDenoiserGain is fitted, not measured: the model's I and
// N are the pilot's, and the pilots leave the largest 2% of pixels' errors out of P and S. The
// figures with --denoise, full size, seeds 1-8 (docs/bench/path-when-denoised-2026-12-06):
// (P - S) / (I + N R0 / R) was 0.53-1.35 on living-room, where path with the denoiser measured
// 7.0e-3 to 8.3e-3 in 25-41 CPU seconds against the cache's 1.13e-2 to 1.40e-2 in 26-30; 2.7-7.4
// on materials (tests/data: glass and metal spheres), where the cache was the better (6.3e-4 to
// 7.2e-4 in 8-10 s against path's 8.1e-4 to 8.4e-4 in 7-10 s). g = 2 lies between the two
// (1.5x above living-room's largest, 1.35x below materials' smallest). Seeds 7 and 8 (the same
// run): 11-23 on specular, 17-21 on a glossy room lit by a sun (make_room 907, where path at 32
// spp would have been 1.17x lower in the same time), 9-460 on four other fresh rooms, above 20 on
// the other shared scenes.
constexpr double kDenoiserGain = 2.0;

// The smallest image (pixels) for which path is chosen: the figures above are of images of 49,000
// and 58,000 pixels. On materials at a quarter of that (64 x 48), (P - S) / (I + N R0 / R) came
// out at 0.6-1.8, and path with the denoiser at 1.8e-3 to 2.4e-3 against the cache's 1.4e-3 to
// 1.9e-3 (seeds 1-4, reference-x4): the denoiser has less of the image to work with.
constexpr int kPathChoiceMinPixels = 32768;

// The path pilot (pilot.cc): camera samples of random pixels traced as the path integrator
// traces them.
struct PathPilotFigures {
  double per_sample_error = 0;    // a pixel's relMSE at one sample (TrimmedMean over the pixels)
  double seconds_per_sample = 0;  // thread time
};

// The errors ChooseForDenoising compares, from the two pilots: relMSE of the image, raw.
struct DenoisedChoice {
  double cache_seconds = 0;   // the cache's predicted thread time: C R / R0 + D
  double cache_own = 0;       // I + N R0 / R: what the denoiser leaves of the cache's error
  double cache_sampling = 0;  // S
  double path = 0;            // P: path's error in cache_seconds
  double image_pixels = 0, min_pixels = 0;
  bool path_pays = false;  // P - S < kDenoiserGain x cache_own, image_pixels >= min_pixels
};

// The choice for a denoised image between the cache the pilot chose (`cache`, its figures at
// `settings_rays`) and path, over an image of `image_pixels`. Never path when either pilot
// measured nothing, nor for an image of fewer than `min_pixels`.
DenoisedChoice ChooseForDenoising(const BalanceResult& cache, int settings_rays,
                                  const PathPilotFigures& path, double image_pixels,
                                  double min_pixels = kPathChoiceMinPixels);

// The samples per pixel the path tracer takes in `seconds` of thread time, within [lo, hi].
int PathSppForSeconds(double seconds, const PathPilotFigures& path, double image_pixels, int lo,
                      int hi);

}  // namespace irfarm
