// --target-error's check of a cache: IrrcacheIntegrator::CacheError (a fresh record against the
// cache's answer at the same point) at random pixels, averaged.
#pragma once

#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>

#include <cstdint>

#include "render/cache_refinement.h"
#include "render/camera.h"
#include "render/irrcache_integrator.h"
#include "render/render_counters.h"
#include "render/renderer.h"

namespace irfarm {

// Mean over random pixels of `rect` of IrrcacheIntegrator::CacheError, clamped at 0, in batches
// of `checks` until the mean's standard error is small against it (cache_check.cc); `levels` is
// the cache's levels (two: the check records take fewer rays and the estimate is scaled, see
// there), `other_factor` the CacheError of a second accuracy (CacheRefinement::other_factor; 0:
// none). Pixels with nothing to check count as 0.
CacheErrorEstimate EstimateCacheError(const IrrcacheIntegrator& integrator, int levels,
                                      const Camera& cam, uint64_t seed, uint64_t iteration,
                                      int checks, const PixelRect& rect, tbb::task_arena& arena,
                                      tbb::enumerable_thread_specific<RenderCounters>& counters,
                                      float other_factor = 0);

}  // namespace irfarm
