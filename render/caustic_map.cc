#include "render/caustic_map.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <nanoflann.hpp>

#include "render/bsdfs/bsdf.h"
#include "render/environment_sun.h"
#include "render/sampling.h"
#include "render/scene.h"

namespace irfarm {
namespace {

// Photons on the other side of a thin wall, or around a corner, do not count.
constexpr float kNormalCos = 0.9f;
// CausticReuse: an answer holds within this fraction of its site's gather radius (the radius
// holds `gather` photons, one in kSiteStride of them a site, so a site's cell is about a third
// of it across) or, where no site's disc holds the point, of the distance to the nearest site; and
// for normals within about 8 degrees.
constexpr float kReuseReach = 0.1f;
constexpr float kReuseNormalCos = 0.99f;
// Delta bounces a photon may take (glass spheres take two per pass).
constexpr int kMaxChain = 16;
constexpr uint64_t kPhotonStream = 0xca05714c;
// Photons emitted per batch: the stop is checked between batches.
constexpr long kBatch = 1 << 16;
constexpr int kGrid = 64;  // lookup grid cells per axis (at most)
// The lookup grid's cell lists hold at most this many entries (4 bytes each): where the sites'
// discs are wide against the grid's cells (a small caustic whose sparse photons gather out to the
// 2% radius cap), the grid is made coarser until they fit. The answers do not depend on it.
constexpr size_t kMostCellEntries = size_t(1) << 23;
// Irradiance is estimated (from all photons) at every 8th photon only, and lookups search those
// sites: on specular at its defaults, alternated with renders without the map (seeds 3-6, loaded
// machine), relMSE 8.5e-4 in 9.4 CPU s against 1.12e-3 in 9.8 s without; at every photon (stride
// 1) the map's build and lookups cost more than it saved (8.5e-4 in 8.5-9.0 s wall against
// 9.2e-4 to 9.8e-4 in 4.8-6.2 s).
constexpr size_t kSiteStride = 8;

// A map is kept only where at least this share of the emitted photons (of equal power: each
// carries the lights' total flux, and Russian roulette keeps it) lands after a caustic bounce,
// judged on the first batch (65,536 photons) and counting only photons that land somewhere (not
// those Trace reports lost at once: they left the scene or met a back that reflects nothing,
// light the image does not hold). Where fewer do, the caustics carry little of the
// light, and the map's build and the record paths' lookups cost more than the error they save
// (make_room rooms at defaults, seeds 7-9, docs/bench/glossy-caustics-2026-12-05/): rooms 422
// (a point light over an aluminium box) and 430 (a point light, two spots and the sun over one)
// stored 1.0% and 1.7% and rendered the same error for 10-12% more CPU; rooms 401, 423 and 425
// (spot lights over metal boxes) 8%, 14% and 16%, where the error in 8 x 8 bins halved; specular
// (a mirror sphere and glass) 8%; materials 1.6% (the same error with and without its map).
constexpr double kLeastCausticShare = 0.04;

// A directional light's photons leave a square across its direction that covers the bounding
// sphere of the shapes with the map's lobes (light that reaches none of them makes no caustic),
// from beyond the scene. Most of it meets a room's walls from outside, so a projection map
// (Jensen 1996) learnt from the first batch (the pilot, uniform over the square, whose photons
// are then dropped) aims the later batches: a kProjection^2 grid over the square marks the cells
// whose pilot photons landed inside (Trace: not lost at once), grown by one cell, and a photon
// comes from a marked cell with probability 1 - kDefensive, else from anywhere on the square.
// Its power divides by that mixture's density, so light through cells the pilot missed is still
// counted, only with fewer, brighter photons.
constexpr int kProjection = 64;
constexpr float kDefensive = 0.1f;

struct Emitter {
  int light = 0;  // -1: the environment's sun (EnvironmentSun)
  Vec3 flux;      // W
  float pick = 0;
  // Directional lights and the environment's sun (see kProjection).
  Vec3 square_center, square_s, square_t;  // centre and half-edges (across the light)
  Vec3 square_axis;                        // the light's (mean) travel direction
  float square_back = 0;                   // how far upstream of the centre the square lies
  std::vector<uint32_t> cells;             // the marked cells; empty: uniform
  std::vector<uint8_t> marked;             // kProjection^2 flags
};

// A glossy lobe counts as sharp (its caustics then go to the map: CausticMap::Lobes) where its
// BRDF at normal incidence and exit reaches this many per steradian (a white Lambertian's is
// 1 / pi): aluminium at alpha 0.1 is about 7, at 0.15 3.2, at 0.2 1.8, at 0.3 0.8; a plastic's
// coat (4% Fresnel) at alpha 0.1 about 0.3. Measured at defaults (make_room rooms, seeds 7-9,
// docs/bench/glossy-caustics-2026-12-05/): room-401 (a spot over an aluminium box at alpha 0.1)
// relMSE 1.15-1.78e-3 -> 1.12-1.13e-3 for 13% more CPU, its records' blotches (the box's
// highlight reflected onto the walls and the ceiling) gone; rooms 404 and 702 (boxes at alpha
// 0.22 and 0.26, peaks 1.5 and 1.0) the same error for 8-10% more CPU: their highlights are not
// what their error is made of, so they keep them in the records.
constexpr float kSharpGlossyPeak = 3.0f;

bool HasSharpGlossy(const Bsdf& bsdf) {
  if ((bsdf.Flags() & kGlossyReflection) == 0) return false;
  const Vec3 n(0, 0, 1);
  return MaxComponent(bsdf.Eval(BsdfContext{}, n, n, kGlossyReflection)) >= kSharpGlossyPeak;
}

// Solid angle a spot light emits into (its cutoff cone).
float SpotSolidAngle(const Light& l) { return 2 * kPi * (1 - l.cos_cutoff); }

// Whether emitter e's photons leave a square (a directional light, or the environment's sun).
bool FromSquare(const Scene& scene, const Emitter& e) {
  return e.light < 0 || scene.lights()[size_t(e.light)].type == LightType::kDirectional;
}

// A square across travel direction `dir` whose photons reach every point of `target` along
// directions within `spread` radians of dir, lying upstream of the whole scene (Emitter).
void PlaceSquare(const Scene& scene, const Bounds3& target, const Vec3& dir, float spread,
                 Emitter* e) {
  const float r = 0.5f * Length(target.Diagonal()) * 1.001f + 1e-6f;
  // Upstream of every point of the scene: the centre is inside the scene's bounds.
  e->square_back = Length(scene.bounds().Diagonal()) * 1.01f + r;
  const float half = r / std::cos(spread) + e->square_back * std::tan(spread);
  Vec3 s, t;
  MakeFrame(dir, &s, &t);
  e->square_center = target.Center();
  e->square_axis = dir;
  e->square_s = s * half;
  e->square_t = t * half;
}

std::vector<Emitter> Emitters(const Scene& scene, const EnvironmentSun& sun) {
  std::vector<Emitter> out;
  const std::vector<Light>& lights = scene.lights();
  // A delta light's caustics need a glossy lobe next to it (see Trace).
  const uint32_t lobes = CausticMap::Lobes(scene);
  const bool glossy = (lobes & kSmoothNonDiffuseLobes) != 0;
  if (!sun.empty() && lobes != 0) {
    const Bounds3 target = scene.BoundsOfLobes(lobes);
    if (!target.Empty()) {
      Emitter e{-1, Vec3(), 0};
      PlaceSquare(scene, target, -sun.axis(), sun.radius(), &e);
      e.flux = Vec3(sun.irradiance() * 4 * LengthSquared(e.square_s));
      if (Luminance(e.flux) > 0 && IsFinite(e.flux)) out.push_back(e);
    }
  }
  for (int i = 0; i < int(lights.size()); ++i) {
    const Light& l = lights[size_t(i)];
    if (!CausticMap::Covers(l) || (l.IsDelta() && !glossy)) continue;
    Vec3 flux;
    Emitter e{i, Vec3(), 0};
    if (l.type == LightType::kDirectional) {
      const Bounds3 target = scene.BoundsOfLobes(lobes);
      if (target.Empty()) continue;
      PlaceSquare(scene, target, l.direction, 0, &e);
      flux = l.intensity * (4 * LengthSquared(e.square_s));
    } else if (l.type == LightType::kArea) {
      const float area =
          l.shape == AreaShape::kSphere ? 4 * kPi * l.radius * l.radius : std::max(0.0f, l.area);
      flux = l.radiance * (kPi * area);
    } else if (l.type == LightType::kPoint) {
      flux = l.intensity * (4 * kPi);
    } else {  // spot: at most its intensity over the cutoff cone (the falloff lowers it)
      flux = l.intensity * SpotSolidAngle(l);
    }
    if (!(Luminance(flux) > 0) || !IsFinite(flux)) continue;
    e.flux = flux;
    out.push_back(e);
  }
  double total = 0;
  for (const Emitter& e : out) total += Luminance(e.flux);
  for (Emitter& e : out) e.pick = float(Luminance(e.flux) / total);
  return out;
}

// A photon leaving emitter e: its ray and power (flux over the emitter's pick probability; the
// count emitted divides it at the end).
// *cell (optional) receives a square's projection cell (else -1).
void Emit(const Scene& scene, const EnvironmentSun& sun, const Emitter& e, Rng& rng, Ray* ray,
          Vec3* power, int* cell) {
  if (cell != nullptr) *cell = -1;
  const float u1 = rng.Next(), u2 = rng.Next(), u3 = rng.Next(), u4 = rng.Next();
  // The light's travel direction and what it carries per unit area of the square: a
  // directional light's irradiance, or the sun's radiance along a sampled direction over its
  // density, projected on the square.
  Vec3 travel, per_area;
  const bool square = FromSquare(scene, e);
  if (e.light < 0) {
    Vec3 d;
    float pdf;
    sun.Sample(rng.Next(), rng.Next(), rng.Next(), &d, &pdf);
    travel = -d;
    const float cos = Dot(d, sun.axis());
    per_area = pdf > 0 && cos > 0 ? scene.EvalEnvironment(d) * (cos / pdf) : Vec3();
    if (!IsFinite(per_area)) per_area = Vec3();  // a scene's map may hold non-finite texels
  } else if (square) {
    travel = scene.lights()[size_t(e.light)].direction;
    per_area = scene.lights()[size_t(e.light)].intensity;
  }
  if (square) {            // see kProjection
    float x = u1, y = u2;  // in [0, 1)^2 over the square
    const float n = float(e.cells.size());
    if (!e.cells.empty() && u3 >= kDefensive) {
      const float pick = u4 * n;
      const uint32_t c = e.cells[std::min(size_t(pick), e.cells.size() - 1)];
      x = (float(c % kProjection) + u1) * (1.0f / kProjection);
      y = (float(c / kProjection) + u2) * (1.0f / kProjection);
    }
    // The mixture's density over the square, relative to uniform.
    float density = 1;
    if (!e.cells.empty()) {
      const int cx = std::min(int(x * kProjection), kProjection - 1);
      const int cy = std::min(int(y * kProjection), kProjection - 1);
      const bool in = e.marked[size_t(cy * kProjection + cx)] != 0;
      density = kDefensive + (in ? (1 - kDefensive) * float(kProjection * kProjection) / n : 0.0f);
    }
    const Vec3 p = e.square_center + e.square_s * (2 * x - 1) + e.square_t * (2 * y - 1) -
                   e.square_axis * e.square_back;
    *ray = Ray{p, travel, INFINITY};
    *power = per_area * (4 * LengthSquared(e.square_s) / (e.pick * density));
    if (cell != nullptr) {
      *cell = std::min(int(y * kProjection), kProjection - 1) * kProjection +
              std::min(int(x * kProjection), kProjection - 1);
    }
    return;
  }
  const Light& l = scene.lights()[size_t(e.light)];
  if (l.type == LightType::kPoint || l.type == LightType::kSpot) {
    Vec3 dir;
    Vec3 flux = e.flux;
    if (l.type == LightType::kPoint) {
      dir = UniformSphere(u1, u2);
    } else {  // uniform over the cutoff cone, weighted by the falloff
      Vec3 s, t;
      MakeFrame(l.direction, &s, &t);
      const Vec3 local = UniformCone(u1, u2, l.cos_cutoff);
      dir = s * local.x + t * local.y + l.direction * local.z;
      flux = flux * SpotFalloff(l, -dir);
    }
    *ray = Ray{l.position, dir, INFINITY};
    *power = flux / e.pick;
    return;
  }
  Vec3 p, n;
  float scale = l.error_scale;
  if (l.shape == AreaShape::kRect) {
    p = l.corner + l.edge_u * u1 + l.edge_v * u2;
    n = l.normal;
  } else if (l.shape == AreaShape::kSphere) {
    const Vec3 d = UniformSphere(u1, u2);
    p = l.center + d * l.radius;
    n = l.flip ? -d : d;
  } else {
    const LightTriangle& t = l.PickTriangle(u1);
    float b0, b1;
    UniformTriangle(rng.Next(), u2, &b0, &b1);
    p = t.p0 * b0 + t.p1 * b1 + t.p2 * (1 - b0 - b1);
    n = t.ng;
    scale = t.error_scale;
  }
  Vec3 s, t;
  MakeFrame(n, &s, &t);
  const Vec3 local = CosineHemisphere(u3, u4);
  const Vec3 dir = s * local.x + t * local.y + n * local.z;
  *ray = Scene::SpawnRay(p, n, scale, dir);
  *power = e.flux / e.pick;
}

// Follows one photon; appends it (unscaled) to *out at every diffuse surface it reaches after
// one or more non-diffuse bounces. From a delta light (point, spot) the first bounce must not be
// a delta lobe: a path traced from the other end reaches such a light only by next-event
// estimation, which a delta lobe cannot make, so neither our path tracer nor Mitsuba's has that
// light (a spot's caustic through a mirror).
// Returns whether the photon was lost at once: it hit nothing, or its first hit was the back of
// a surface that reflects nothing there (a room's one-sided wall seen from outside, where most
// of a sun's photons land). That is light the image does not hold, left out of the map's share
// (Build).
bool Trace(const Scene& scene, uint32_t lobes, Ray ray, Vec3 power, bool delta_light, Rng& rng,
           std::vector<CausticMap::Photon>* out) {
  int bounces = 0;  // non-diffuse scattering events so far (a mask's pass-through is not one)
  for (int i = 0; i < kMaxChain; ++i) {
    SurfaceHit hit;
    if (!scene.Intersect(ray, &hit)) return i == 0;
    const Bsdf& bsdf = scene.material(hit.material);
    const BsdfContext ctx = hit.Context();
    const ShadingFrame frame = hit.Frame();
    const Vec3 wo = -ray.dir;
    const Vec3 wo_l = frame.ToLocal(wo);
    const bool diffuse = !IsBlack(bsdf.DiffuseAlbedo(ctx, wo_l));
    const bool back_of_dark = i == 0 && !diffuse && Dot(wo, hit.ng) <= 0;
    if (bounces > 0 && diffuse)
      out->push_back(CausticMap::Photon{hit.p, wo_l.z >= 0 ? hit.ns : -hit.ns, power});
    if ((bsdf.Flags() & lobes) == 0) return back_of_dark;
    const float u1 = rng.Next(), u2 = rng.Next(), u3 = rng.Next();
    const BsdfSample bs = bsdf.Sample(ctx, wo_l, u1, u2, u3, lobes);
    if (IsBlack(bs.weight)) return back_of_dark;
    if (delta_light && bounces == 0 && bs.IsDelta() && bs.lobe != kNullTransmission) return false;
    const Vec3 wi = frame.ToWorld(bs.wi);
    if (!SidesAgree(wo, wi, hit.ng, wo_l.z, bs.wi.z)) return false;
    // The weight is radiance's: a refraction scales radiance by 1 / eta^2, flux not at all.
    Vec3 w = bs.weight * (bs.eta * bs.eta);
    if (bs.lobe != kNullTransmission) ++bounces;
    const float q = std::min(1.0f, MaxComponent(w));
    if (!(q > 0)) return false;
    if (q < 1) {
      if (rng.Next() >= q) return false;
      w = w / q;
    }
    power *= w;
    ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale, wi);
  }
  return false;
}

}  // namespace

