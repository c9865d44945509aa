// What a render measures on random pixels before its overture: the pilot of record_balance.h,
// which chooses the record rays and the cache levels at default settings, and, for
// --target-error, the sampling error the final pass's first round will leave.
#pragma once

#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>

#include <cstdint>

#include "render/camera.h"
#include "render/irrcache_integrator.h"
#include "render/record_balance.h"
#include "render/render_counters.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace irfarm {

// The pilot at the settings' cache levels and, where the settings leave the levels to it
// (IrrcacheSettings::choose_cache_levels) and the records' noise is large enough
// (MayPreferTwoLevels), a second pilot at two levels; two levels, at that pilot's rays, where the
// two pilots' figures predict them cheaper (TwoLevelsPay, render/record_balance.h). With
// `two_levels_above` > 0 (--target-error) instead: two levels where the records' noise dominates
// (PrefersTwoLevels) and the one-level record noise is above that. *ic receives the rays and the
// levels. Its records go into a scratch cache that is then dropped.
BalanceResult PilotSettings(const Scene& scene, const RenderSettings& settings,
                            const PixelRect& rect, tbb::task_arena& arena,
                            tbb::enumerable_thread_specific<RenderCounters>& counters,
                            IrrcacheSettings* ic, double two_levels_above = 0);

// The sampling error the final pass will estimate after its first round of `spp` samples, from
// random pixels of `rect` rendered with `integrator`'s cache (pilot.cc).
double EstimateSamplingError(const IrrcacheIntegrator& integrator, const Camera& cam, uint64_t seed,
                             int spp, int light_samples, bool splat, const PixelRect& rect,
                             tbb::task_arena& arena,
                             tbb::enumerable_thread_specific<RenderCounters>& counters);

// The path pilot of ChooseForDenoising (record_balance.h): 1,024 random pixels of `rect`, 16
// camera samples each, traced as the path integrator's final pass traces them
// (PathIntegratorSettings); their per-sample error and thread time.
PathPilotFigures PathPilot(const Scene& scene, const RenderSettings& settings,
                           const PixelRect& rect, tbb::task_arena& arena,
                           tbb::enumerable_thread_specific<RenderCounters>& counters);

}  // namespace irfarm
