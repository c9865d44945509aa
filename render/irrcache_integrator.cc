#include "render/irrcache_integrator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include "render/irradiance_hessian.h"
#include "render/record_balance.h"
#include "render/render_stats.h"

namespace irfarm {
namespace {
constexpr int kMaxSpecularChain = 64;  // delta bounces before a camera path is dropped
// Up to this many local lights, every light that can reach a point gets its own samples; with
// more, DirectLight picks lights by their expected contribution (LightSampler::Sample).
constexpr int kAllLightsMax = LightSampler::kAllLightsMax;
// Records with more strata than this keep Ward's split-sphere spacing (the Hessian needs every
// stratum's ray on the stack: 80 KB).
constexpr int kMaxHessianStrata = 4096;
// At most this many nearest hits are kept for a camera record's occluder-plane test (5% of 10k
// rays); with more rays the test asks for this many within twice the nearest distance.
constexpr int kMaxPlaneRays = 512;
// Each stratum's ray, kept for Hessian spacing: direction (times its hit distance, once known),
// first-hit distance and luminance.
struct StrataRays {
  Vec3 dir[kMaxHessianStrata];
  float dist[kMaxHessianStrata], lum[kMaxHessianStrata];
};

}  // namespace

void IrrcacheIntegrator::Strata(float ray_fraction, int* T, int* P) const {
  // Ward & Heckbert: T x P strata with P ~ pi T give square-ish strata on the projected disk.
  const int full = std::max(4, settings_.record_rays);
  const int n = ray_fraction >= 1 ? full
                                  : std::clamp(int(std::lround(full * double(ray_fraction))),
                                               std::min(full, kMinRecordRays), full);
  *T = std::max(1, int(std::lround(std::sqrt(n / kPi))));
  *P = std::max(1, int(std::lround(double(n) / *T)));
}

Vec3 DirectTerms::Resolve() const {
  Vec3 d;
  for (int j = 0; j < kMaxLights; ++j) d += analytic[j] * Ratio(shadowed[j], unshadowed[j]);
  return d;
}

IrrcacheIntegrator::IrrcacheIntegrator(const Scene& scene, IrradianceCache* cache,
                                       const IrrcacheSettings& settings)
    : scene_(scene), cache_(cache), settings_(settings) {
  Strata(1, &strata_t_, &strata_p_);
  const LightSampler& ls = scene.light_sampler();
  int slots = 0;
  for (int i = 0; i < ls.num_local(); ++i) {
    const Light& l = ls.lights()[i];
    const bool rect = l.type == LightType::kArea && l.shape == AreaShape::kRect;
    const bool ratio = rect && settings.analytic_direct && slots < DirectTerms::kMaxLights;
    ratio_slot_.push_back(ratio ? slots++ : -1);
  }
  ratio_slots_ = slots;
  if (settings.direct_sun && !scene.environment_sun().empty()) sun_ = &scene.environment_sun();
}

namespace {
// A glossy vertex's next-event samples of the environment draw it by its radiance (the mixture
// `path` uses), whatever PathSettings::env_importance says for the records' paths: a lobe of
// rough metal or varnish reflects the map's bright patches, which cosine-weighted samples around
// the normal almost never find. layered_shoes (github.com/VElysianP/mitsuba_scenes: a rough
// silver floor under a studio map), defaults, seed 7: relMSE 6.9e-2 -> 3.9e-2 for 8% more CPU;
// envmap rooms 504, 512, 601, 602, living-room and layered_kitchen within -21% and +5% (seeds 7-8).
constexpr bool kGlossyEnvImportance = true;
}  // namespace

float IrrcacheIntegrator::EnvironmentMisWeight(float prev_pdf, const Vec3& prev_p,
                                               const Vec3& prev_n, const Vec3& dir) const {
  // prev_pdf > 0: the previous vertex was glossy, whose next-event samples draw the environment
  // by its radiance (GlossyDirect).
  return prev_pdf == 0 ? 1.0f
                       : PowerHeuristic(prev_pdf, scene_.light_sampler().NeePdfEnvironment(
                                                      settings_.path.all_lights, prev_p, prev_n,
                                                      dir, kGlossyEnvImportance));
}

float IrrcacheIntegrator::AreaLightMisWeight(float prev_pdf, const Vec3& prev_p, const Vec3& prev_n,
                                             const SurfaceHit& hit, const Vec3& dir) const {
  return prev_pdf == 0 ? 1.0f
                       : PowerHeuristic(prev_pdf, scene_.light_sampler().NeePdfArea(
                                                      settings_.path.all_lights, prev_p, prev_n,
                                                      hit.light, hit.p, hit.ns, hit.prim, dir));
}

Vec3 IrrcacheIntegrator::DirectLight(const SurfaceHit& hit, const Vec3& nf, const Vec3& wo,
                                     const Vec3& weight, const LightStrata& strata, Rng& rng,
                                     RenderCounters& counters, DirectTerms* terms, bool one_sample,
                                     const DiffuseLobe* lobe) const {
  const LightSampler& ls = scene_.light_sampler();
  const int nl = ls.num_local();
  const int k = std::max(1, settings_.light_samples);
  const float wo_side = Dot(wo, hit.ng);
  Vec3 L;
  // u2, u3 of light sample j: the pixel's stratified points, else independent.
  auto uv = [&](int j, float* u2, float* u3) {
    if (strata.sampler) {
      strata.sampler->Get(strata.first + j, u2, u3);
    } else {
      *u2 = rng.Next();
      *u3 = rng.Next();
    }
  };
  // Contribution of a light sample before visibility (0 below the shading horizon), and
  // whether a shadow ray finds it unblocked.
  auto visible = [&](const LightSample& s) {
    if (Dot(s.wi, hit.ng) * wo_side <= 0) return false;  // below the geometric surface
    ++counters.shadow_rays;
    return !scene_.ShadowOccluded(hit, s);
  };
  // The environment's sun (IrrcacheSettings::direct_sun): one sample by its luminance.
  if (sun_ != nullptr) {
    LightSample s;
    s.environment = true;
    float pdf;
    sun_->Sample(rng.Next(), rng.Next(), rng.Next(), &s.wi, &pdf);
    const float cos_i = Dot(s.wi, nf);
    if (pdf > 0 && cos_i > 0 && visible(s)) {
      const Vec3 c =
          (lobe ? lobe->Eval(s.wi) : weight * cos_i) * scene_.EvalEnvironment(s.wi) / pdf;
      if (IsFinite(c)) {
        L += c;
      } else {
        ++counters.nonfinite_samples;
      }
    }
  }
  if (nl > kAllLightsMax || one_sample) {
    for (int j = 0; j < k; ++j) {
      const float u1 = rng.Next();
      float u2, u3;
      uv(j, &u2, &u3);
      LightSample s;
      int skipped = 0;
      const bool ok = scene_.SampleLight(hit.p, nf, u1, u2, u3, false, &s, &skipped);
      counters.lights_skipped += uint64_t(skipped);
      if (!ok) continue;
      const float cos_i = Dot(s.wi, nf);
      if (cos_i > 0 && visible(s))
        L += (lobe ? lobe->Eval(s.wi) : weight * cos_i) * scene_.LightValue(s) / float(k);
    }
    return L;
  }
  for (int i = 0; i < nl; ++i) {
    const int slot = ratio_slot_[i];
    // The analytic irradiance doubles as the reachability test of rectangles.
    const Vec3 analytic = slot >= 0 ? ls.AnalyticIrradiance(i, hit.p, nf) : Vec3();
    if (slot >= 0 ? IsBlack(analytic) : ls.Weight(i, hit.p, nf) <= 0) {
      ++counters.lights_skipped;  // cannot reach: no sample, no shadow ray
      continue;
    }
    const bool delta = ls.lights()[i].IsDelta();
    const int n = delta ? 1 : k;  // a delta light's one sample is exact
    Vec3 shadowed, unshadowed;
    for (int j = 0; j < n; ++j) {
      float u2, u3;
      uv(j, &u2, &u3);
      LightSample s;
      if (!ls.SampleOne(i, hit.p, nf, u2, u3, &s)) continue;
      const float cos_i = Dot(s.wi, nf);
      if (cos_i <= 0) continue;
      const Vec3 c = weight * s.value * (cos_i / float(n));
      // The lobe's own value; the unshadowed sum stays Lambertian where it divides the
      // analytic term (same samples: the ratio is the lobe's visible share of that term).
      const Vec3 e = lobe ? lobe->Eval(s.wi) * s.value / float(n) : c;
      if (!IsFinite(c) || !IsFinite(e)) {
        ++counters.nonfinite_samples;
        continue;
      }
      unshadowed += slot >= 0 ? c : e;
      if (visible(s)) shadowed += e;
    }
    if (slot < 0) {
      L += shadowed;
      continue;
    }
    if (terms) {
      terms->analytic[slot] += weight * analytic;
      terms->shadowed[slot] += shadowed;
      terms->unshadowed[slot] += unshadowed;
    } else {
      // Without the pixel's sums (a vertex past a glossy bounce, a record's rays) the plain
      // estimate: one sample's ratio S / U times the analytic term is not consistent (it is the
      // lamp's visible share by solid angle, not by cosine: a surface seen in a rough mirror,
      // lit by a lamp whose zenith part a shelf hides, came out 0.6% bright), and costs the
      // same (A/B on four rooms: efficiency 0.98-1.02).
      L += shadowed;
    }
  }
  return L;
}

bool IrrcacheIntegrator::FindDiffuse(Ray ray, Rng& rng, RenderCounters& counters, Vec3* beta,
                                     SurfaceHit* hit, Vec3* nf, int* depth, float* distance) const {
  const int max_depth = settings_.path.max_depth;
  *distance = 0;
  for (*depth = 1; *depth <= kMaxSpecularChain; ++*depth) {
    if (!scene_.Intersect(ray, hit)) return false;
    *distance += hit->t;
    const Vec3 wo = -ray.dir;
    if (max_depth >= 0 && *depth >= max_depth) return false;
    const Bsdf& bsdf = scene_.material(hit->material);
    const BsdfContext ctx = hit->Context();
    const ShadingFrame frame = hit->Frame();
    const Vec3 wo_l = frame.ToLocal(wo);
    if (!IsBlack(bsdf.DiffuseAlbedo(ctx, wo_l))) {
      *nf = wo_l.z >= 0 ? hit->ns : -hit->ns;
      return true;
    }
    const BsdfSample bs =
        bsdf.Sample(ctx, wo_l, rng.Next(), rng.Next(), rng.Next(), kNonDiffuseLobes);
    if (IsBlack(bs.weight)) return false;
    const Vec3 wi = frame.ToWorld(bs.wi);
    if (!SidesAgree(wo, wi, hit->ng, wo_l.z, bs.wi.z)) return false;
    *beta *= bs.weight;
    ray = Scene::SpawnRay(hit->p, hit->ng, hit->error_scale, wi);
    ++counters.bounce_rays;
  }
  return false;
}

IrradianceRecord IrrcacheIntegrator::ComputeRecord(const SurfaceHit& hit, const Vec3& nf, int depth,
                                                   float pixel_spread, Rng& rng,
                                                   RenderCounters& counters, Vec3* half_difference,
                                                   int level, float ray_fraction) const {
  // Thread CPU time (see PilotSettings' figures, which use it); nested records are inside it.
  const double start = counters.record_nesting == 0 ? ThreadCpuSeconds() : 0.0;
  const uint64_t work_start = counters.Work();
  ++counters.record_nesting;
  Vec3 s, t;
  MakeFrame(nf, &s, &t);
  // The geometric normal on the side of the facing normal: rays below it would pass through.
  const Vec3 ng_side = Dot(hit.ng, nf) >= 0 ? hit.ng : -hit.ng;
  double inv_dist_sum = 0;
  float nearest = INFINITY;  // the nearest ray hit (occluder clamp)
  Vec3 nearest_dir;
  int T = strata_t_, P = strata_p_;
  if (ray_fraction < 1) Strata(ray_fraction, &T, &P);
  const bool cached_rays = level + 1 < settings_.cache_levels;
  // Footprint of one of this record's rays: its share of the hemisphere, sqrt(2 pi / n) radians
  // wide, plus the record's own footprint; secondary records are spaced for that (ray cones),
  // not for a camera pixel: each ray averages over its footprint anyway.
  const float ray_cone = std::sqrt(2 * kPi / float(std::max(1, T * P)));
  // Russian roulette from the first bounce of each record ray (not from rr_depth): a record
  // averages over many rays, so shorter paths with more rays win. Measured at equal CPU time on
  // cornell-box and sunlit-room: 1536 rays with early roulette beat 1024 without it.
  PathSettings record_path = settings_.path;
  record_path.rr_depth = std::min(record_path.rr_depth, depth + 1);
  record_path.caustics = settings_.caustics;
  record_path.direct_sun = sun_;
  // Hessian spacing keeps each stratum's ray; split-sphere records do not fill (or zero) it.
  std::optional<StrataRays> grid;
  if (settings_.spacing == RecordSpacing::kHessian && T * P <= kMaxHessianStrata) grid.emplace();
  bool grid_complete = grid.has_value();
  // The k nearest hit distances (a max-heap, on the stack): at the end, whether k rays hit within
  // twice the nearest one's distance decides the camera record's occluder plane.
  const bool plane_test =
      settings_.occluder_plane && level == 0 && settings_.occluder_plane_fraction > 0;
  std::array<float, kMaxPlaneRays> near_heap;
  const int near_k =
      plane_test ? std::clamp(int(std::ceil(settings_.occluder_plane_fraction * float(T * P))), 1,
                              kMaxPlaneRays)
                 : 0;
  int near_count = 0;
  Vec3 sum, half_sum[2];
  // The environment map's next-event samples (IrrcacheSettings::environment_samples): m of them
  // beside the n strata; a stratum's first-segment environment light then counts with the balance
  // heuristic's weight n p_cos / (n p_cos + m p_env).
  // How many: the share asked, times the fraction of kEnvironmentProbes samples of the map that
  // find it unblocked from here (probes of their own, not used in the estimate: m must not
  // depend on the samples it weighs). Deep in a room lit through a window most of them hit a wall,
  // and there the strata alone do better (rooms 512 and 513: 6% and 11% higher relMSE over five
  // seeds with a fixed share, against 30-45% lower on an open still life).
  const LightSampler& lights = scene_.light_sampler();
  const float n_strata = float(T * P);
  // One sample of the map by its radiance from x, and whether it arrives: above both horizons
  // and unblocked (a shadow ray).
  const auto sample_map = [&](LightSample* ls) {
    const float u2 = rng.Next(), u3 = rng.Next();
    if (!lights.SampleEnvironment(hit.p, nf, u2, u3, ls, true)) return false;
    if (!(Dot(ls->wi, nf) > 0) || Dot(ls->wi, ng_side) <= 0) return false;
    if (sun_ != nullptr && sun_->Contains(ls->wi)) return false;  // DirectLight's (direct_sun)
    ++counters.shadow_rays;
    return !scene_.ShadowOccluded(hit, *ls);
  };
  int m_env = 0;
  if (lights.has_environment_map() && settings_.environment_samples > 0) {
    int seen = 0;
    for (int k = 0; k < IrrcacheSettings::kEnvironmentProbes; ++k) {
      LightSample ls;
      seen += sample_map(&ls);
    }
    m_env = int(std::lround(settings_.environment_samples * n_strata * float(seen) /
                            float(IrrcacheSettings::kEnvironmentProbes)));
  }
  float brightest = 0;  // the largest luminance one stratum's ray brought
  for (int i = 0; i < T; ++i)
    for (int j = 0; j < P; ++j) {
      const float u = rng.Next();
      const float v = rng.Next();  // drawn in order: argument evaluation order is unspecified
      const Vec3 local = StratifiedCosineHemisphere(i, j, T, P, u, v);
      const Vec3 dir = s * local.x + t * local.y + nf * local.z;
      if (Dot(dir, ng_side) <= 0) {  // below the geometric surface: blocked, no light
        grid_complete = false;
        continue;
      }
      const Ray ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale, dir);
      ++counters.record_rays;
      float d = INFINITY;
      Vec3 env_first;
      Vec3 L = cached_rays ? CachedRayRadiance(ray, depth + 1, level + 1, pixel_spread, ray_cone,
                                               rng, counters, &d, &env_first)
                           : TracePath(scene_, ray, depth + 1, true, record_path, rng, counters, &d,
                                       nullptr, &env_first);
      // The stratum's own radiance, unweighted, for the record's derivatives (the grid below).
      const float radiance = IsFinite(L) ? Luminance(L) : 0.0f;
      if (m_env > 0 && !IsBlack(env_first)) {
        const float p_cos = local.z * kInvPi;
        const float p_env = lights.PdfEnvironmentAlone(hit.p, nf, dir, true);
        L += env_first * (n_strata * p_cos / (n_strata * p_cos + float(m_env) * p_env) - 1.0f);
      }
      if (IsFinite(L)) {
        sum += L;
        half_sum[(i + j) & 1] += L;  // a checkerboard of strata: two interleaved halves
        brightest = std::max(brightest, Luminance(L));
      } else {
        ++counters.nonfinite_samples;
      }
      if (d > 0 && std::isfinite(d)) {
        inv_dist_sum += 1.0 / d;
        if (d < nearest) {
          nearest = d;
          nearest_dir = dir;
        }
        if (near_count < near_k) {
          near_heap[size_t(near_count++)] = d;
          std::push_heap(near_heap.begin(), near_heap.begin() + near_count);
        } else if (near_k > 0 && d < near_heap[0]) {
          std::pop_heap(near_heap.begin(), near_heap.begin() + near_count);
          near_heap[size_t(near_count - 1)] = d;
          std::push_heap(near_heap.begin(), near_heap.begin() + near_count);
        }
      }
      if (grid) {
        grid->dir[i * P + j] = dir;
        grid->dist[i * P + j] = d;
        grid->lum[i * P + j] = radiance;
      }
    }
  // The environment map's samples, in the strata's units (E = sum pi / n): L cos / (n p_cos +
  // m p_env) n / pi each; alternately into the two halves.
  for (int k = 0; k < m_env; ++k) {
    LightSample ls;
    if (!sample_map(&ls)) continue;
    const float cos_i = Dot(ls.wi, nf);
    const Vec3 v = scene_.EvalEnvironment(ls.wi) *
                   (n_strata * cos_i / (n_strata * cos_i + kPi * float(m_env) * ls.pdf));
    if (!IsFinite(v)) {
      ++counters.nonfinite_samples;
      continue;
    }
    sum += v;
    half_sum[k & 1] += v;
  }
  const int n = T * P;
  IrradianceRecord r;
  r.position = hit.p;
  r.normal = nf;
  r.level = uint8_t(level);
  r.irradiance = sum * (kPi / float(n));
  if (half_difference) {
    const int n0 = (n + 1) / 2, n1 = n / 2;
    *half_difference =
        half_sum[0] * (kPi / float(std::max(1, n0))) - half_sum[1] * (kPi / float(std::max(1, n1)));
  }
  const float a = settings_.accuracy;
  // Harmonic mean distance, then clamps on the validity radius a*R in pixel footprints at x.
  float spacing = inv_dist_sum > 0 ? float(n / inv_dist_sum) : INFINITY;  // harmonic mean
  if (grid_complete) {
    // The distance where the record's own derivatives predict a relative error of a: there
    // eps = |x - x_i| / R_i reaches a (irradiance_hessian.h). Rays that left the scene end far
    // beyond the farthest hit (what lies there moves with x no more than the sky does).
    float far = 0;
    for (int k = 0; k < n; ++k)
      if (std::isfinite(grid->dist[k])) far = std::max(far, grid->dist[k]);
    far = far > 0 ? 100 * far : 1.0f;
    for (int k = 0; k < n; ++k)
      grid->dir[k] = grid->dir[k] * (std::isfinite(grid->dist[k]) ? grid->dist[k] : far);
    IrradianceDerivatives der;
    if (EstimateIrradianceDerivatives(T, P, grid->dir, grid->lum, Luminance(sum) / float(n), nf, s,
                                      t, &der)) {
      spacing = ErrorRadius(der, a) / a;
      ++counters.records_hessian;
    }
  }
  const float r_min = settings_.min_spacing_px * pixel_spread / a;
  const float r_max = settings_.max_spacing_px * pixel_spread / a;
  r.radius = std::clamp(spacing, r_min, r_max);
  if (level > 0 && settings_.occluder_reach > 0 && std::isfinite(nearest)) {
    const float a_max = a * std::max(1.0f, settings_.relaxed_factor);
    const float reach =
        std::max(settings_.occluder_reach * nearest, settings_.occluder_floor_px * pixel_spread);
    r.radius = std::min(r.radius, reach / a_max);
  }
  // Where a floor keeps the validity radius past the nearest hit (a record next to a partition;
  // a camera record by a lamp hung just below the ceiling, whose 1.5-pixel floor reached into
  // the dark gap above the lamp), the occluder plane keeps the record from the other side.
  // A camera record's plane only where something large is that close (occluder_plane_fraction):
  // k rays within twice the nearest distance.
  const bool large_occluder = !plane_test || (near_count == near_k && near_heap[0] < 2 * nearest);
  if (settings_.occluder_plane && std::isfinite(nearest) && large_occluder)
    r.occluder = nearest_dir * nearest;
  if (!(r.radius > 0) || !std::isfinite(r.radius)) {
    // Degenerate footprint (should not happen): fall back to a small multiple of the offset scale.
    r.radius = std::max(1e-4f * std::max(hit.error_scale, MaxAbsComponent(hit.p)), 1e-30f);
  }
  ++counters.records_computed;
  if (level > 0) {
    ++counters.records_secondary;
    if (brightest > kHeavyRayShare * Luminance(sum)) ++counters.records_secondary_heavy;
  }
  // A record made for another record's rays is part of that record's time.
  if (--counters.record_nesting == 0) {
    counters.record_seconds += ThreadCpuSeconds() - start;
    counters.record_work += counters.Work() - work_start;
  }
  return r;
}