struct CausticMap::Index {
  struct Cloud {
    const std::vector<Photon>* photons;
    size_t kdtree_get_point_count() const { return photons->size(); }
    float kdtree_get_pt(size_t i, size_t dim) const {
      const Vec3& p = (*photons)[i].p;
      return dim == 0 ? p.x : dim == 1 ? p.y : p.z;
    }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
      return false;
    }
  };
  using Tree =
      nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>, Cloud, 3>;
  Cloud cloud;
  Tree tree;
  explicit Index(const std::vector<Photon>* photons)
      : cloud{photons}, tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {}
};

CausticMap::CausticMap() = default;
CausticMap::~CausticMap() = default;

bool CausticMap::Covers(const Light& l) {
  if (l.IsDelta()) return true;
  return l.type == LightType::kArea && !(l.shape == AreaShape::kMesh && l.cdf.empty());
}

bool CausticMap::Covers(const Scene& scene, int light) {
  return light >= 0 && Covers(scene.lights()[size_t(light)]);
}

uint32_t CausticMap::Lobes(const Scene& scene) {
  uint32_t lobes = 0;
  for (int i = 0; i < scene.num_materials(); ++i) {
    const Bsdf& m = scene.material(i);
    if ((m.Flags() & (kDeltaReflection | kDeltaTransmission)) != 0) lobes |= kDeltaLobes;
    if (HasSharpGlossy(m)) lobes |= kSmoothNonDiffuseLobes | kNullTransmission;
  }
  return lobes;
}

