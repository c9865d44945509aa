// Picks and samples the scene's lights as seen from a shading point (p, n).
//
// Selection: each light gets a weight, an estimate of its unoccluded contribution at p (power,
// distance, orientation, the spot's cone; for rectangles the exact unoccluded irradiance by
// Lambert's formula); lights that cannot reach p (behind p's horizon, p behind their emitting
// side, outside a spot's cone) get weight 0 and so no sample and no shadow ray. With more than
// kMaxSpatialLights local lights the weights are not evaluated per point (that would cost
// O(lights) per sample) and the choice is uniform.
//
// Sampling one light: rectangles by solid angle (spherical rectangles), spheres by their cone of
// directions, emissive meshes by a triangle picked by its estimated contribution at (p, n) (the
// mesh's LightTree) and then sampled by solid angle (spherical triangles); by area only where
// the solid angle is too small to sample that way (far away, where the area pdf is harmless). The
// environment (all constant + envmap lights together) is sampled cosine-weighted around n
// (uniformly over the sphere when n is zero), and, when it holds an envmap, by its radiance
// (EnvironmentMapSampler) with probability 1 - kEnvCosineShare: a mixture, so that the cosine part
// still covers the light an envmap holds where the map's density is low.
//
// n may be the zero vector: no horizon test (points that also transmit light).
#pragma once

#include <vector>

#include "render/environment_guide.h"
#include "render/environment_map_sampler.h"
#include "render/light.h"
#include "render/sampling.h"

namespace irfarm {

class LightSampler {
 public:
  static constexpr int kMaxSpatialLights = 64;
  // Up to this many local lights, next-event estimation may sample every light at each vertex
  // (SampleForNee with all = true); with more, one is picked.
  static constexpr int kAllLightsMax = 16;
  // Share of environment samples drawn cosine-weighted when an envmap is importance sampled.
  // 0.1 since 2026-12-04 (0.25 before): seeds 1-2 / 7-8, `path` 64 spp on living-room relMSE
  // -2.5%; irrcache defaults: layered_kitchen (studio map) -9% / -20%, layered_shoes (a silver
  // floor reflecting it) -4%, living-room, rooms 501 and 511 within their scatter; CPU alike
  // (docs/bench/envmap-record-samples-2026-12-04/cosine-share.log).
  static constexpr float kEnvCosineShare = 0.1f;
  // Share of environment samples drawn from the EnvironmentGuide's histogram where it has one.
  static constexpr float kGuideShare = 0.5f;

  // `lights`: local lights first, then environment lights.
  void Build(std::vector<Light> lights, int num_local);

  const std::vector<Light>& lights() const { return lights_; }
  int num_local() const { return num_local_; }
  bool has_environment() const { return int(lights_.size()) > num_local_; }
  // An environment map that SampleEnvironment(..., importance = true) samples by its radiance.
  bool has_environment_map() const { return !env_map_.empty(); }
  // Where the environment is seen from (Scene::Build learns it after Build); null: unguided.
  void set_guide(const EnvironmentGuide* guide) { guide_ = guide; }

  // Selection weight of local light i at (p, n); 0 exactly when it cannot reach p.
  float Weight(int i, const Vec3& p, const Vec3& n) const;
  // Unoccluded irradiance at (p, n) from area light i when it has a closed form (rectangles),
  // else a negative value. n must be a unit normal.
  Vec3 AnalyticIrradiance(int i, const Vec3& p, const Vec3& n) const;

  // Samples local light i alone from (p, n): s->pdf is the solid-angle pdf of this light alone
  // (0 for delta lights), s->value = Le / pdf (delta lights: I / d^2, or E). False: nothing
  // reaches p. n (which may be zero) guides the choice of a mesh's triangle, which takes u2 (and
  // leaves what remains of it to the point on the triangle), so that stratified (u2, u3) spread
  // over a mesh's triangles too. `coarse`: a mesh's light tree walks with stop_far
  // (LightTree::Sample).
  bool SampleOne(int i, const Vec3& p, const Vec3& n, float u2, float u3, LightSample* s,
                 bool coarse = false) const;
  // Solid-angle pdf of SampleOne(i, p, n, ...) giving direction wi that reaches point q
  // (shading normal nq, triangle prim) of area light i.
  float PdfOne(int i, const Vec3& p, const Vec3& n, const Vec3& q, const Vec3& nq, unsigned prim,
               const Vec3& wi, bool coarse = false) const;