bool IrrcacheIntegrator::CachedIrradiance(const Vec3& p, const Vec3& nf, int level,
                                          float region_radius, float region_angle,
                                          LookupRegion* region, Vec3* E, LookupInfo* info,
                                          float factor) const {
  // Camera lookups weigh records out to eps_i < a * lookup_factor; a record is made where none
  // counts at a (LookupInfo::counts_at_narrow).
  const float a = settings_.accuracy, a_lookup = LookupAccuracy(level, factor);
  const bool wider = a_lookup > a;
  const bool found = region != nullptr
                         ? cache_->LookupNear(p, nf, a_lookup, region_radius, region_angle, region,
                                              E, info, level, wider ? a : 0)
                         : cache_->Lookup(p, nf, a_lookup, E, info, level, wider ? a : 0);
  if (!wider) return found;
  if (!found || !info->counts_at_narrow) return false;
  // Where the wider answer departs from the records at a by more than lookup_agreement, the
  // difference is structure (a lamp's edge, a panel's foot), not the records' noise: the records
  // at a answer alone.
  const float narrow = Luminance(info->narrow_irradiance);
  if (std::abs(Luminance(*E) - narrow) > settings_.lookup_agreement * narrow)
    *E = info->narrow_irradiance;
  return true;
}

Vec3 IrrcacheIntegrator::Irradiance(const SurfaceHit& hit, const Vec3& nf, int depth,
                                    float distance, bool relax, Rng& rng, RenderCounters& counters,
                                    bool* made, int level, float ray_fraction,
                                    PixelReuse* reuse) const {
  Vec3 E;
  LookupInfo info;
  ++counters.lookups;
  const float a = settings_.accuracy;
  // A pixel's samples land within about a pixel of each other: the region reaches kRegionPixels
  // pixel footprints (grazing surfaces and edges just gather anew) and kRegionAngle of normal
  // (curved surfaces).
  constexpr float kRegionPixels = 2.0f, kRegionAngle = 0.1f;
  const bool found =
      CachedIrradiance(hit.p, nf, level, kRegionPixels * scene_.camera().PixelSpread(distance),
                       kRegionAngle, reuse != nullptr ? &reuse->region : nullptr, &E, &info);
  counters.region_lookups += uint64_t(info.from_region);
  // The records leave caustics out (their rays skip them); the photon map's estimate takes their
  // place at every level.
  const Vec3 caustic =
      settings_.caustics != nullptr
          ? settings_.caustics->Irradiance(hit.p, nf, reuse != nullptr ? &reuse->caustic : nullptr)
          : Vec3();
  if (found || (relax && cache_->Lookup(hit.p, nf, std::min(1.0f, a * settings_.relaxed_factor), &E,
                                        &info, level))) {
    ++counters.lookup_hits;
    counters.records_used += uint64_t(info.records_used);
    counters.remote_records_used += uint64_t(info.remote_records_used);
    return E + caustic;
  }
  const IrradianceRecord r = ComputeRecord(hit, nf, depth, scene_.camera().PixelSpread(distance),
                                           rng, counters, nullptr, level, ray_fraction);
  cache_->Insert(r);
  *made = true;
  return r.irradiance + caustic;
}

