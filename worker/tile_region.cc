// The box of a tile's first camera hits (see tile_region.h).
#include "worker/tile_region.h"

#include <algorithm>
#include <cmath>

namespace irfarm {

std::optional<Bounds3> TileRegionOf(const Scene& scene, const PixelRect& rect) {
  const Camera& camera = scene.camera();
  Bounds3 box;
  float pad = 0;  // scene units
  SurfaceHit hit;
  // The pixels' samples land up to the film filter's reach beyond the tile (PixelFilter): the
  // rays cover the tile grown by that many pixels, inside the image.
  const int grow = int(std::ceil(camera.filter().reach()));
  const int x0 = std::max(0, rect.x0 - grow), x1 = std::min(camera.width(), rect.x1 + grow);
  const int y0 = std::max(0, rect.y0 - grow), y1 = std::min(camera.height(), rect.y1 + grow);
  // Half-pixel steps: corners (even) and centres (odd) of every pixel.
  for (int j = 2 * y0; j <= 2 * y1; ++j) {
    for (int i = 2 * x0; i <= 2 * x1; ++i) {
      if ((i + j) % 2 != 0) continue;  // a corner or a centre, not an edge midpoint
      Ray ray;
      ray.origin = camera.origin();
      ray.dir = camera.Direction(0.5f * float(i), 0.5f * float(j));
      if (!scene.Intersect(ray, &hit)) continue;
      box.Extend(hit.p);
      pad = std::max(pad, 2 * camera.PixelSpread(hit.t));
    }
  }
  if (box.Empty()) return std::nullopt;
  box.lo = box.lo - Vec3(pad);
  box.hi = box.hi + Vec3(pad);
  return box;
}

}  // namespace irfarm
