// The overture: records placed over a rect coarse to fine before the final pass, so that camera
// samples find a cache with records everywhere (overture.cc).
#pragma once

#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>
#include <atomic>

#include <cstdint>
#include <vector>

#include "render/camera.h"
#include "render/irrcache_integrator.h"
#include "render/render_counters.h"
#include "render/renderer.h"

namespace irfarm {

// IrrcacheIntegrator::Prime at pixel centres of `rect` on grids of stride 32, 16, ..., 1, on
// `threads` threads of `arena`; `iteration` keys the random streams (--target-error's rounds).
// Pixels where a record was made are set in *marks (rect's pixels, row by row) unless it is empty.
void RunOverture(const Camera& cam, const IrrcacheIntegrator& integrator, const PixelRect& rect,
                 uint64_t seed, uint64_t iteration, int threads, bool tty, tbb::task_arena& arena,
                 tbb::enumerable_thread_specific<RenderCounters>& counters,
                 std::vector<uint8_t>* marks, const std::atomic<bool>* cancel = nullptr);

}  // namespace irfarm
