// The figures every render reports (design.md "What every run reports"): wall and CPU seconds by
// phase, rays by kind, records computed / received / used, cache lookups and hit rate, tiles and
// peak memory; written as a JSON object next to the image.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "core/math.h"
#include "render/record_balance.h"
#include "render/render_counters.h"

namespace irfarm {

struct PhaseTime {
  std::string name;
  double wall_seconds = 0, cpu_seconds = 0;
};

// --target-error: one round of the cache's refinement (render/renderer.cc), as its checks
// measured it. rebuilt: the round's cache is one rebuilt coarser, replacing a cache that came out
// far finer than the error asked needs (an easy scene).
struct CacheRound {
  float accuracy = 0, lookup_factor = 0;
  int record_rays = 0;
  double error = 0, noise = 0, share = 0;  // estimated relMSE, its records' noise part, the goal
  bool rebuilt = false;                    // the cache was rebuilt coarser for this round
  bool renewed = false;  // the cache was started anew for this round's rays (kRenewRaysFactor)
};

struct RenderStats {
  std::string scene, integrator;
  bool cancelled = false;  // RenderSettings::cancel was set: the image is not finished
  int width = 0, height = 0, spp = 0, threads = 0;
  uint64_t seed = 0;
  // irrcache settings actually used (zero for path)
  float accuracy = 0;
  int record_rays = 0, strata_theta = 0, strata_phi = 0, light_samples = 0, cache_levels = 0;
  float min_spacing_px = 0, max_spacing_px = 0;
  float lookup_factor = 0;    // IrrcacheSettings::lookup_factor
  std::string spacing;        // IrrcacheSettings::spacing: "hessian" or "split-sphere"
  std::string interpolation;  // the cache's lookups: "linear" (CacheSettings::linear_fit) or "ward"
  std::vector<PhaseTime> phases;
  RenderCounters counters;
  uint64_t records_received = 0;  // from other processes (the service), 0 for a local render
  uint64_t records_in_cache = 0;
  uint64_t records_overture = 0;  // of records computed, those made by the overture
  long caustic_photons = 0, caustic_photons_emitted = 0;  // the photon map's (0: none built)
  int tiles = 0, tile_size = 0;
  Vec3 mean_rgb;
  long nonfinite_pixels = 0;
  // Sampling (final pass): samples per pixel, pixels that stopped before the maximum, and the
  // image's own error estimates (relMSE as the benchmarks define it).
  int spp_min = 0, spp_max = 0;
  double spp_mean = 0;
  long pixels_stopped_early = 0;
  int adaptive_rounds = 0;
  long fireflies_spread = 0;  // pixels whose brightest sample was spread (SpreadFireflies)
  double estimated_sampling_relmse = 0;  // from the pixels' two half-images
  // Adaptive with a budget: counted work of the budget (RenderSettings::budget_carry included)
  // the final pass did not spend.
  double budget_left = 0;
  double estimated_cache_relmse = -1;  // cross-validated records (target-error mode), -1: none
  double target_error = 0;
  std::vector<CacheRound> cache_rounds;  // --target-error's refinement, in order
  // Default settings: the pilot's balance of record rays (record_balance.h), when it ran.
  bool balanced = false;
  BalanceResult balance;
  // A denoised image at default settings (RenderSettings::choose_integrator): the path pilot's
  // figures and what ChooseForDenoising compared, when it ran.
  bool integrator_chosen = false;
  PathPilotFigures path_pilot;
  DenoisedChoice denoised_choice;
  long triangles = 0, degenerate_dropped = 0;
  int environment_guide_cells = 0;  // EnvironmentGuide's histograms (0: none learned)
  std::vector<std::string> warnings;

  double PhaseWall(const std::string& name) const;
  std::string ToJson() const;
};

// CPU seconds of this process so far (user + system) and peak resident set size in MiB.
double ProcessCpuSeconds();
// CPU seconds of the calling thread (CLOCK_THREAD_CPUTIME_ID): the time a piece of work took
// without the time the thread waited to run, so costs compared on a loaded machine (the pilot's
// records against its samples) are not skewed by when other processes got the CPU.
double ThreadCpuSeconds();
double PeakRssMiB();

// Measures one phase: wall and process CPU seconds from construction to Stop().
class PhaseTimer {
 public:
  explicit PhaseTimer(std::string name);
  PhaseTime Stop() const;

 private:
  std::string name_;
  double wall0_, cpu0_;
};

absl::Status WriteTextFile(const std::string& path, const std::string& text);

}  // namespace irfarm
