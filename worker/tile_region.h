// TileRegionOf: what a tile sees, for the coordinator's filtered record fan-out (issue 11,
// coordinator/fanout_region.h). Traces the camera rays through every pixel corner and centre of
// the tile, grown by the film filter's reach (PixelFilter::reach: 1.5 pixels for Mitsuba's
// default gaussian, 0 for box), and returns the world-space box of their first hits, padded by
// two pixel footprints at the farthest hit (lookups happen anywhere inside a pixel, between the
// traced rays). Lookups reached through specular surfaces or glossy bounces are not in the box:
// there the worker computes its own records (the image is unaffected; only sharing is lost).
// About 2 rays per pixel of the tile, a negligible fraction of rendering it.
#pragma once

#include <optional>

#include "core/math.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace irfarm {

// nullopt when no ray of the tile hits anything (nothing there to look up).
std::optional<Bounds3> TileRegionOf(const Scene& scene, const PixelRect& rect);

}  // namespace irfarm