bool CausticMap::SceneHasCaustics(const Scene& scene) {
  return Lobes(scene) != 0 && !Emitters(scene, scene.environment_sun()).empty();
}

std::unique_ptr<CausticMap> CausticMap::Build(const Scene& scene,
                                              const CausticMapSettings& settings,
                                              tbb::task_arena& arena, CausticMapStats* stats) {
  CausticMapStats st;
  std::unique_ptr<CausticMap> map;
  const uint32_t lobes = Lobes(scene);
  const EnvironmentSun& sun = scene.environment_sun();
  std::vector<Emitter> emitters = Emitters(scene, sun);
  if (lobes != 0 && !emitters.empty()) {
    std::vector<float> cdf;
    float acc = 0;
    for (const Emitter& e : emitters) cdf.push_back(acc += e.pick);
    bool pilot = false;     // the first batch only aims the squares' photons (kProjection)
    bool from_sun = false;  // the environment's sun is one of the emitters
    for (const Emitter& e : emitters) {
      from_sun |= e.light < 0;
      pilot |= FromSquare(scene, e);
    }
    std::vector<Photon> photons;
    constexpr long kChunk = 1024;
    std::vector<std::vector<Photon>> chunks(kBatch / kChunk);
    std::vector<long> chunk_lost(chunks.size());
    // Pilot: (emitter, projection cell) of each square's photon that landed.
    std::vector<std::vector<std::pair<uint32_t, uint32_t>>> chunk_landed(chunks.size());
    // Photons lost at once (Trace): they hit nothing, or a back that reflects nothing.
    long lost = 0;
    long counted = 0;  // photons emitted after the pilot: the stored photons' power divides by it
    while (long(photons.size()) < settings.target_photons && st.emitted < settings.max_emitted) {
      const long first = st.emitted;
      const bool in_pilot = pilot && first == 0;
      arena.execute([&] {
        tbb::parallel_for(size_t(0), chunks.size(), [&](size_t c) {
          chunks[c].clear();
          chunk_lost[c] = 0;
          chunk_landed[c].clear();
          for (long k = 0; k < kChunk; ++k) {
            const long index = first + long(c) * kChunk + k;
            Rng rng(HashCombine(settings.seed, kPhotonStream), uint64_t(index));
            const float u = rng.Next() * acc;
            size_t ei = size_t(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin());
            ei = std::min(ei, emitters.size() - 1);
            Ray ray;
            Vec3 power;
            int cell = -1;
            Emit(scene, sun, emitters[ei], rng, &ray, &power, &cell);
            const int light = emitters[ei].light;
            const bool gone =
                Trace(scene, lobes, ray, power,
                      light >= 0 && scene.lights()[size_t(light)].IsDelta(), rng, &chunks[c]);
            chunk_lost[c] += gone;
            if (in_pilot && !gone && cell >= 0) chunk_landed[c].emplace_back(ei, cell);
          }
        });
      });
      st.emitted += kBatch;
      for (const std::vector<Photon>& c : chunks) photons.insert(photons.end(), c.begin(), c.end());
      for (const long a : chunk_lost) lost += a;
      if (first == 0 && double(photons.size()) < kLeastCausticShare * double(kBatch - lost)) {
        photons.clear();  // the caustics carry too little of the light: no map
        break;
      }
      if (!in_pilot) {
        counted += kBatch;
        continue;
      }
      // Mark the cells the pilot's photons landed through, and their neighbours.
      for (Emitter& e : emitters)
        if (FromSquare(scene, e)) e.marked.assign(size_t(kProjection * kProjection), 0);
      for (const auto& c : chunk_landed)
        for (const auto& [ei, cell] : c) {
          const int cx = int(cell) % kProjection, cy = int(cell) / kProjection;
          for (int y = std::max(cy - 1, 0); y <= std::min(cy + 1, kProjection - 1); ++y)
            for (int x = std::max(cx - 1, 0); x <= std::min(cx + 1, kProjection - 1); ++x)
              emitters[ei].marked[size_t(y * kProjection + x)] = 1;
        }
      for (Emitter& e : emitters)
        for (uint32_t c = 0; c < e.marked.size(); ++c)
          if (e.marked[c]) e.cells.push_back(c);
      photons.clear();
    }
    if (!photons.empty()) {
      const float inv = 1.0f / float(counted);
      for (Photon& p : photons) p.power *= inv;
      map.reset(new CausticMap());
      map->lobes_ = lobes;
      if (from_sun) map->sun_ = &sun;
      st.stored = long(photons.size());
      const Index all(&photons);
      // Estimates at every kSiteStride-th photon only: the lookups' sites.
      for (size_t i = 0; i < photons.size(); i += kSiteStride) map->photons_.push_back(photons[i]);
      // Photons farther than this (1/50 of the scene's diagonal) never make an estimate: a
      // sparse caustic is blurred at most that far.
      const Vec3 extent = scene.bounds().hi - scene.bounds().lo;
      const float max_r = 0.02f * Length(extent);
      const float max_r2 = max_r * max_r;
      const size_t k = size_t(std::max(1, settings.gather));
      map->estimates_.resize(map->photons_.size());
      arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, map->photons_.size(), 256),
                          [&](const tbb::blocked_range<size_t>& r) {
                            std::vector<uint32_t> idx(k);
                            std::vector<float> d2(k);
                            for (size_t i = r.begin(); i < r.end(); ++i) {
                              const Photon& ph = map->photons_[i];
                              const float q[3] = {ph.p.x, ph.p.y, ph.p.z};
                              const size_t n = all.tree.knnSearch(q, k, idx.data(), d2.data());
                              float r2 = n > 0 ? std::min(d2[n - 1], max_r2) : max_r2;
                              if (n < k) r2 = max_r2;  // fewer photons than k in the whole map
                              Vec3 sum;
                              for (size_t j = 0; j < n; ++j) {
                                const Photon& o = photons[idx[j]];
                                if (d2[j] <= r2 && Dot(o.n, ph.n) >= kNormalCos) sum += o.power;
                              }
                              map->estimates_[i] = Estimate{sum / (kPi * r2), r2};
                            }
                          });
      });
      // A grid over the sites' discs: each cell lists the sites whose disc's box reaches it
      // (compressed rows: cell_start_ into cell_sites_), so a lookup scans one cell's list.
      Vec3 lo(INFINITY), hi(-INFINITY);
      for (const Photon& p : map->photons_) {
        lo = Min(lo, p.p);
        hi = Max(hi, p.p);
      }
      lo = lo - Vec3(max_r);
      hi = hi + Vec3(max_r);
      const Vec3 size = Max(hi - lo, Vec3(1e-6f));
      map->grid_lo_ = lo;
      map->sites_.resize(map->photons_.size());
      // The cells a site's disc box spans at n cells per axis, as [a, b] per axis.
      const auto span = [&](size_t i, int n, int a[3], int b[3]) {
        const float r = std::sqrt(map->estimates_[i].radius2);
        const Vec3 scale(float(n) / size.x, float(n) / size.y, float(n) / size.z);
        const Vec3 lo_f = (map->photons_[i].p - Vec3(r) - lo) * scale;
        const Vec3 hi_f = (map->photons_[i].p + Vec3(r) - lo) * scale;
        const auto cell = [n](float v) { return std::clamp(int(v), 0, n - 1); };
        a[0] = cell(lo_f.x), a[1] = cell(lo_f.y), a[2] = cell(lo_f.z);
        b[0] = cell(hi_f.x), b[1] = cell(hi_f.y), b[2] = cell(hi_f.z);
      };
      int n = kGrid;
      for (; n > 1; n /= 2) {
        size_t entries = 0;
        for (size_t i = 0; i < map->photons_.size(); ++i) {
          int a[3], b[3];
          span(i, n, a, b);
          entries += size_t(b[0] - a[0] + 1) * size_t(b[1] - a[1] + 1) * size_t(b[2] - a[2] + 1);
        }
        if (entries <= kMostCellEntries) break;
      }
      map->grid_n_ = n;
      map->grid_scale_ = Vec3(float(n) / size.x, float(n) / size.y, float(n) / size.z);
      const size_t cells = size_t(n) * size_t(n) * size_t(n);
      map->cell_start_.assign(cells + 1, 0);
      const auto for_cells = [&](size_t i, const auto& fn) {
        int a[3], b[3];
        span(i, n, a, b);
        for (int z = a[2]; z <= b[2]; ++z)
          for (int y = a[1]; y <= b[1]; ++y)
            for (int x = a[0]; x <= b[0]; ++x)
              fn((size_t(z) * size_t(n) + size_t(y)) * size_t(n) + size_t(x));
      };
      for (size_t i = 0; i < map->photons_.size(); ++i) {
        const Vec3& q = map->photons_[i].p;
        map->sites_[i] = Site{q.x, q.y, q.z, map->estimates_[i].radius2};
        for_cells(i, [&](size_t c) { ++map->cell_start_[c + 1]; });
      }
      for (size_t c = 0; c < cells; ++c) map->cell_start_[c + 1] += map->cell_start_[c];
      map->cell_sites_.resize(map->cell_start_[cells]);
      std::vector<uint32_t> fill(map->cell_start_.begin(), map->cell_start_.end() - 1);
      for (size_t i = 0; i < map->photons_.size(); ++i)
        for_cells(i, [&](size_t c) { map->cell_sites_[fill[c]++] = uint32_t(i); });
    }
  }
  if (stats) *stats = st;
  return map;
}