Vec3 IrrcacheIntegrator::CachedRayRadiance(Ray ray, int depth, int level, float footprint,
                                           float cone, Rng& rng, RenderCounters& counters,
                                           float* first_distance, Vec3* first_environment) const {
  // Li's walk (delta and glossy lobes path traced with MIS, diffuse lobes from the cache), with
  // one light sample per diffuse vertex and Russian roulette from the first bounce on, as the
  // path-traced record rays have it.
  Vec3 L, beta(1, 1, 1);
  const int max_depth = settings_.path.max_depth;
  float prev_pdf = 0;
  Vec3 prev_p, prev_n;
  *first_distance = INFINITY;
  *first_environment = Vec3();
  // The part of beta that scattered through the caustic map's lobes only (PathSettings::caustics):
  // the light of the map's lights it finds is a caustic at the record point, the map's.
  const uint32_t caustic_lobes = settings_.caustics != nullptr ? settings_.caustics->lobes() : 0u;
  Vec3 beta_caustic = caustic_lobes != 0 ? Vec3(1, 1, 1) : Vec3();
  bool first = true;       // still on the first segment (masks passed through)
  float first_length = 0;  // its length so far, across the masks and panes it passed
  for (int i = 0; i < kMaxSpecularChain; ++i, ++depth) {
    SurfaceHit hit;
    if (!scene_.Intersect(ray, &hit)) {
      if (first) *first_distance = INFINITY;  // out through whatever it passed straight through
      if (scene_.has_environment()) {
        const float w = EnvironmentMisWeight(prev_pdf, prev_p, prev_n, ray.dir);
        // Past non-diffuse bounces, the environment's sun is a caustic: the map's, if it has it.
        // On the first segment the environment's sun is the record point's direct light
        // (direct_sun: DirectLight's, wherever the record is looked up).
        if (first && sun_ != nullptr && sun_->Contains(ray.dir)) break;
        const Vec3 throughput =
            !first && caustic_lobes != 0 && settings_.caustics->CoversEnvironment(ray.dir)
                ? beta - beta_caustic
                : beta;
        const Vec3 c = throughput * scene_.EvalEnvironment(ray.dir) * w;
        L += c;
        if (first) *first_environment = c;
      }
      break;
    }
    if (first) *first_distance = first_length += hit.t;
    footprint += hit.t * cone;
    const Vec3 wo = -ray.dir;
    // At the first hit (straight through masks and panes as well): the record point's direct
    // light; past non-diffuse bounces only: a caustic, the photon map's when there is one.
    if (hit.light >= 0 && !first) {
      const Vec3 le = scene_.Emitted(hit, wo);
      const Vec3 throughput =
          caustic_lobes != 0 && CausticMap::Covers(scene_, hit.light) ? beta - beta_caustic : beta;
      if (!IsBlack(le)) {
        const float w = AreaLightMisWeight(prev_pdf, prev_p, prev_n, hit, ray.dir);
        L += throughput * le * w;
      }
    }
    if (max_depth >= 0 && depth >= max_depth) break;
    const Bsdf& bsdf = scene_.material(hit.material);
    const BsdfContext ctx = hit.Context();
    const ShadingFrame frame = hit.Frame();
    const Vec3 wo_l = frame.ToLocal(wo);
    const Vec3 albedo = bsdf.DiffuseAlbedo(ctx, wo_l);
    if (!IsBlack(albedo)) {
      const Vec3 nf = wo_l.z >= 0 ? hit.ns : -hit.ns;
      const Vec3 w = beta * albedo * kInvPi;
      if (max_depth < 0 || depth + 1 <= max_depth) {
        const DiffuseLobe lobe{bsdf, ctx, frame, wo_l, beta};
        L += DirectLight(hit, nf, wo, w, LightStrata{}, rng, counters, nullptr, true, &lobe);
      }
      if (max_depth < 0 || depth + 2 <= max_depth) {
        bool made = false;
        // As the camera distance at which a pixel is that wide (Irradiance's unit).
        const float distance = footprint / scene_.camera().PixelSpread(1.0f);
        L += w * Irradiance(hit, nf, depth, distance, true, rng, counters, &made, level,
                            settings_.secondary_ray_fraction);
      } else if (depth + 1 == max_depth) {
        const DiffuseLobe lobe{bsdf, ctx, frame, wo_l, beta};
        L += LastBounceEnvironment(hit, nf, wo, w, &lobe, rng, counters);
      }
    }
    if (!bsdf.HasNonDiffuse()) break;
    if (max_depth >= 0 && depth + 1 > max_depth) break;
    if ((bsdf.Flags() & kSmoothNonDiffuseLobes) != 0)
      L += GlossyDirect(bsdf, ctx, frame, hit, wo, wo_l, beta, beta_caustic, caustic_lobes, rng,
                        counters);
    const float u1 = rng.Next(), u2 = rng.Next(), u3 = rng.Next();
    const BsdfSample bs = bsdf.Sample(ctx, wo_l, u1, u2, u3, kNonDiffuseLobes);
    if (IsBlack(bs.weight)) break;
    const Vec3 wi = frame.ToWorld(bs.wi);
    if (!SidesAgree(wo, wi, hit.ng, wo_l.z, bs.wi.z)) break;
    if (!IsBlack(beta_caustic))
      beta_caustic *= bs.IsDelta() ? bs.weight
                      : bs.pdf > 0 ? bsdf.Eval(ctx, wo_l, bs.wi, caustic_lobes) / bs.pdf
                                   : Vec3();
    beta *= bs.weight;
    if (IsBlack(beta)) break;
    ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale, wi);
    ++counters.bounce_rays;
    if (bs.lobe == kNullTransmission) continue;  // through a mask: MIS state unchanged
    first = false;
    const float q = std::min(MaxComponent(beta), 0.95f);
    if (rng.Next() >= q) break;
    beta /= q;
    beta_caustic /= q;
    if (!bs.IsDelta() && bs.pdf > 0)  // a glossy lobe widens the cone by about its width
      cone = std::min(kPi / 2, cone + 1.0f / std::sqrt(kPi * bs.pdf));
    prev_pdf = bs.IsDelta() ? 0.0f : bs.pdf;
    prev_p = hit.p;
    prev_n = LightSelectionNormal(bsdf.Flags(), wo_l.z >= 0 ? hit.ns : -hit.ns);
  }
  return L;
}