  // Samples the environment alone from (p, n): cosine-weighted around n (uniform over the sphere
  // when n is zero), and with `importance` and an envmap the mixture with its radiance
  // (EnvironmentMapSampler); s->pdf is that direction's pdf alone, s->value 1 / pdf (see Sample).
  // `importance` (PathSettings::env_importance) must be the same in the matching pdf calls.
  // With a guide that has a cell at p, kGuideShare of the samples come from its histogram.
  bool SampleEnvironment(const Vec3& p, const Vec3& n, float u2, float u3, LightSample* s,
                         bool importance = false) const;
  // The same with `guide` instead of the sampler's own (null: unguided); EnvironmentGuide::Learn
  // samples its second round with its first round's histograms.
  bool SampleEnvironment(const EnvironmentGuide* guide, const Vec3& p, const Vec3& n, float u2,
                         float u3, LightSample* s, bool importance) const;
  // The pdf of SampleEnvironment(p, n, ...) giving wi.
  float PdfEnvironmentAlone(const Vec3& p, const Vec3& n, const Vec3& wi,
                            bool importance = false) const;
  // Picks a light by weight (the environment too when include_env) and samples it; pdf and
  // value include the selection probability. An environment sample's value lacks the radiance
  // (LightSample::environment): Scene::LightValue completes it once the sample is unblocked.
  // *skipped (if given) counts the local lights that got weight 0 (no shadow ray is spent on them).
  bool Sample(const Vec3& p, const Vec3& n, float u1, float u2, float u3, bool include_env,
              LightSample* s, int* skipped = nullptr, bool env_importance = false) const;
  // Probability that Sample(p, n, ..., include_env = true) picks local light `index`, or the
  // environment for index == num_local().
  float SelectionProbability(const Vec3& p, const Vec3& n, int index) const {
    return SelectPdf(p, n, index);
  }
  // Solid-angle pdf, including selection, of Sample(p, n, ..., include_env = true) having
  // produced direction wi towards point q of area light `light`.
  float PdfArea(const Vec3& p, const Vec3& n, int light, const Vec3& q, const Vec3& nq,
                unsigned prim, const Vec3& wi) const;
  // ... and of it having produced the environment direction wi.
  float PdfEnvironment(const Vec3& p, const Vec3& n, const Vec3& wi, bool importance = false) const;

  // Radiance from the environment lights (constant + envmap) along direction d.
  Vec3 EvalEnvironment(const Vec3& d) const;

  // Next-event estimation at (p, n), for a path vertex that also samples its BSDF (MIS). With
  // `all` (PathSettings::all_lights) and at most kAllLightsMax local lights: one sample of every
  // local light that can reach p and one of the environment, each alone (its own pdf, no
  // selection); else one light (or the environment) picked by weight, as Sample does. Calls
  // f(const LightSample&) for each sample; lights that cannot reach p are counted in *skipped.
  // Random numbers: three per light (two for the environment), or three in all.
  bool SamplesEveryLight(bool all) const { return all && num_local_ <= kAllLightsMax; }
  // `coarse` (PathSettings::coarse_light_tree) applies to the every-light samples only, as in
  // NeePdfArea.
  template <typename F>
  void SampleForNee(bool all, bool env_importance, const Vec3& p, const Vec3& n, Rng& rng,
                    uint64_t* skipped, F&& f, bool coarse = false) const {
    if (!SamplesEveryLight(all)) {
      LightSample s;
      const float u1 = rng.Next(), u2 = rng.Next(), u3 = rng.Next();
      int zero = 0;
      const bool ok = Sample(p, n, u1, u2, u3, true, &s, &zero, env_importance);
      *skipped += uint64_t(zero);
      if (ok) f(s);
      return;
    }
    for (int i = 0; i < num_local_; ++i) {
      if (Weight(i, p, n) <= 0) {
        ++*skipped;  // cannot reach: no sample, no shadow ray
        continue;
      }
      LightSample s;
      const float u2 = rng.Next(), u3 = rng.Next();
      if (SampleOne(i, p, n, u2, u3, &s, coarse)) f(s);
    }
    if (has_environment()) {
      LightSample s;
      const float u2 = rng.Next(), u3 = rng.Next();
      if (SampleEnvironment(p, n, u2, u3, &s, env_importance)) f(s);
    }
  }
  // The pdf with which SampleForNee(all, p, n, ...) produces direction wi towards point q of
  // area light `light` (0 when it never does), and towards the environment: what MIS weighs a
  // BSDF sample from p against.
  float NeePdfArea(bool all, const Vec3& p, const Vec3& n, int light, const Vec3& q, const Vec3& nq,
                   unsigned prim, const Vec3& wi, bool coarse = false) const;
  float NeePdfEnvironment(bool all, const Vec3& p, const Vec3& n, const Vec3& wi,
                          bool env_importance = false) const;

 private:
  // Selection probability of candidate `index` (num_local_ = the environment).
  float SelectPdf(const Vec3& p, const Vec3& n, int index) const;
  float EnvironmentWeight(const Vec3& n) const;
  // The unguided environment density (cosine, or the mixture with the map's).
  float UnguidedPdf(const Vec3& n, const Vec3& wi, bool importance) const;

  std::vector<Light> lights_;
  int num_local_ = 0;
  EnvironmentMapSampler env_map_;  // empty without an envmap (or with a non-rotation frame)
  const EnvironmentGuide* guide_ = nullptr;
};

}  // namespace irfarm
