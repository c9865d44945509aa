// The final pass of a render: every pixel of a rect gets its camera samples, with adaptive
// sampling and splatting film filters (final_pass.cc).
#pragma once

#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cstdint>
#include <vector>

#include "render/irrcache_integrator.h"
#include "render/path_tracer.h"
#include "render/render_counters.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace irfarm {

// A rectangle of pixels [x0, x1) x [y0, y1), rendered by one task.
struct Tile {
  int x0, y0, x1, y1;
};

// `r` cut into tiles of `size` pixels, row by row.
std::vector<Tile> MakeTiles(const PixelRect& r, int size);

// What the path integrator traces a camera sample with: the settings' path and, where the
// settings ask for it and the map has one, an environment map's sun sampled as direct light
// (PathSettings::direct_sun, as irrcache's records do: one sample of it by its cells' luminance at
// every non-delta vertex, which the environment's own samples then leave out); the coarse light
// tree. FinalPass and the path pilot (pilot.cc) trace with it.
PathSettings PathIntegratorSettings(const Scene& scene, const RenderSettings& settings);

// The final pass: every pixel of `rect` gets its samples (all of them, or with adaptive
// sampling min_spp first and then rounds that double the samples of the pixels with the largest
// estimated error); fills out->image, the sampling figures of out->stats and, if asked, the
// sample map; marks pixels where records were computed.
//
// With a tent or gaussian film filter (PixelFilter::SplatReach() = g > 0) the first round's
// samples splat: each lands uniformly in its own pixel and is added to every pixel of `rect`
// whose centre its filter reaches, so the pixels up to g around `rect` (inside the image) are
// sampled too, exactly as the rect owning them samples them (their streams are keyed by their
// place in the image). Those pixels are rendered in four phases of tiles (final_pass.cc), so that
// no two tiles running at once add to the same pixel. Adaptive rounds add samples to some pixels
// only: splatted, those would make the sample density uneven under a pixel's filter and weigh its
// neighbours unevenly (a shifted filter: a bias at every edge the rounds refine). Their samples are
// placed by the pixel's own filter instead (PixelFilter::FilmPoint, an unbiased estimate of the
// same value) and combined with the splatted ones as samples of equal variance
// (PixelFilter::SplatSampleWeight).
void FinalPass(const Scene& scene, const RenderSettings& settings,
               const IrrcacheIntegrator& integrator, const PixelRect& rect, bool tty,
               tbb::task_arena& arena, tbb::enumerable_thread_specific<RenderCounters>& counters,
               std::vector<uint8_t>* marks, RenderOutput* out,
               std::chrono::steady_clock::time_point start_time);

}  // namespace irfarm
