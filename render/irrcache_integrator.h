// The irradiance-cache integrator (Ward 1988, as in the lecture). Camera paths are traced through
// specular (delta) surfaces to the first diffuse surface x. There:
//   - emission seen directly or through specular chains is counted as is;
//   - direct light from local lights (area, point, spot, directional) is always computed
//     explicitly by next-event estimation;
//   - everything else arriving at x (light from other surfaces, from the environment, and caustics
//     through specular surfaces) is the indirect irradiance E, interpolated from cached records
//     with Ward's weights, or, when no record counts, computed as a new record and inserted.
// A new record samples the hemisphere around x's facing normal with T x P stratified
// cosine-weighted rays (E = pi/(TP) sum L); the radiance along each ray is estimated by the
// unbiased path tracer from the ray's first hit on (by default: unbiased beyond the first bounce;
// cache_levels = 2 puts a second-level cache there instead). Environment light is integrated by the
// records, as RADIANCE does with sky glow: it is smooth over a surface, so caching it removes most
// of its noise; with an environment map a record also samples the map by its radiance, weighed
// against its strata by multiple importance sampling (environment_samples). R_i is the harmonic
// mean of the ray hit distances (escaped rays add 1/d = 0), clamped so that the validity radius a *
// R_i covers between min_spacing_px and max_spacing_px pixels at x: the clamps adapt to the image
// resolution and the scene's scale. Two sides of a surface have separate records: a record's normal
// faces the side it was made on.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "cache/irradiance_cache.h"
#include "render/aov.h"
#include "render/caustic_map.h"
#include "render/path_tracer.h"
#include "render/pixel_sampler.h"
#include "render/scene.h"