Vec3 IrrcacheIntegrator::Li(const Ray& camera_ray, const LightStrata& strata, Rng& rng,
                            RenderCounters& counters, IrrcacheShade* shade, DirectTerms* terms,
                            SampleAov* aov) const {
  // The camera path: through delta and glossy lobes (path traced, light sampled with MIS at
  // glossy vertices), and at every vertex with a diffuse lobe that lobe is shaded from the
  // cache (ShadeDiffuse). A scene without glossy or delta materials makes one vertex per path.
  // The pixel's direct-light terms (`terms`, the per-pixel shadow ratio) collect only the first
  // diffuse vertex reached through delta lobes; later ones resolve their ratio per sample.
  Vec3 L, beta(1, 1, 1);
  const int max_depth = settings_.path.max_depth;
  float prev_pdf = 0;        // pdf of the glossy sample that made `ray`; 0 = delta lobe or camera
  Vec3 prev_p, prev_n;       // the previous vertex and its facing normal (light selection)
  bool prev_glossy = false;  // a diffuse or glossy vertex lies before this one
  // AOVs: the first vertex with a diffuse lobe (-1: not reached); what comes before it and its
  // direct light (and light its glossy sample hits) is direct, its cached term and everything
  // after is indirect.
  int first_diffuse = -1;
  // The albedo AOV is set at the first vertex with a diffuse or a glossy lobe (`albedo_set`):
  // the diffuse albedo plus, where glossy lobes are, their directional albedo as this vertex's
  // glossy sample estimates it (its weight; the pixel's mean is the albedo), both times the
  // delta lobes' throughput before it. A rough metal or a plastic's coat then guides the denoiser
  // with its own reflectance, instead of with what it reflects (metal) or its base alone.
  bool albedo_set = false;
  if (aov) *aov = SampleAov{};
  if (max_depth == 0) return L;  // as Mitsuba's path: nothing, not even emitters seen
  const auto add = [&](const Vec3& c, int d, bool cached) {
    L += c;
    if (!aov) return;
    if (first_diffuse < 0) aov->emission += c;
    const bool direct = !cached && (first_diffuse < 0 || d <= first_diffuse + 1);
    (direct ? aov->direct : aov->indirect) += c;
  };
  float distance = 0;  // along the camera path (the depth AOV, record spacing)
  // Past a glossy bounce the path stands for a cone about as wide as the lobe (1/sqrt(pi pdf)
  // radians for the sampled direction's pdf; ray cones, cf. Igehy 1999): diffuse vertices there
  // look the cache up at level 1 and make level-1 records spaced for that footprint (as the
  // camera distance at which a pixel is that wide), which camera-visible surfaces never use.
  float footprint_distance = 0;
  float cone_extra = 0;  // radians added by glossy lobes
  const float pixel_angle = scene_.camera().PixelSpread(1.0f);
  Ray ray = camera_ray;
  for (int depth = 1; depth <= kMaxSpecularChain; ++depth) {
    SurfaceHit hit;
    if (!scene_.Intersect(ray, &hit)) {
      if (scene_.has_environment()) {
        const float w = EnvironmentMisWeight(prev_pdf, prev_p, prev_n, ray.dir);
        add(beta * scene_.EvalEnvironment(ray.dir) * w, depth, false);
      }
      break;
    }
    distance += hit.t;
    footprint_distance += hit.t * (1.0f + cone_extra / pixel_angle);
    const Vec3 wo = -ray.dir;
    if (hit.light >= 0) {
      const Vec3 le = scene_.Emitted(hit, wo);
      if (!IsBlack(le)) {
        const float w = AreaLightMisWeight(prev_pdf, prev_p, prev_n, hit, ray.dir);
        add(beta * le * w, depth, false);
      }
    }
    if (max_depth >= 0 && depth >= max_depth) break;
    const Bsdf& bsdf = scene_.material(hit.material);
    const BsdfContext ctx = hit.Context();
    const ShadingFrame frame = hit.Frame();
    const Vec3 wo_l = frame.ToLocal(wo);
    const Vec3 albedo = bsdf.DiffuseAlbedo(ctx, wo_l);
    const bool glossy = (bsdf.Flags() & kSmoothNonDiffuseLobes) != 0;
    const bool albedo_here = aov && !albedo_set && (glossy || !IsBlack(albedo));
    if (albedo_here) {
      albedo_set = true;
      aov->albedo = beta * albedo;  // the glossy part is added with the glossy sample below
      aov->normal = wo_l.z >= 0 ? hit.ns : -hit.ns;
      aov->depth = distance;
    }
    if (!IsBlack(albedo)) {
      const Vec3 nf = wo_l.z >= 0 ? hit.ns : -hit.ns;
      if (aov && first_diffuse < 0) first_diffuse = depth;
      Vec3 cached;
      // Direct light about the mapped normal (normalmap/bumpmap), on the side wo is on; the cache
      // keeps the surface's own normal (records are smooth over the surface).
      const Vec3 np_l = bsdf.ShadingNormal(ctx, wo_l);
      const Vec3 np_w = frame.ToWorld(np_l);
      const Vec3 nd = np_l.z * wo_l.z >= 0 ? np_w : -np_w;
      // Past a glossy bounce the cached term reaches the pixel weighted by the path throughput:
      // its record gets that share of the rays (RADIANCE likewise lowers ambient divisions with
      // the ray weight), at level 1 where no camera-visible surface looks.
      const bool glossy_chain = cone_extra > 0;
      const float ray_fraction = glossy_chain ? std::min(1.0f, Luminance(beta)) : 1.0f;
      const DiffuseLobe lobe{bsdf, ctx, frame, wo_l, beta};
      const Vec3 shaded = ShadeDiffuse(hit, nf, nd, wo, beta, albedo, depth, footprint_distance,
                                       glossy_chain ? 1 : 0, ray_fraction, strata, rng, counters,
                                       shade, prev_glossy ? nullptr : terms, &cached, &lobe);
      add(shaded - cached, depth, false);
      add(cached, depth, true);
      prev_glossy = true;  // later diffuse vertices do not share the pixel's ratio terms
    }
    if (!bsdf.HasNonDiffuse()) break;
    if (max_depth >= 0 && depth + 1 > max_depth) break;
    if (glossy) {
      prev_glossy = true;
      ++counters.glossy_bounces;
      add(GlossyDirect(bsdf, ctx, frame, hit, wo, wo_l, beta, Vec3(), 0, rng, counters), depth,
          false);
    }
    const float u1 = rng.Next(), u2 = rng.Next(), u3 = rng.Next();
    const BsdfSample bs = bsdf.Sample(ctx, wo_l, u1, u2, u3, kNonDiffuseLobes);
    if (albedo_here && !bs.IsDelta() && IsFinite(bs.weight)) aov->albedo += beta * bs.weight;
    if (IsBlack(bs.weight)) break;
    const Vec3 wi = frame.ToWorld(bs.wi);
    if (!SidesAgree(wo, wi, hit.ng, wo_l.z, bs.wi.z)) break;
    beta *= bs.weight;
    if (IsBlack(beta)) break;
    if (bs.lobe == kNullTransmission) {  // passed through a mask: MIS state unchanged
      ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale, wi);
      continue;
    }
    if (depth >= settings_.path.rr_depth) {
      const float q = std::min(MaxComponent(beta), 0.95f);
      if (rng.Next() >= q) break;
      beta /= q;
    }
    if (!bs.IsDelta() && bs.pdf > 0)
      cone_extra = std::min(kPi / 2, cone_extra + 1.0f / std::sqrt(kPi * bs.pdf));
    prev_pdf = bs.IsDelta() ? 0.0f : bs.pdf;
    prev_p = hit.p;
    prev_n = LightSelectionNormal(bsdf.Flags(), wo_l.z >= 0 ? hit.ns : -hit.ns);
    ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale, wi);
    ++counters.bounce_rays;
  }
  return L;
}

