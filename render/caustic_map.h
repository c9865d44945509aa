// Caustic photon map (Jensen 1996; the companion of the irradiance cache in Mitsuba 0.5's
// photon mapper and in Jensen's book): light that reaches a diffuse surface from an area light
// through one or more delta (mirror, smooth glass, smooth coating) bounces.
//
// Such light is found by a record's hemisphere rays only where a ray happens to leave through the
// mirror or the glass towards the lamp: a small, bright solid angle, so records near a caustic
// are noisy and the cache interpolates their noise into blotches. With a map, the cache leaves
// that light out (every record's rays skip area-light emission reached from the record point by
// delta bounces only: PathSettings::skip_caustic_emission) and every cached irradiance lookup
// adds the map's estimate at its point instead (IrrcacheIntegrator::Irradiance), at every cache
// level, so the two never overlap and nothing is counted twice.
//
// Photons are emitted from area lights (rectangles, spheres, meshes; not from delta lights, whose
// caustics no path tracer renders, Mitsuba's included; environment light through glass stays with
// the records) in proportion to their power, followed through delta lobes only, and stored at each
// surface with a diffuse lobe after at least one delta bounce; a photon whose first hit is not a
// delta surface is direct light (the integrators' next-event estimation) and is dropped. A glossy
// (rough) lobe ends the photon, and such light stays with the records. Photon i draws its numbers
// from its own stream, and batches are appended in order, so the map does not depend on the thread
// count.
//
// Irradiance is precomputed at every 8th stored photon (Christensen 1999, who used a subset too):
// the k nearest photons on the same side (normals within kNormalCos) over the disc that holds
// them. A lookup takes, of the two sites nearest the point (approximately), the first whose disc
// contains it and whose normal agrees; none: no caustic there. The k-d trees are nanoflann's.
//
// On by default where the integrator is irrcache and paths are unbounded
// (RenderSettings::caustics; `irfarm render --no-caustics` turns it off); a scene with no delta
// BSDF or no area light builds nothing.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "cache/math.h"

namespace irfarm {

class Scene;

struct CausticMapSettings {
  long target_photons = 100000;  // stop emitting once this many are stored
  long max_emitted = 4000000;    // ... or once this many were emitted
  int gather = 64;               // photons per irradiance estimate (k)
  uint64_t seed = 0;
};

// What consecutive lookups of one render thread (a pixel's samples, its neighbours) may reuse: a
// lookup's answer is the estimate of the site nearest the point, constant over that site's cell,
// so a point within `reach` of the last one, with the same normal, gets the same answer.
struct CausticReuse {
  Vec3 p, n, value;
  float reach2 = -1;  // squared; negative: nothing to reuse
};

struct CausticMapStats {
  long emitted = 0, stored = 0;
};

class CausticMap {
 public:
  // nullptr when the scene has nothing that makes caustics (no delta BSDF, or no area light) or
  // when no emitted photon found one.
  static std::unique_ptr<CausticMap> Build(const Scene& scene, const CausticMapSettings& settings,
                                           tbb::task_arena& arena, CausticMapStats* stats);
  // Whether a scene has what a caustic map needs (cheap; Build checks it too).
  static bool SceneHasCaustics(const Scene& scene);

  ~CausticMap();
  CausticMap(const CausticMap&) = delete;
  CausticMap& operator=(const CausticMap&) = delete;

  // Caustic irradiance arriving at p on the side of unit normal n (0 where there is none).
  // Allocates nothing. With `reuse`, the last answer is taken again within its reach.
  Vec3 Irradiance(const Vec3& p, const Vec3& n, CausticReuse* reuse = nullptr) const;

  size_t sites() const { return photons_.size(); }  // photons with an estimate (every 8th)

  struct Photon {
    Vec3 p, n;  // where, and the normal on the side it arrived from
    Vec3 power;
  };
  struct Estimate {
    Vec3 irradiance;
    float radius2 = 0;
  };

 private:
  CausticMap();
  struct Index;
  std::vector<Photon> photons_;
  std::vector<Estimate> estimates_;
  std::unique_ptr<Index> index_;
  // A coarse occupancy grid over the photons' bounds: most lookups are far from any caustic and
  // end here, without a tree search.
  Vec3 grid_lo_, grid_scale_;
  int grid_n_ = 0;
  std::vector<uint8_t> grid_;
};

}  // namespace irfarm
