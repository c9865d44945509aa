// --target-error's cache refinement: which cache each round builds, and what a round's measured
// error decides (render/renderer.cc runs the rounds: it builds each round's cache, checks it by
// cross-validation at random pixels, and hands the figures to CacheRefinement::AfterRound).
//
// Each round estimates the cache's error (relMSE by cross-validation at random pixels) and the
// part of it its records' own noise explains; the rest is interpolation error. A round that
// raised only the record rays removes noise (which falls as 1 / rays); one that lowered the
// accuracy a removes interpolation error (about as a^2). The refinement stops, among other
// reasons, when the last round took less than a third off the error: what is left is then
// neither (light leaks through gaps that more rays and records do not close: veach-ajar), and
// going on multiplies the cost for nothing. Except when the error is still more than twice the
// cache's share, the last round raised only the rays and the noise part answered them (lost at
// least a third): what kept the error up is then interpolation, and lowering a, the round that
// removes it, has not been tried. (Within twice its share, stopping leaves the image within about
// 1.5 E: specular at E = 1e-3 went on from 1.11 E in 8.6 s to 0.76 E in 22.7 s without that limit.)
// Until 2026-12-04 the noise had to fall to half and interpolation to be most of what was left: a
// room lit by spot lights (bench/make_room.py 401 --lamps bulb, E = 4e-3, seed 7) stopped at
// a = 0.36 after one rays-only round (noise 6.8e-3 -> 4.3e-3 at 3.3x the rays, interpolation
// 2.8e-3) and came out at 1.0e-2, 2.5 E, in 0.7 s, where the defaults take 1.1 s for 1.1e-3.
#pragma once

#include "render/render_stats.h"