// Direct light through the non-diffuse (glossy) lobes at a camera-path vertex: next-event
// estimation as the path tracer does it (every light, or one picked: PathSettings::all_lights;
// the environment included: the cache serves only the diffuse lobe), MIS-weighted against the
// glossy sample that continues the path.
Vec3 IrrcacheIntegrator::GlossyDirect(const Bsdf& bsdf, const BsdfContext& ctx,
                                      const ShadingFrame& frame, const SurfaceHit& hit,
                                      const Vec3& wo, const Vec3& wo_l, const Vec3& beta,
                                      const Vec3& beta_caustic, uint32_t caustic_lobes, Rng& rng,
                                      RenderCounters& counters) const {
  // As prev_n in Li and CachedRayRadiance (light selection).
  const Vec3 n_select = LightSelectionNormal(bsdf.Flags(), wo_l.z >= 0 ? hit.ns : -hit.ns);
  Vec3 L;
  scene_.light_sampler().SampleForNee(
      settings_.path.all_lights, kGlossyEnvImportance, hit.p, n_select, rng,
      &counters.lights_skipped, [&](const LightSample& ls) {
        const Vec3 wi_l = frame.ToLocal(ls.wi);
        if (!SidesAgree(wo, ls.wi, hit.ng, wo_l.z, wi_l.z)) return;
        const Vec3 f = bsdf.Eval(ctx, wo_l, wi_l, kNonDiffuseLobes);
        if (IsBlack(f)) return;
        Vec3 c = beta * f;
        if (!IsBlack(beta_caustic) && (ls.environment ? settings_.caustics->CoversEnvironment(ls.wi)
                                                      : CausticMap::Covers(scene_, ls.light))) {
          c -= beta_caustic * bsdf.Eval(ctx, wo_l, wi_l, caustic_lobes);
          if (IsBlack(c)) return;
        }
        ++counters.shadow_rays;
        if (scene_.ShadowOccluded(hit, ls)) return;
        const float w = ls.pdf == 0
                            ? 1.0f
                            : PowerHeuristic(ls.pdf, bsdf.Pdf(ctx, wo_l, wi_l, kNonDiffuseLobes));
        L += c * scene_.LightValue(ls) * w;
      });
  return L;
}