namespace irfarm {

// How a record's validity radius R_i (eps_i = |x - x_i| / R_i + ...) is chosen.
enum class RecordSpacing {
  kSplitSphere,  // Ward's: the harmonic mean of the rays' hit distances (worst-case gradient)
  kHessian,      // the record's own gradient and Hessian (render/irradiance_hessian.h)
};
// The names the CLI takes (--spacing) and the stats print.
inline const char* RecordSpacingName(RecordSpacing s) {
  return s == RecordSpacing::kHessian ? "hessian" : "split-sphere";
}

struct IrrcacheSettings {
  float accuracy = 0.1f;  // Ward's a: records count when eps_i < a (RADIANCE rtrace -aa 0.1)
  // Rays per record, T x P with P ~ pi T (measured: docs/guide/irradiance-cache.md).
  int record_rays = 1536;
  int light_samples = 1;  // direct-light samples per shading point and camera sample
  // Hessian by default since the wider camera lookups (lookup_factor): at equal records it halves
  // the cache's own error against the split sphere's on all eight indirect-only scenes; the split
  // sphere stays for comparison (docs/guide/irradiance-cache.md, "Hessian spacing").
  RecordSpacing spacing = RecordSpacing::kHessian;
  // Lookups take the value of the plane fitted to the records that count (weighted least
  // squares, Ward's weights; CacheSettings::linear_fit, cache/local_linear_fit.h) instead of
  // their weighted mean; false: Ward's weighted mean (`--interpolation ward`, for comparison).
  // --target-error keeps Ward's mean: its error model was calibrated with it.
  bool linear_fit = true;
  // Rectangles' direct light as analytic unoccluded irradiance times the pixel's shadow ratio
  // (DirectTerms); false: the plain Monte Carlo estimate (for comparison).
  bool analytic_direct = true;
  float min_spacing_px = 1.5f;   // validity radius a*R_i >= this many pixel footprints at x
  float max_spacing_px = 16.0f;  // ... and <= this many (Tabellion & Lamorlette: ~20 px)
  // Final pass only: a lookup that finds nothing at accuracy a is retried at a * relaxed_factor
  // before a new record is computed (RADIANCE likewise relaxes accuracy for low-weight rays).
  // Such misses are mostly camera samples that land, within an edge pixel, on a surface other
  // than the one the overture saw at the pixel's centre: a small part of that pixel.
  float relaxed_factor = 2.0f;
  // Camera lookups (level 0) weigh the records within eps_i < a * lookup_factor, while a record
  // is still made wherever none counts at a: the records are spaced as before, and each point
  // averages more of them, so that one record's noise covers no patch of its own (the blotches of
  // a room lit by a small bright patch of ceiling). 1 = Ward's rule. The wider answer is taken
  // only where its luminance is within lookup_agreement of the answer of the records at a alone:
  // a larger difference is structure, not noise (the dark gap between a lamp and the ceiling, the
  // foot of a panel), and the records at a answer there. Measured: docs/guide/irradiance-cache.md,
  // "Wider lookups".
  float lookup_factor = 1.5f;
  float lookup_agreement = 0.25f;
  // Neighbour clamping of record radii (CacheSettings::neighbour_slope): R_i <= R_j + 3 |x_i -
  // x_j|. Measured on the 9 shared scenes at defaults: cornell-box 2.9x lower relMSE (its lamp-gap
  // leak), specular 1.8x, thin-panels 1.3x, veach-ajar 1.2x, the others unchanged, for 5-11% more
  // records (veach-ajar 33%). Slope 1 (Krivanek et al.) cost up to 90% more records for the same
  // gain on cornell-box; slope 10 changed nothing.
  float neighbour_slope = 3.0f;
  // Occluder clamp of secondary records (level >= 1: made through glossy lobes or for other
  // records' rays, spaced for a ray cone many pixels wide): the validity radius a_max * R_i
  // (a_max: the relaxed lookups' accuracy) is at most occluder_reach times the record's nearest
  // ray hit, so that it does not reach across a thin occluder (a panel standing on the floor, a
  // partition, a curtain: its two sides see different light); never below occluder_floor_px of
  // the record's footprints (at a concave edge the nearest hit goes to 0, and records follow it).
  // Camera records (level 0) are not clamped: their 1.5-pixel floor bounds a leak to 1.5 pixels.
  // Measured on tests/data/scenes/principledthin (full size, 256 spp, 2 seeds), what is seen
  // through the frosted panel: off 6.4% dark; floor 1 footprint 2.5%, 0.5: 2%, 0.1: 0.8%. On
  // living-room (fixed rays, quiet machine) its cost in CPU: +4..18%, +11%, +30%; relMSE the same
  // within 2%. cache_levels 2 on thin-panels: 1.6e-3 off, 4.6e-4, 3.4e-4, 3.6e-4. 0 = off.
  float occluder_reach = 0.7f;
  float occluder_floor_px = 1.0f;
  // Records (camera records too, see occluder_plane_fraction) keep the plane through their nearest
  // ray hit, perpendicular to that ray (IrradianceRecord::occluder), and are not used beyond it. On
  // cornell-box a camera record on the ceiling by the lamp, valid 1.5 pixels around by the spacing
  // floor, reached into the dark gap between lamp and ceiling: a bright line along the lamp's far
  // edge, about 35 pixels carrying half the image's error (seed 12: relMSE 6.6e-4 with the plane
  // off, 3.5e-4 on; seed 14: 5.7e-4 against 2.9e-4). Records made: +0-4% on room-a ... room-d,
  // specular, sunlit-room, thin-panels and veach-ajar; +23% on living-room (35k -> 43k), whose
  // error x time at defaults is then 1.02x what it was before this plane and kInterpolationFloor
  // together.
  bool occluder_plane = true;
  // A camera record keeps its plane only when at least this fraction of its rays hit within twice
  // its nearest hit's distance: a partition, a wall or a panel close by, not a leaf or a chair
  // leg (a plane through one small object's hit cuts off a half-space the object hardly
  // shades). A wall at distance h standing on the surface gets about 15% of cosine-weighted rays
  // within 2h, a panel hung parallel to the surface up to 25%; a leaf seen at 0.05 sr 1-2%.
  // Secondary records keep theirs whatever the fraction. 0 = every record with a hit.
  // Measured against 0 (seed 7 unless said): living-room at defaults, seeds 7-8, records 43.0k ->
  // 37.5k, CPU 48 -> 35 s, relMSE 2.32e-2 -> 2.33e-2 (mean); cornell-box's lamp gap stays closed
  // (300 rays, seeds 12/14: 3.6e-4 / 2.5e-4 against 3.5e-4 / 2.6e-4; 6.6e-4 / 5.7e-4 with no
  // planes); thin-panels (534 rays, seeds 7-10) 3.28e-4 -> 3.26e-4 mean; veach-ajar (340 rays,
  // seeds 7-15) median 1.08e-2 -> 1.18e-2, mean 1.67e-2 -> 1.40e-2 (its record noise: 8.5e-3 to
  // 3.7e-2 over seeds with either); room-a ... room-d, sunlit-room, specular within 5%.
  float occluder_plane_fraction = 0.05f;
  // Levels of cached irradiance (RADIANCE's ambient bounces are all cached likewise): 1 = a
  // record's rays are path traced (unbiased beyond the interpolation at x); 2 = they are shaded,
  // at the first diffuse surface they reach, by one direct-light sample plus that surface's own
  // cached irradiance (secondary records: secondary_ray_fraction of the rays, spaced for the
  // ray's cone, used only by other records' rays). At default settings the pilot chooses
  // (choose_cache_levels; TwoLevelsPay in render/record_balance.h): two where the two pilots'
  // figures predict a lower error x time (veach-ajar 4.5x lower relMSE, sunlit-room 1.8x), one
  // where the camera samples' error dominates (living-room) or the secondary records cost more
  // than they save (a cluttered still life). 3 = the secondary records' rays are shaded likewise
  // from a third level's records; chosen after two where most of the two-level pilot's secondary
  // records are one ray's light (ThreeLevelsPay: veach-ajar's door gap). Off when the levels are
  // given (scene, --cache-levels, the job's settings); --target-error chooses one or two.
  int cache_levels = 1;
  bool choose_cache_levels = true;
  // The two-level pilot stops, and one level is kept, once its pixels have taken this many times
  // the one-level pilot's thread time. Where two levels lose for being dear - a cluttered scene,
  // whose every record makes many secondary records of its own - the pilot is dear for the same
  // reason: living-room's took 2.4-2.6 thread-s against 0.37-0.44 s for the one-level pilot
  // (6-6.5x), and two levels lost there on every seed. Where two levels were taken it cost
  // 0.9-2.0x (seed 8: cornell-box 1.65, sunlit-room 1.5, thin-panels 1.6, room-a 1.12, room-b
  // 1.78, room-d 1.51, veach-ajar 2.0, make_room 931 and 940 1.08, 961 0.9-1.0, specular
  // 1.15-1.18). The recorded pilots of Mitsuba's layered_kitchen, where two levels lose 1.62x:
  // the two-level record time 4.7x the one-level one (veach-ajar 1.8x, make_room 602 0.8x).
  double two_level_pilot_cost_cap = 3.0;
  // With an environment map, a record also samples the map by its radiance (next-event samples,
  // each a shadow ray), weighed against its strata's rays by the balance heuristic (MIS): a bright
  // patch of the map (the sun's disc, a lamp in a studio map) is then found by many samples
  // instead of by the few strata that cover it. Their number is this share of the record's rays
  // times the share of kEnvironmentProbes samples of the map that find it unblocked from the
  // record's point (few deep in a room lit through a window). 0 = strata only. Measured against
  // strata only (seeds 7-8, CPU seconds alike or lower): an open still life lit by a studio map
  // (layered_kitchen, github.com/VElysianP/mitsuba_scenes) relMSE 22-40% lower; envmap rooms
  // 501 and 511 10-23% lower; living-room 3% lower on average; rooms 512 and 513 even in error x
  // time over five seeds; RecordEnvironmentTest checks it against strata alone.
  float environment_samples = 0.25f;
  // An environment map's sun (EnvironmentSun: a photographed sky's few directions far above the
  // rest) is direct light like a directional light's: one sample of it (by its luminance) with a
  // shadow ray at every diffuse point that takes direct light (DirectLight) and at every
  // non-delta vertex of the records' paths (PathSettings::direct_sun), and the records and the
  // paths leave it out of the environment's light wherever such a sample was made (their first
  // segment, their environment samples, escapes after a non-delta vertex). Without it, the sun
  // through a window is found by a record's few strata that point at it: its patch on the floor
  // and the light it sends on were the records' noise, the image's mean 20% off from seed to
  // seed (docs/bench/sun-caustics-2026-12-05/).
  bool direct_sun = true;
  static constexpr int kEnvironmentProbes = 16;
  float secondary_ray_fraction = 0.25f;
  // Default settings: lower record_rays where the pilot shows that records cost more than their
  // noise is worth against the camera samples (render/record_balance.h). Off when the rays are
  // given (scene, --record-rays, the job's settings) and with --target-error.
  bool balance_record_rays = true;
  PathSettings path;
  // Caustics (light from area lights through delta bounces only) from this photon map instead of
  // the records, which then leave that light out (see render/caustic_map.h). Built by
  // BuildCausticMap (RenderSettings::caustics): per render by RenderRect, or once per job by the
  // worker's JobContext; not owned; null: the records keep it.
  const CausticMap* caustics = nullptr;
};

// What the lookups of camera-visible surfaces may reuse across a pixel's samples and its
// neighbours (the caller keeps one per render thread): gathered records
// (IrradianceCache::LookupNear) and the caustic map's last answer.
struct PixelReuse {
  LookupRegion region;
  CausticReuse caustic;
};

struct IrrcacheShade {
  bool made_record = false;
  PixelReuse* reuse = nullptr;  // in, optional
};

// Direct light from lights with a closed-form unoccluded irradiance (rectangles), kept apart per
// light so that a pixel's estimate can be formed as a ratio (Heitz, Hill and McGuire 2018,
// "Combining analytic direct illumination and stochastic shadows"):
//   D_j = (sum_s A_j,s) * (sum_s S_j,s) / (sum_s U_j,s)
// with, per camera sample s, A the analytic unoccluded term (throughput * albedo/pi * E_j), and
// S and U the Monte Carlo estimates of the same term with and without the shadow rays, from the
// same light samples. Where the light is fully visible over the pixel S = U and D = sum A: no
// noise from the light's shape; fully shadowed, S = 0 and D = 0; only penumbrae are noisy. The
// ratio is consistent (its bias vanishes as the pixel's samples grow), not unbiased: with few
// samples in a penumbra, and where albedo * irradiance varies inside the pixel together with the
// shadow, it deviates by O(1/samples).
struct DirectTerms {
  static constexpr int kMaxLights = 8;  // rectangles beyond the 8th use the plain estimator
  Vec3 analytic[kMaxLights], shadowed[kMaxLights], unshadowed[kMaxLights];
  void Add(const DirectTerms& o) {
    for (int j = 0; j < kMaxLights; ++j) {
      analytic[j] += o.analytic[j];
      shadowed[j] += o.shadowed[j];
      unshadowed[j] += o.unshadowed[j];
    }
  }
  // Whether every sum is finite (a NaN texel reaches the analytic term, which L does not hold).
  bool Finite() const {
    for (int j = 0; j < kMaxLights; ++j)
      if (!IsFinite(analytic[j]) || !IsFinite(shadowed[j]) || !IsFinite(unshadowed[j]))
        return false;
    return true;
  }
  // sum_j A_j * S_j / U_j, per channel (0 where U_j is 0).
  Vec3 Resolve() const;
  // s / u per channel, 0 where u is 0: the shadow ratio of one light's sums.
  static Vec3 Ratio(const Vec3& s, const Vec3& u) {
    return Vec3(u.x > 0 ? s.x / u.x : 0, u.y > 0 ? s.y / u.y : 0, u.z > 0 ? s.z / u.z : 0);
  }
};

// Where this camera sample's direct-light samples come from: points k = first .. first + count-1
// of the pixel's stratified set (see PixelSampler), so the pixel's light samples are stratified
// over the light's area.
struct LightStrata {
  const PixelSampler* sampler = nullptr;
  int first = 0;
};

class IrrcacheIntegrator {
 public:
  IrrcacheIntegrator(const Scene& scene, IrradianceCache* cache, const IrrcacheSettings& settings);