namespace irfarm {

// --target-error: half of the error asked goes to the cache. Calibrated on the shared scenes from
// the cross-validated cache error that --target-error 1e-3 and 4e-3 runs measured (8 scenes,
// 2026-11-30, with neighbour clamping): scaled back to the defaults (a = 0.1, 1536 record rays)
// by the model below, 2.1e-4 and 2.2e-4 on average (room-b 0.4e-4 ... room-a 4.6e-4); its
// interpolation part grows about as a^2, its noise as 1 / rays. (7e-4 before neighbour clamping
// made every cache 3x more accurate, and runs then ended far below the error asked.)
constexpr double kCacheErrorAtDefaults = 2.2e-4;

// --target-error on an easy scene: the coarsest cache it may rebuild. a beyond 0.5 makes Ward's
// interpolation blotchy where light changes (and the validity radius is clamped at
// max_spacing_px anyway); 16 rays are 2 x 8 strata, the fewest for two half-records of 8 rays.
constexpr float kCoarsestAccuracy = 0.5f;
constexpr int kFewestRecordRays = 16;

// --target-error: the samples every pixel gets before adaptive rounds, from the sampling error
// at 16 spp on the shared scenes (0.9e-4 to 3.3e-4 of relMSE, falling as 1 / spp) and the half
// of the error left to sampling; never more than the settings' own min_spp.
constexpr double kSamplingErrorAt16Spp = 2.5e-4;
// The fewest samples per pixel a --target-error render starts its pixels at (TargetMinSpp).
constexpr int kFewestTargetSpp = 4;

// --target-error: the share of E the first cache is built for by the model above. More than the
// refinement's nominal half: the caches came out at 0.45-0.95 of the model's figure on rooms it
// was not calibrated on (six unseen rooms and room-301, E = 4e-3 at a = 0.3 and 168 rays: 0.23 E
// to 0.47 E), and with the camera samples at their minimum adding 0.05 E to 0.6 E, those renders
// ended at 0.36 E to 0.55 E, at or below the band's lower end and at more cost than the error
// asked needs. The first cache's estimate then sets the share the refinement works to.
constexpr double kFirstCacheShare = 0.7;
// A first cache that, with the camera samples at their minimum, is estimated to end below this
// fraction of E is rebuilt coarser. The truth (measured less the reference's own error) ran
// 0.77x-1.22x of the estimate in the issue-6 run at 2aa34a0 (seed 7, 18 targets), 0.89x-1.35x at
// 156f673 but for veach-ajar at 1e-3 (0.56x); the band is [E/2, 2E], and an end estimated at
// 1.25 E/2 is inside it unless the estimate is more than 1.25x high. It was E/2 before: room-c at E
// = 1e-3 was estimated at 0.51 E, not rebuilt, and ended at 0.455 E in two runs (2aa34a0, 156f673).
constexpr double kLowestPlannedEnd = 0.625;
// A refinement round whose records take more than this many times the rays of the cache's oldest
// records starts its cache anew (CacheRefinement::Next::kRenew; a cache of one level that the
// render made itself). A record counts wherever a is
// met, whatever its rays: a round that kept a and raised the rays made no record at all (its
// points all had one), and after a round that halved a, a quarter of the lookups' weight was
// still the old, noisier records'. The checks then measured the old records' noise, which more
// rays could not remove, and the split into noise (from a fresh record's variance) and
// interpolation error put it in the interpolation part. layered_kitchen (one level, E = 4e-3,
// seed 7): rounds at 128, 512 and 2048 rays checked 9.0e-2, 3.0e-2, 1.3e-2 and the render ended
// at 2.0 E (estimated at 1.77x the measured); the same a and 2048 rays built from empty measure
// 2.4e-3 at 256 spp; with renewal, 1.1e-2 and 2.8e-3 at the same rounds, 0.91 E, estimate 1.05x.
constexpr double kRenewRaysFactor = 1.5;
// ... and only a cache whose records took at least this many rays. A coarse rebuild's records of
// a few dozen rays are far noisier than the 1/rays model the rounds plan with says (their strata
// are few and wide), so a fresh cache at twice their rays lands far below the plan: room-b at
// 1/4 size and E = 4e-3 (rounds at 16 and 30 rays after a rebuild) checked 1.5e-3 against the
// 2.2e-3 planned and ended at 0.41 E, below the band (GoldenImageTest.TargetError...).
constexpr int kFewestRenewedRays = 64;

// The samples every pixel gets before adaptive rounds at E = `target_error`, at least
// kFewestTargetSpp and at most max(kFewestTargetSpp, `settings_min_spp`).
int TargetMinSpp(double target_error, int settings_min_spp);
// The starting accuracy for `share` of E.
double TargetAccuracy(double target_error, double share = kFirstCacheShare);
// Record rays for `share` of E: the cache's error is mostly its records' noise (measured on the
// shared scenes: half-rays records have 4-18% relative standard error), which falls as 1 / rays,
// so the rays are scaled from the settings' count R0 by the cache's share of the error; within
// [128, 4 R0].
int TargetRecordRays(double target_error, int settings_rays, double share = kFirstCacheShare);

struct CacheErrorCheck {
  double error = 0;  // the cache's estimated error
  double noise = 0;  // the part of it the records' noise explains (at most `error`)
};

inline bool RefinementStalled(const CacheErrorCheck& previous, const CacheErrorCheck& now,
                              bool last_round_raised_only_rays, double share) {
  const bool interpolation_left = now.error > 2 * share && last_round_raised_only_rays &&
                                  now.noise <= (2.0 / 3.0) * previous.noise;
  return now.error > (2.0 / 3.0) * previous.error && !interpolation_left;
}

// One round's cross-validated estimate of its cache's error (relMSE), with the part its records'
// noise explains, and the same at the settings' wider lookups (other_*, when asked for).
struct CacheErrorEstimate {
  double error = 0;  // clamped at 0
  double noise = 0;  // the part of it the records' own noise explains (at most `error`)
  double other_error = 0, other_noise = 0;
};

// What the refinement starts from.
struct RefinementStart {
  double target_error = 0;         // E
  int settings_rays = 1536;        // R0: the settings' record rays
  float settings_accuracy = 0.1f;  // a0: the settings' accuracy
  int settings_min_spp = 0;
  float wider_factor = 0;    // the settings' lookup factor: the wider lookups where > 1
  bool may_rebuild = false;  // the cache is this render's own and empty: it may be started anew
  int pilot_rays = 0;        // two levels: the two-level pilot's starting rays (0: one level)
  int cache_levels = 1;      // the cache's levels (two: its checks do not see the second level)
  double pilot_work = 0;     // the pilot's rays and lookups (RenderCounters::Work)
  double time_limit = 0;     // --time-limit in seconds (0: none)
};

// The rounds of one --target-error render. Each round builds the cache at accuracy(),
// record_rays() and lookup_factor() (a fresh cache when AfterRound says kRebuild or kRenew),
// checks it with
// checks() pixels per batch (with other_factor() for the wider lookups' figures) and, where
// measures_sampling(), estimates the camera samples' error at TargetMinSpp; AfterRound then says
// what comes next.
class CacheRefinement {
 public:
  explicit CacheRefinement(const RefinementStart& start);