// The diffuse lobe at x, weighted by the path throughput beta: direct light from local lights
// (DirectLight, Lambertian with the lobe's albedo; for plastic that takes the Fresnel
// transmission towards the light as its hemispherical average, see plastic.cc), plus the cached
// indirect irradiance times albedo / pi.
Vec3 IrrcacheIntegrator::ShadeDiffuse(const SurfaceHit& hit, const Vec3& nf, const Vec3& nd,
                                      const Vec3& wo, const Vec3& beta, const Vec3& albedo,
                                      int depth, float distance, int level, float ray_fraction,
                                      const LightStrata& strata, Rng& rng, RenderCounters& counters,
                                      IrrcacheShade* shade, DirectTerms* terms, Vec3* cached,
                                      const DiffuseLobe* lobe) const {
  Vec3 L;
  *cached = Vec3();
  const int max_depth = settings_.path.max_depth;
  // Direct light from local lights, always explicit.
  if (max_depth < 0 || depth + 1 <= max_depth)
    L +=
        DirectLight(hit, nd, wo, beta * albedo * kInvPi, strata, rng, counters, terms, false, lobe);
  // Indirect irradiance from the cache.
  if (max_depth < 0 || depth + 2 <= max_depth) {
    bool made = false;
    const Vec3 E = Irradiance(hit, nf, depth, distance, true, rng, counters, &made, level,
                              ray_fraction, level == 0 && shade ? shade->reuse : nullptr);
    if (shade) shade->made_record = shade->made_record || made;
    *cached = beta * albedo * E * kInvPi;
    L += *cached;
  } else if (depth + 1 == max_depth) {
    L += LastBounceEnvironment(hit, nd, wo, beta * albedo * kInvPi, lobe, rng, counters);
  }
  return L;
}

