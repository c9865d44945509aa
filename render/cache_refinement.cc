#include "render/cache_refinement.h"

#include <algorithm>
#include <cmath>

namespace irfarm {

int TargetMinSpp(double target_error, int settings_min_spp) {
  const double spp = 16 * kSamplingErrorAt16Spp / (0.5 * target_error);
  // At least 4. The error estimate compares two halves of a pixel's samples, and a pixel that
  // stops on its first two agreeing by chance is noisier than they say (the pixels left at 2 spp
  // held 3x-5x the error they estimated on cornell-box at E = 4e-3: the estimate 0.63x of the
  // measured error; at 4 spp, 0.82x).
  return std::clamp(int(std::ceil(spp)), kFewestTargetSpp,
                    std::max(kFewestTargetSpp, settings_min_spp));
}

double TargetAccuracy(double target_error, double share) {
  return std::clamp(0.1 * std::sqrt(share * target_error / kCacheErrorAtDefaults), 0.03, 0.4);
}

int TargetRecordRays(double target_error, int settings_rays, double share) {
  const double base = std::max(4, settings_rays);
  return int(std::lround(
      std::clamp(base * kCacheErrorAtDefaults / (share * target_error), 128.0, 4 * base)));
}

CacheRefinement::CacheRefinement(const RefinementStart& start) : start_(start) {
  const double e = start.target_error;
  // The first cache's share: kFirstCacheShare where the first round can measure the samples'
  // error and so raise the cache's share to match (a cache this render made). Two levels (the
  // pilot chose them for noisy one-level records, and their rays for half of E) and a shared
  // or imported cache keep the model's nominal half; built coarser, veach-ajar took more
  // rounds to the same band (E = 1e-3: 186 s against 65 s).
  const double first_share = start.may_rebuild && start.pilot_rays == 0 ? kFirstCacheShare : 0.5;
  accuracy_ = float(TargetAccuracy(e, first_share));
  // Ward's rule to start with: the error model above and its coarsest cache
  // (kCoarsestAccuracy, kFewestRecordRays) were calibrated with it. With wider lookups from
  // the start the coarsest cache is more accurate, and easy scenes ended below E/2
  // (2026-12-03, seed 7, E = 4e-3 and 1e-3 on eight shared scenes and six unseen rooms,
  // against the truth: 17 of 28 in [E/2, 2E] at factor 1.5, 22 of 28 with the model's
  // constant recalibrated to 1.5e-4, 25 of 28 at factor 1; docs/guide/irradiance-cache.md, "Wider
  // lookups"). Each round's checks also measure the settings' wider lookups; where the cache is
  // above its share, mostly by its records' noise, and they measure lower but not below the
  // refinement's aim (0.8 of the share, below: the calibrated rounds get there without
  // overshooting), the render takes them from then on.
  lookup_factor_ = 1;
  wider_factor_ = start.wider_factor > 1 ? start.wider_factor : 0.0f;
  record_rays_ = start.pilot_rays > 0 ? start.pilot_rays
                                      : TargetRecordRays(e, start.settings_rays, first_share);
  most_rays_ = 4 * std::max(4, start.settings_rays);
  cache_rays_ = record_rays_;
  cache_budget_ = 0.5 * e;
  left_by_samples_ = 0.5 * e;
}

int CacheRefinement::checks() const {
  return int(std::min<long>(
      4096, 256L * std::max(1, TargetRecordRays(start_.target_error, start_.settings_rays) /
                                   std::max(1, record_rays_))));
}

bool CacheRefinement::measures_sampling() const {
  return start_.may_rebuild && rebuilds_ == 0 && iteration_ == 0;
}

CacheRefinement::Next CacheRefinement::AfterRound(CacheErrorEstimate estimate, double sampling,
                                                  double work, double elapsed, CacheRound* round) {
  const double e = start_.target_error;
  // The first round also measures what the camera samples at their minimum leave of E: that is
  // the cache's share from then on (at least half of E, at most 0.9 E).
  if (measures_sampling()) {
    first_sampling_ = sampling;
    left_by_samples_ = std::clamp(e - sampling, 0.5 * e, 0.9 * e);
    cache_budget_ = left_by_samples_;
  }
  if (lookup_factor_ < wider_factor_ && estimate.error > cache_budget_ &&
      estimate.noise > 0.5 * estimate.error && estimate.other_error < estimate.error &&
      estimate.other_error >= 0.8 * cache_budget_) {
    lookup_factor_ = wider_factor_;
    estimate.error = estimate.other_error;
    estimate.noise = estimate.other_noise;
  }
  cache_error_ = estimate.error;
  *round = CacheRound{accuracy_,
                      lookup_factor_,
                      record_rays_,
                      cache_error_,
                      estimate.noise,
                      cache_budget_,
                      rebuilds_ > 0 && iteration_ == 0,
                      renewed_};
  renewed_ = false;
  // An easy scene: the first cache is far inside what the first round of samples (TargetMinSpp)
  // leaves of E, below a quarter of it, and the render would end far below E (room-b: 4.8e-4 at
  // E = 4e-3, at 2 spp). That share is E minus those samples' error, within [E/2, 0.9 E]: where
  // they leave more than half of E (room-c at E = 4e-3: 9.7e-4 of sampling error at 4 spp, cache
  // 5.4e-4), the cache may take more than its nominal half. Rebuild the cache coarser by the
  // model the first round used (interpolation error ~ a^2, noise ~ 1 / rays), aiming at that
  // share; the adaptive samples then stop at or near their minimum. Once more if the rebuilt
  // cache is still below half of it (the first estimate is from 256 checks only, and a larger a
  // may buy nothing where the validity radius is clamped at max_spacing_px).
  // Also where the first cache and the samples would end below kLowestPlannedEnd E even at the
  // fewest samples per pixel the final pass may start at (kFewestTargetSpp; where the cache
  // leaves room, the final pass starts at fewer than TargetMinSpp, FinalMinSpp).
  // bench/make_room.py's rooms 222 and 226, seed 7: first caches at 0.29 and 0.25 of the share,
  // renders at 0.28 E to 0.35 E at E = 4e-3 and 1e-3, the estimates within 1.2x of the truth.
  const double sampling_at_fewest = std::max(0.0, first_sampling_) *
                                    TargetMinSpp(e, start_.settings_min_spp) /
                                    double(kFewestTargetSpp);
  // Only a cache's first round: a cache the rounds have refined is not thrown away for coming out
  // finer than asked. Until 2026-12-04 the first cache's test also held after refinement rounds:
  // bench/make_room.py's daylight room 512 at E = 1e-3 (seed 7, one run in three) refined a =
  // 0.15 -> 0.078, its check then read 8e-5, and the cache was rebuilt at a = 0.20 and 306 rays,
  // whose next check collapsed to 0: 1.3 E against the truth, estimated at 0.29 E.
  // A rebuilt cache is rebuilt again only on a check that measured something: a check clamped at
  // 0 (the records' variance, subtracted, swamped what was left) says nothing of how far below
  // the share the cache is. Room-512 at E = 1e-3 (seed 10, one run in three): its rebuilt cache
  // (a = 0.31, 267 rays) read 0 and was rebuilt at a = 0.5 and 17 rays, 2.9e-2; four rounds
  // then ended at 3.3 E.
  const bool far_below =
      iteration_ == 0 &&
      (rebuilds_ == 0 ? cache_error_ < std::max(0.25 * left_by_samples_,
                                                kLowestPlannedEnd * e - sampling_at_fewest)
                      : cache_error_ > 0 && cache_error_ < 0.5 * cache_budget_);
  // Not a two-level cache: its checks share the second level with the records they check, so
  // they do not see that level's error (kTwoLevelCheckBias scales them for it at the settings'
  // rays), and a coarser rebuild with fewer rays makes that error larger, unseen. The daylight
  // room 512 (bench/make_room.py, two levels) at E = 1e-3: runs whose first cache read low
  // rebuilt it at a = 0.26-0.5 with 24-385 rays, checks then read 2.5e-5 to 4.5e-4, and the
  // renders ended at 1.7-3.9 E (bin 4: most of it low-frequency, the cache's); the runs that kept
  // their first cache ended at 1.1-1.5 E (5.9e-4 of it the reference's own).
  if (start_.may_rebuild && start_.cache_levels == 1 && rebuilds_ < 2 && far_below) {
    if (rebuilds_ == 0) cache_budget_ = left_by_samples_;
    const double r = std::min(16.0, cache_budget_ / std::max(cache_error_, 1e-12));
    const float a = std::min(kCoarsestAccuracy, float(accuracy_ * std::sqrt(r)));
    const int rays = std::max(kFewestRecordRays, int(std::lround(record_rays_ / r)));
    if (a != accuracy_ || rays != record_rays_) {
      accuracy_ = a;
      record_rays_ = rays;
      ++rebuilds_;
      iteration_ = 0;  // the rebuilt cache's rounds start afresh
      ++streams_;
      cache_rays_ = record_rays_;
      return Next::kRebuild;
    }
  }
  // Stop also when the last refinement bought less than a third off the error: what is left is
  // not the noise or interpolation error that more rays and records remove (a light leak); going
  // on multiplies the cost for nothing. (RefinementStalled: not when the last round raised only
  // the rays and what is left is interpolation error. living-room at E = 2e-2 stopped here
  // before, at a = 0.4: 7.2e-2 -> 6.7e-2 at 4x the rays, the noise part 7.0e-2 -> 1.8e-2.)
  const bool stalled =
      iteration_ > 0 && RefinementStalled(CacheErrorCheck{previous_error_, previous_noise_},
                                          CacheErrorCheck{cache_error_, estimate.noise},
                                          last_rays_only_, cache_budget_);
  // Each round costs several times the one before (up to 4x the rays, more records): no round
  // that would end past 10x the first round's time, at 4x the last round's cost (veach-ajar at
  // E = 4e-3 took 198 s against 6 s at the defaults without this: its cache error is its
  // records' noise, light found through the door gap by few of a record's rays, and falls only
  // as 1 / rays: 2.3e-2 at a = 0.1 and 1536 rays, 8.2e-3 at 6144 rays in 3.7x the time).
  // Work counted in rays traced and cache lookups (the pilot's, the rounds' and their checks'),
  // not timed: the stop must not move with the machine's load. Timed in wall seconds, beside two
  // CPU-bound processes, veach-ajar at quarter size and E = 4e-3 ended at 3.9e-3 to 8.1e-3; in the
  // process's CPU seconds it still varied (8.1e-3 in a CI run, 6.3e-3 idle, seed 5): a loaded
  // machine's cores also run each instruction slower.
  // The first round's cost as if its cache had been built for half of E, as the model set it
  // before kFirstCacheShare (records cost as rays / a^2): a first cache built coarser costs less,
  // and would leave a scene that needs rounds fewer of them. The pilot's work is not scaled: it
  // does not depend on the first cache. (living-room at E = 1e-3, which no rule here reaches,
  // costs 3x the time it did from the old start: 868-909 CPU s for 3.3e-3, against 280 s for
  // 4.5e-3; its last cache, a = 0.045 and 6144 rays, makes the final pass 750 s.)
  if (iteration_ == 0) {
    const double nominal_a = TargetAccuracy(e, 0.5);
    const double nominal_rays =
        start_.pilot_rays > 0 ? start_.pilot_rays : TargetRecordRays(e, start_.settings_rays, 0.5);
    const double scale = rebuilds_ > 0 ? 1.0
                                       : nominal_rays / std::max(1, record_rays_) *
                                             (double(accuracy_) / nominal_a) *
                                             (double(accuracy_) / nominal_a);
    first_round_ = start_.pilot_work + (work - start_.pilot_work) * std::max(1.0, scale);
  }
  // Not while the cache is still cheaper than the settings' own (R0 rays at a0; records cost as
  // rays / a^2: a render at the settings builds that much cache anyway) and its error is above
  // twice its share (the render would end far above E; within that, the samples make up most of
  // the rest). layered_kitchen at E = 1e-2 stopped here at a = 0.2 and 512 rays (0.08 of the
  // settings' cache, error 4.5x its share): 2.56 E; going on, 0.98 E in 12 s. Without the
  // second condition daylight rooms 511-513 at 4e-3 took a fourth round (1.15-1.4x their share
  // after the third) for 1.8x the time and no gain in band.
  const double cost_vs_settings = double(record_rays_) / std::max(1, start_.settings_rays) *
                                  (double(start_.settings_accuracy) / accuracy_) *
                                  (double(start_.settings_accuracy) / accuracy_);
  // A two-level cache's check misses part of its second level's error (kTwoLevelCheckBias in
  // cache_check.cc scales it by the scenes' middle, 1.5; veach-ajar measured 1.95), so less of
  // its reading above the share can be left to the samples: 1.25x. veach-ajar at 4e-3 (two
  // levels) stopped here at 1.35-1.7x its share and ended at 1.55 E, estimated at 0.57-0.71x.
  const double far_factor = start_.cache_levels > 1 ? 1.25 : 2.0;
  const bool cheap_and_far = cost_vs_settings < 1 && cache_error_ > far_factor * cache_budget_;
  const bool too_costly = !cheap_and_far && work + 4 * (work - round_start_) > 10 * first_round_;
  round_start_ = work;
  const bool out_of_time = start_.time_limit > 0 && elapsed >= 0.5 * start_.time_limit;
  if (cache_error_ <= cache_budget_ || iteration_ >= 3 || stalled || too_costly || out_of_time) {
    if (cache_error_ > cache_budget_)
      stop_reason_ = stalled       ? "the last round removed less than a third of it"
                     : too_costly  ? "another round would pass 10x the first round's time"
                     : out_of_time ? "half of --time-limit is spent"
                                   : "after 4 rounds";
    return Next::kDone;
  }
  previous_error_ = cache_error_;
  previous_noise_ = estimate.noise;
  // Aim at T = 0.8 of the cache's share (0.4 E when that is E/2) at the least cost. The error is
  // the records' noise N, which falls as 1 / rays (k times the rays: N / k) and not with a, plus
  // interpolation error I, which falls about as a^2 (Ward's bound is linear in a; a times f:
  // I f^2). The cost grows as k / f^2 (rays per record times records). The least k / f^2 with
  // N / k + I f^2 = T: f^2 = T / (2 I) where I > T / 2 (interpolation and noise get half of T
  // each: k = 2 N / T), else f = 1 and k = N / (T - I). Before, every round lowered a and raised
  // the rays together (k = 1 / f^2), which multiplied records where the error was their noise.
  const double target = 0.8 * cache_budget_;
  const double noise = estimate.noise, interp = std::max(0.0, cache_error_ - noise);
  double f2 = 1, k = 1;
  if (interp > 0.5 * target) {
    f2 = target / (2 * interp);
    k = 2 * noise / target;
  } else {
    k = noise / std::max(target - interp, 1e-12);
  }
  // At most 4x the rays and half the accuracy a round; at least 1.25x the cost, so that a round
  // is not spent on a change too small to measure.
  f2 = std::clamp(f2, 0.25, 1.0);
  k = std::clamp(k, 0.5, 4.0);
  if (k / f2 < 1.25) k = 1.25 * f2;
  // (f2 >= 1 before: mesh-lamps, seed 5, E = 4e-3, from a first cache at a = 0.36 and 128 rays
  // with error 1.8e-2, nearly all noise: a round of 4x the rays and a 0.36 -> 0.31 took the noise
  // to 4.2e-3 and left 1.0e-2 of interpolation error, and stopped there as stalled, at 3.6x the
  // error asked.)
  last_rays_only_ = f2 > 2.0 / 3.0;
  accuracy_ *= float(std::sqrt(f2));
  record_rays_ = std::clamp(int(std::lround(record_rays_ * k)), kFewestRecordRays, most_rays_);
  ++iteration_;
  ++streams_;
  // Only a cache this render made may be emptied (not one it was given: --cache-in, a job's),
  // and only one of one level: a two-level cache's checks do not see its second level
  // (kTwoLevelCheckBias, calibrated on caches kept through the rounds), whose records a renewal
  // would drop as well. veach-ajar at E = 4e-3 (two levels, renewed at round 2, seeds 7-9) ended
  // at 1.07-1.41 E, estimates 0.63-0.92x, against 1.00-1.21 E and 0.70-1.09x kept.
  if (start_.may_rebuild && start_.cache_levels == 1 && cache_rays_ >= kFewestRenewedRays &&
      record_rays_ > kRenewRaysFactor * cache_rays_) {
    cache_rays_ = record_rays_;
    renewed_ = true;
    return Next::kRenew;
  }
  return Next::kRefine;
}

int CacheRefinement::FinalMinSpp() const {
  const int start = TargetMinSpp(start_.target_error, start_.settings_min_spp);
  // Where the cache leaves the samples more than their first round's error, the pixels start at
  // fewer samples (no fewer than kFewestTargetSpp): at TargetMinSpp they would end the render
  // below E, at more cost than E needs (room-c at E = 1e-3: cache 2.1e-4, samples 3.0e-4 at 8
  // spp, the render 0.455 E against the reference). The start is set for 0.8 of that room
  // (sampling error ~ 1 / spp); adaptive rounds add samples where the pixels need them.
  if (first_sampling_ > 0 && cache_error_ >= 0) {
    const double room = 0.8 * (start_.target_error - cache_error_);
    if (room > 0)
      return std::clamp(int(std::ceil(start * first_sampling_ / room)), kFewestTargetSpp, start);
  }
  return start;
}

double CacheRefinement::FinalTargetError() const {
  return std::max(start_.target_error - std::max(0.0, cache_error_), 0.25 * start_.target_error);
}

}  // namespace irfarm