  // Radiance arriving at the camera along camera ray `ray`. With `terms`, the direct light of
  // rectangle lights goes there (for the pixel's ratio estimate, see DirectTerms) instead of
  // into the returned value; without, each sample's own ratio is used. `aov` (optional)
  // receives the sample's AOVs: direct = emission seen + explicit direct light, indirect = the
  // cached irradiance term (with `terms`, the rectangles' ratio part is added per pixel).
  Vec3 Li(const Ray& ray, const LightStrata& strata, Rng& rng, RenderCounters& counters,
          IrrcacheShade* shade, DirectTerms* terms = nullptr, SampleAov* aov = nullptr) const;
  // Overture: makes sure the cache covers the first diffuse surface seen along `ray`, computing
  // a record there if none counts, and nothing else. Returns true when it computed one.
  bool Prime(const Ray& ray, Rng& rng, RenderCounters& counters) const;

  // Cross-validation of the cache at the first diffuse surface seen along `ray`: the interpolated
  // irradiance against a fresh record made there (not inserted), in units of the pixel's
  // relMSE: ((w (E_interp - E_fresh))^2 - w^2 Var(E_fresh)) / (v^2 + 0.01) per channel,
  // averaged, with w = throughput * albedo / pi, Var(E_fresh) from the difference of the fresh
  // record's two interleaved halves of strata, and v the point's radiance (direct + indirect).
  // Its mean over random pixels estimates the cache's share of the image's relMSE. `noise`
  // receives the part of it the records' own noise explains: the fresh record's variance
  // (records made with the same rays have about as much) times the share of it the lookup's
  // weighted mean keeps, sum w_i^2 / (sum w_i)^2, in the same units. That part falls as 1 / rays
  // and not with the accuracy (a lookup averages about as many records at any a); the rest is
  // interpolation error, which falls with a. False where there is nothing to check (no diffuse
  // hit, or the lookup fails).
  // `ray_fraction` < 1: the fresh record takes that share of the rays (cheaper checks; its larger
  // variance is subtracted all the same, and `noise` is scaled back to the records' rays).
  // With `other_factor` > 0, *other_error and *other_noise receive the same figures for camera
  // lookups at that lookup_factor, from the same fresh record (the renderer's --target-error
  // compares two lookup rules on one set of checks).
  bool CacheError(const Ray& ray, Rng& rng, RenderCounters& counters, double* error, double* noise,
                  float ray_fraction = 1, float other_factor = 0, double* other_error = nullptr,
                  double* other_noise = nullptr) const;