Vec3 IrrcacheIntegrator::LastBounceEnvironment(const SurfaceHit& hit, const Vec3& nf,
                                               const Vec3& wo, const Vec3& weight,
                                               const DiffuseLobe* lobe, Rng& rng,
                                               RenderCounters& counters) const {
  if (!scene_.has_environment()) return Vec3();
  LightSample s;
  const float u2 = rng.Next(), u3 = rng.Next();
  if (!scene_.light_sampler().SampleEnvironment(hit.p, nf, u2, u3, &s, true)) return Vec3();
  if (sun_ != nullptr && sun_->Contains(s.wi)) return Vec3();  // DirectLight's
  const float cos_i = Dot(s.wi, nf);
  if (!(cos_i > 0) || Dot(s.wi, hit.ng) * Dot(wo, hit.ng) <= 0) return Vec3();
  ++counters.shadow_rays;
  if (scene_.ShadowOccluded(hit, s)) return Vec3();
  const Vec3 c = (lobe ? lobe->Eval(s.wi) : weight * cos_i) * scene_.LightValue(s);
  if (!IsFinite(c)) {
    ++counters.nonfinite_samples;
    return Vec3();
  }
  return c;
}

bool IrrcacheIntegrator::FirstDiffuse(const Ray& ray, Rng& rng, RenderCounters& counters,
                                      DiffuseVertex* v) const {
  if (!FindDiffuse(ray, rng, counters, &v->beta, &v->hit, &v->nf, &v->depth, &v->distance))
    return false;
  const int max_depth = settings_.path.max_depth;
  return max_depth < 0 || v->depth + 2 <= max_depth;
}

