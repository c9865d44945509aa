// Caustic photon map (Jensen 1996; the companion of the irradiance cache in Mitsuba 0.5's
// photon mapper and in Jensen's book): light that reaches a diffuse surface from a light through
// one or more of the map's lobes (Lobes): delta lobes (mirror, smooth glass, smooth coatings),
// and in a scene with a sharp glossy material (a metal or coat of low roughness) every
// non-diffuse lobe.
//
// Such light is found by a record's hemisphere rays only where a ray happens to leave through the
// mirror or the glass towards the lamp, or meets a metal where it reflects a lamp's highlight: a
// small, bright solid angle, so records near a caustic are noisy and the cache interpolates their
// noise into blotches. With a map, the records leave that light out wherever it lands on their
// paths (PathSettings::caustics: at the record point and at every vertex on the way, where the
// path adds the map's estimate instead) and every cached irradiance lookup adds the map's estimate
// at its point (IrrcacheIntegrator::Irradiance), at every cache level, so the two never overlap
// and nothing is counted twice.
//
// Photons are emitted from area lights (rectangles, spheres, meshes) in proportion to their
// power, from an environment map's sun (EnvironmentSun) and, where the map has glossy lobes,
// from point, spot and directional lights (a sun's photons from a square across it that covers
// the shapes with the map's lobes); the rest of the environment's light stays with the records.
// They are followed through the map's lobes only and stored at each surface with a diffuse lobe
// after at least one such bounce; a photon whose first hit is not such a lobe is direct light (the
// integrators' next-event estimation) and is dropped. A delta light's photon whose first bounce is
// a delta lobe is dropped too: a path traced from the other end reaches a delta light only by
// next-event estimation, which a delta lobe cannot make, so neither our path tracer nor Mitsuba's
// renders that light. Photon i draws its numbers from its own stream, and batches are appended in
// order, so the map does not depend on the thread count.
//
// Irradiance is precomputed at every 8th stored photon (Christensen 1999, who used a subset too):
// the k nearest photons on the same side (normals within kNormalCos) over the disc that holds
// them (nanoflann's k-d tree). A lookup takes, of the sites whose disc contains the point and
// whose normal agrees, the nearest; none: no caustic there. It finds them in a uniform grid whose
// cells list the sites whose disc reaches them.
//
// On by default where the integrator is irrcache and paths are unbounded
// (RenderSettings::caustics; `irfarm render --no-caustics` turns it off); a scene with none of
// the map's lobes or no light it covers builds nothing.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "core/math.h"
#include "render/environment_sun.h"

namespace irfarm {

class Scene;
struct Light;

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
  // nullptr when the scene has nothing that makes caustics (none of the map's lobes, or no light
  // the map covers) or when too few emitted photons found one (kLeastCausticShare).
  static std::unique_ptr<CausticMap> Build(const Scene& scene, const CausticMapSettings& settings,
                                           tbb::task_arena& arena, CausticMapStats* stats);
  // Whether a scene has what a caustic map needs (cheap; Build checks it too).
  static bool SceneHasCaustics(const Scene& scene);
  // The lobes the photons follow, which make a caustic (PathSettings::caustics): the delta lobes
  // where the scene has a delta material, and the glossy ones (and diffuse transmission) where it
  // has a sharp glossy material (a metal or a coat of low roughness, caustic_map.cc
  // kSharpGlossyPeak); a mask's pass-through with either; 0: none, no map.
  static uint32_t Lobes(const Scene& scene);
  uint32_t lobes() const { return lobes_; }
  // Whether the map holds this light's caustics (area, point, spot and directional lights); the
  // records then leave them out (PathSettings::caustics). Environment light stays with the
  // records. The second form takes a scene's light index (-1: none).
  static bool Covers(const Light& light);
  static bool Covers(const Scene& scene, int light);
  // Whether the map holds the caustics of the environment's light along world direction d
  // (unit, towards the sky): the directions of its sun (EnvironmentSun), where it has one.
  bool CoversEnvironment(const Vec3& d) const { return sun_ != nullptr && sun_->Contains(d); }

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
  struct Index;  // the build's k-d tree over all stored photons
  struct Site {
    float x, y, z, radius2;  // a site's position and its disc's squared radius, packed
  };
  uint32_t lobes_ = 0;
  const EnvironmentSun* sun_ = nullptr;  // the scene's, where the map holds it
  std::vector<Photon> photons_;          // the sites: every kSiteStride-th stored photon
  std::vector<Estimate> estimates_;      // their irradiance estimates
  std::vector<Site> sites_;
  // A grid over the sites' bounds: cell c lists the sites whose disc's box reaches it,
  // cell_sites_[cell_start_[c] .. cell_start_[c + 1]). Most lookups far from any caustic find an
  // empty cell; the others scan one cell's list.
  Vec3 grid_lo_, grid_scale_;
  int grid_n_ = 0;
  std::vector<uint32_t> cell_start_, cell_sites_;
};

}  // namespace irfarm