Vec3 CausticMap::Irradiance(const Vec3& p, const Vec3& n, CausticReuse* reuse) const {
  const Vec3 g = (p - grid_lo_) * grid_scale_;
  if (!(g.x >= 0 && g.y >= 0 && g.z >= 0 && g.x < grid_n_ && g.y < grid_n_ && g.z < grid_n_))
    return Vec3();
  const size_t c = (size_t(g.z) * size_t(grid_n_) + size_t(g.y)) * size_t(grid_n_) + size_t(g.x);
  const uint32_t begin = cell_start_[c], end = cell_start_[c + 1];
  if (begin == end) return Vec3();
  if (reuse != nullptr && LengthSquared(p - reuse->p) <= reuse->reach2 &&
      Dot(n, reuse->n) >= kReuseNormalCos)
    return reuse->value;
  // Of the sites whose disc holds p on the same side, the nearest; none: no caustic here.
  float nearest2 = INFINITY, best2 = INFINITY;
  uint32_t best = 0;
  for (uint32_t k = begin; k < end; ++k) {
    const uint32_t i = cell_sites_[k];
    const Site& s = sites_[i];
    const float dx = s.x - p.x, dy = s.y - p.y, dz = s.z - p.z;
    const float d2 = dx * dx + dy * dy + dz * dz;
    nearest2 = std::min(nearest2, d2);
    if (d2 <= s.radius2 && d2 < best2 && Dot(photons_[i].n, n) >= kNormalCos) {
      best2 = d2;
      best = i;
    }
  }
  Vec3 value;
  float reach2 = kReuseReach * kReuseReach * nearest2;
  if (best2 < INFINITY) {
    value = estimates_[best].irradiance;
    reach2 = kReuseReach * kReuseReach * estimates_[best].radius2;
  }
  if (reuse != nullptr) *reuse = CausticReuse{p, n, value, reach2};
  return value;
}

}  // namespace irfarm