bool IrrcacheIntegrator::CacheError(const Ray& ray, Rng& rng, RenderCounters& counters,
                                    double* error, double* noise, float ray_fraction,
                                    float other_factor, double* other_error,
                                    double* other_noise) const {
  DiffuseVertex dv;
  if (!FirstDiffuse(ray, rng, counters, &dv)) return false;
  Vec3 interp[2];
  LookupInfo info[2];
  if (!CachedIrradiance(dv.hit.p, dv.nf, 0, 0, 0, nullptr, &interp[0], &info[0])) return false;
  // Both rules make a record at the same places (where none counts at a): the other finds too.
  const bool other =
      other_factor > 0 && other_error != nullptr && other_noise != nullptr &&
      CachedIrradiance(dv.hit.p, dv.nf, 0, 0, 0, nullptr, &interp[1], &info[1], other_factor);
  Vec3 half_diff;
  const IrradianceRecord fresh =
      ComputeRecord(dv.hit, dv.nf, dv.depth, scene_.camera().PixelSpread(dv.distance), rng,
                    counters, &half_diff, 0, ray_fraction);
  // The cache's records have the full rays: their variance is the fresh one's times its share.
  int T = strata_t_, P = strata_p_;
  if (ray_fraction < 1) Strata(ray_fraction, &T, &P);
  const double share = double(T * P) / double(strata_t_ * strata_p_);
  const Bsdf& bsdf = scene_.material(dv.hit.material);
  const ShadingFrame frame = dv.hit.Frame();
  const Vec3 w = dv.beta * bsdf.DiffuseAlbedo(dv.hit.Context(), frame.ToLocal(-ray.dir)) * kInvPi;
  const Vec3 direct =
      DirectLight(dv.hit, dv.nf, -ray.dir, w, LightStrata{}, rng, counters, nullptr);
  const Vec3 v = direct + w * interp[0];  // the point's radiance (emission on the way left out)
  double* errors[2] = {error, other_error};
  double* noises[2] = {noise, other_noise};
  for (int k = 0; k < (other ? 2 : 1); ++k) {
    const double kept =
        info[k].weight_sum > 0
            ? double(info[k].weight_sq_sum) / (double(info[k].weight_sum) * info[k].weight_sum)
            : 1.0;
    double e = 0, nz = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = double(w[c]) * (double(interp[k][c]) - double(fresh.irradiance[c]));
      // Var(E_fresh) = E[(E_even - E_odd)^2] / 4 for two independent halves.
      const double var = double(w[c]) * w[c] * double(half_diff[c]) * half_diff[c] / 4;
      const double scale = double(v[c]) * v[c] + 0.01;
      e += (d * d - var) / scale;
      nz += var * share * kept / scale;
    }
    *errors[k] = e / 3;
    *noises[k] = nz / 3;
  }
  if (!other && other_error != nullptr && other_noise != nullptr) {
    *other_error = *error;
    *other_noise = *noise;
  }
  return true;
}

bool IrrcacheIntegrator::Pilot(const Ray& ray, Rng& rng, RenderCounters& counters,
                               PilotRecord* out) const {
  DiffuseVertex dv;
  if (!FirstDiffuse(ray, rng, counters, &dv)) return false;
  const float spread = scene_.camera().PixelSpread(dv.distance);
  Vec3 half_diff;
  const IrradianceRecord r =
      ComputeRecord(dv.hit, dv.nf, dv.depth, spread, rng, counters, &half_diff);
  out->record = r;
  const Bsdf& bsdf = scene_.material(dv.hit.material);
  out->weight =
      dv.beta * bsdf.DiffuseAlbedo(dv.hit.Context(), dv.hit.Frame().ToLocal(-ray.dir)) * kInvPi;
  // Var(E) = E[(E_even - E_odd)^2] / 4 for two independent halves (as CacheError).
  out->irradiance_variance = half_diff * half_diff * 0.25f;
  out->footprint_px = spread > 0 ? settings_.accuracy * r.radius / spread : 0;
  return true;
}

bool IrrcacheIntegrator::Prime(const Ray& ray, Rng& rng, RenderCounters& counters) const {
  DiffuseVertex dv;
  if (!FirstDiffuse(ray, rng, counters, &dv)) return false;
  bool made = false;
  Irradiance(dv.hit, dv.nf, dv.depth, dv.distance, false, rng, counters, &made);
  return made;
}

}  // namespace irfarm