  // The cache's irradiance at (p, nf) for a lookup at `level` (lookup_factor and
  // lookup_agreement at level 0), through `region` when given; false when no record counts at a
  // (a new record is due there). `info` must not be null.
  // `factor` < 0: the settings' lookup_factor.
  bool CachedIrradiance(const Vec3& p, const Vec3& nf, int level, float region_radius,
                        float region_angle, LookupRegion* region, Vec3* E, LookupInfo* info,
                        float factor = -1) const;

  // Pilot for balancing record rays (render/record_balance.h): computes (does not insert) a
  // record at the first diffuse surface seen along `ray` with the settings' rays, and gives its
  // weight in the pixel (throughput * albedo / pi), the variance of its irradiance (from its two
  // halves) and its validity radius in pixel footprints. False where there is no diffuse hit.
  struct PilotRecord {
    IrradianceRecord record;
    Vec3 weight, irradiance_variance;
    float footprint_px = 0;
  };
  bool Pilot(const Ray& ray, Rng& rng, RenderCounters& counters, PilotRecord* out) const;

  // Computes a new record at x (facing normal nf, geometric normal ng) and inserts it.
  // `level` 0: a record for what the camera sees (through delta lobes); 1: for what it sees
  // through glossy lobes, or for another record's rays. `ray_fraction`: that share of record_rays
  // (at least kMinRecordRays) is traced.
  IrradianceRecord ComputeRecord(const SurfaceHit& hit, const Vec3& nf, int depth,
                                 float pixel_spread, Rng& rng, RenderCounters& counters,
                                 Vec3* half_difference = nullptr, int level = 0,
                                 float ray_fraction = 1) const;
  // The accuracy a level's lookups weigh records at (IrrcacheSettings::lookup_factor).
  // `factor` < 0: the settings' lookup_factor.
  float LookupAccuracy(int level, float factor = -1) const {
    if (factor < 0) factor = settings_.lookup_factor;
    return level == 0 ? std::min(1.0f, settings_.accuracy * std::max(1.0f, factor))
                      : settings_.accuracy;
  }
  int strata_theta() const { return strata_t_; }
  // DirectTerms slots in use (rectangle lights with the ratio estimator).
  int ratio_slots() const { return ratio_slots_; }
  int strata_phi() const { return strata_p_; }