  float accuracy() const { return accuracy_; }
  int record_rays() const { return record_rays_; }
  float lookup_factor() const { return lookup_factor_; }
  // The random-stream index of the round (a rebuilt cache's rounds get new ones).
  int streams() const { return streams_; }
  // Check pixels per batch: 256, or more for a rebuilt coarser cache, as many as cost the first
  // round's record rays (its few records each cover many pixels, and 256 checks saw the noise of
  // too few of them: room-b, 16 rays, estimates 0.57x to 0.95x of the measured).
  int checks() const;
  // The lookup factor the checks also measure (0: none).
  float other_factor() const { return lookup_factor_ < wider_factor_ ? wider_factor_ : 0.0f; }
  // This round also estimates the samples' error at their minimum (the first round of a cache
  // this render may rebuild).
  bool measures_sampling() const;

  // kRefine: the next round adds records to the cache; kRebuild: a coarser cache, from empty;
  // kRenew: the next round's records take so many more rays than the cache's that it starts
  // from empty too (kRenewRaysFactor); kDone: the cache is the one the render uses.
  enum class Next { kRefine, kRebuild, kRenew, kDone };
  // The round's checks (`estimate`), the samples' error at TargetMinSpp when measures_sampling()
  // (else ignored), the work counted so far (the pilot's included) and the seconds since the
  // render began. `round` receives the round's figures for the stats.
  Next AfterRound(CacheErrorEstimate estimate, double sampling, double work, double elapsed,
                  CacheRound* round);

  // After kDone: the last round's estimated error, the share it was held to, and why it ended
  // above that share (nullptr where it did not).
  double cache_error() const { return cache_error_; }
  double cache_budget() const { return cache_budget_; }
  const char* stop_reason() const { return stop_reason_; }
  // The samples per pixel the final pass starts at, and the error it is asked for.
  int FinalMinSpp() const;
  double FinalTargetError() const;

 private:
  RefinementStart start_;
  float accuracy_ = 0, lookup_factor_ = 1, wider_factor_ = 0;
  int record_rays_ = 0, most_rays_ = 0;
  // The fewest rays the records in the cache were made with (those of its first round), and
  // whether the round being built started its cache anew for its rays.
  int cache_rays_ = 0;
  bool renewed_ = false;
  int iteration_ = 0, streams_ = 0, rebuilds_ = 0;
  // The cache's share of the error: half, until the first round has measured the samples'.
  double cache_budget_ = 0;
  double previous_error_ = 0, previous_noise_ = 0, first_round_ = 0, round_start_ = 0;
  // The last refinement lowered a too little to take a third off the interpolation error (about
  // as a^2): it raised the rays and kept a, or lowered a by less than a factor sqrt(3/2).
  bool last_rays_only_ = false;
  // What the first round of samples (TargetMinSpp) leaves of E, within [E/2, 0.9 E].
  double left_by_samples_ = 0;
  double first_sampling_ = -1;  // the samples' error the first round measured (-1: not measured)
  double cache_error_ = -1;
  const char* stop_reason_ = nullptr;
};

}  // namespace irfarm