 private:
  // Fewest rays of a record made with a ray_fraction < 1.
  static constexpr int kMinRecordRays = 96;
  // T x P strata for ray_fraction of record_rays.
  void Strata(float ray_fraction, int* T, int* P) const;
  // The first diffuse vertex along a camera ray (FindDiffuse's results), for the overture, the
  // cache check and the pilot; false also when max_depth leaves no room for its indirect light.
  struct DiffuseVertex {
    Vec3 beta{1, 1, 1};
    SurfaceHit hit;
    Vec3 nf;
    int depth = 0;
    float distance = 0;
  };
  bool FirstDiffuse(const Ray& ray, Rng& rng, RenderCounters& counters, DiffuseVertex* v) const;
  // Follows `ray` through non-diffuse lobes (one sample each) to the first hit with a diffuse
  // lobe. Returns false when the path ends before that.
  bool FindDiffuse(Ray ray, Rng& rng, RenderCounters& counters, Vec3* beta, SurfaceHit* hit,
                   Vec3* nf, int* depth, float* distance) const;
  // Direct light at a diffuse point: every local light that can reach it (up to
  // kAllLightsMax lights; beyond, lights picked by expected contribution), each sampled by
  // solid angle; `weight` = path throughput * albedo / pi.
  // MIS weights of emission reached by a glossy sample of pdf prev_pdf taken at prev_p (facing
  // normal prev_n) against light sampling there; 1 when prev_pdf is 0 (delta lobe or first ray).
  float EnvironmentMisWeight(float prev_pdf, const Vec3& prev_p, const Vec3& prev_n,
                             const Vec3& dir) const;
  float AreaLightMisWeight(float prev_pdf, const Vec3& prev_p, const Vec3& prev_n,
                           const SurfaceHit& hit, const Vec3& dir) const;
  // The BSDF's own diffuse lobe at a shading point (f cos, times the path throughput), for
  // direct light: plastic's and roughplastic's diffuse lobes are not Lambertian (the coating
  // lets less light in at grazing angles), nor is principled's (Burley's retro-reflection).
  struct DiffuseLobe {
    const Bsdf& bsdf;
    const BsdfContext& ctx;
    const ShadingFrame& frame;
    const Vec3& wo_l;
    const Vec3& beta;
    Vec3 Eval(const Vec3& wi) const {
      return beta * bsdf.Eval(ctx, wo_l, frame.ToLocal(wi), kDiffuseReflection);
    }
  };
  // `one_sample`: one light picked by expected contribution (records' rays) instead of all.
  // With `lobe`, each light sample is weighed by the lobe itself instead of `weight` times the
  // cosine; rectangles' analytic terms stay Lambertian (`weight`) and their ratio's
  // denominator with them, so that the ratio carries the lobe's shape over the light.
  Vec3 DirectLight(const SurfaceHit& hit, const Vec3& nf, const Vec3& wo, const Vec3& weight,
                   const LightStrata& strata, Rng& rng, RenderCounters& counters,
                   DirectTerms* terms, bool one_sample = false,
                   const DiffuseLobe* lobe = nullptr) const;
  // The environment's light at a diffuse vertex whose cache lookup max_depth forbids (its light
  // may take one more bounce, not two: depth + 1 == max_depth). The records carry it elsewhere;
  // here it comes from one sample of the environment alone, outside the sun where DirectLight
  // samples the sun itself, as the path tracer's next-event estimation has it.
  Vec3 LastBounceEnvironment(const SurfaceHit& hit, const Vec3& nf, const Vec3& wo,
                             const Vec3& weight, const DiffuseLobe* lobe, Rng& rng,
                             RenderCounters& counters) const;
  // nf: the facing normal (cache lookups); nd: the facing mapped normal (direct light).
  Vec3 ShadeDiffuse(const SurfaceHit& hit, const Vec3& nf, const Vec3& nd, const Vec3& wo,
                    const Vec3& beta, const Vec3& albedo, int depth, float distance, int level,
                    float ray_fraction, const LightStrata& strata, Rng& rng,
                    RenderCounters& counters, IrrcacheShade* shade, DirectTerms* terms,
                    Vec3* cached, const DiffuseLobe* lobe = nullptr) const;
  // Light through the non-diffuse lobes at a path vertex, weighted by beta; on a record ray's
  // walk, less beta_caustic's share through the caustic map's lobes of the map's lights (see
  // PathSettings::caustics; beta_caustic 0 elsewhere).
  Vec3 GlossyDirect(const Bsdf& bsdf, const BsdfContext& ctx, const ShadingFrame& frame,
                    const SurfaceHit& hit, const Vec3& wo, const Vec3& wo_l, const Vec3& beta,
                    const Vec3& beta_caustic, uint32_t caustic_lobes, Rng& rng,
                    RenderCounters& counters) const;
  Vec3 Irradiance(const SurfaceHit& hit, const Vec3& nf, int depth, float distance, bool relax,
                  Rng& rng, RenderCounters& counters, bool* made, int level = 0,
                  float ray_fraction = 1, PixelReuse* reuse = nullptr) const;
  // Radiance arriving at a record along one of its rays (first hit: path vertex `depth`; light
  // from local emitters at that hit excluded, it is the record point's explicit direct light),
  // with the diffuse lobes it reaches shaded from the cache at `level` (cache_levels > 1).
  // `footprint`: the record point's footprint width; `cone`: the ray's angular width (radians),
  // together the footprint new records along the ray are spaced for. *first_environment: as
  // TracePath's.
  Vec3 CachedRayRadiance(Ray ray, int depth, int level, float footprint, float cone, Rng& rng,
                         RenderCounters& counters, float* first_distance,
                         Vec3* first_environment) const;

  const Scene& scene_;
  IrradianceCache* cache_;
  IrrcacheSettings settings_;
  int strata_t_ = 1, strata_p_ = 1;      // primary records' strata
  std::vector<int> ratio_slot_;          // per local light: its DirectTerms slot, or -1
  const EnvironmentSun* sun_ = nullptr;  // the scene's sun where direct_sun: see there
  int ratio_slots_ = 0;
};

}  // namespace irfarm
