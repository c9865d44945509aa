// The unbiased path tracer (Mitsuba's `path`): next-event estimation at every non-delta vertex
// with multiple importance sampling (power heuristic) against BSDF sampling, specular chains
// followed exactly, Russian roulette from rr_depth on. Also used by the irradiance-cache
// integrator to estimate the radiance arriving along each hemisphere ray of a new record.
#pragma once

#include "render/aov.h"
#include "render/caustic_map.h"
#include "render/environment_sun.h"
#include "render/render_counters.h"
#include "render/sampling.h"
#include "render/scene.h"

namespace irfarm {

struct PathSettings {
  int max_depth = -1;  // path vertices as Mitsuba counts them; -1 = unbounded
  int rr_depth = 5;
  // Next-event estimation with one sample of every light (and of the environment) at each
  // vertex, instead of one light picked by its unoccluded contribution: a sun or a sky that is
  // blocked at most points of a room lit through a window, or one lamp among several, is then
  // not picked in vain. Up to LightSampler::kAllLightsMax local lights; with more, one is
  // picked as usual.
  // Measured at 16 spp (path) and 1540 record rays (irrcache), against picking one light:
  // room-a (2 lamps, sun, sky) path relMSE 0.111 -> 0.019 for 1.7x the time, room-c 0.058 ->
  // 0.0061 for 1.5x; irrcache room-a 7.4e-4 -> 5.1e-4 (the reference's own error is about
  // 3.2e-4 of that), room-d 5.9e-4 -> 4.5e-4 in the same time; one-lamp scenes unchanged.
  bool all_lights = true;
  // The environment's next-event samples drawn by its radiance (LightSampler::SampleEnvironment
  // with importance), not cosine-weighted only. On for `path` (SettingsForScene): living-room
  // at 64 spp relMSE 0.152 -> 0.136 in 1.06-1.10x the time. Off for `irrcache`, whose records
  // smooth the environment's light anyway: there the same change cost 18-36% more CPU on
  // living-room, materials and principled for equal error (the importance-sampled shadow rays
  // cross the room, through windows and masked leaves, where cosine ones hit the nearest wall).
  // (irrcache's camera-path glossy vertices draw the environment by its radiance regardless:
  // kGlossyEnvImportance in irrcache_integrator.cc.) Either way, where the scene's
  // EnvironmentGuide has a cell, half of the samples aim where the environment was seen from there.
  bool env_importance = false;
  // Irradiance records' paths with a caustic map (CausticMap: light of area, point and spot
  // lights that reached a diffuse surface through one or more of the map's lobes M: delta lobes,
  // and in scenes with a sharp glossy material every non-diffuse lobe). Such light is the map's
  // wherever it lands: at the path's start (the record point, whose lookups add the map) and at
  // every vertex on the way, where the path adds the map's irradiance through the vertex's
  // diffuse lobe. The path keeps beside its throughput the part whose scatterings since the last
  // diffuse one (or the start) all went through M (each vertex's f over the sampled pdf, split
  // by lobe), and takes that part off the map's lights' next-event estimates through M and off
  // their emission found by BSDF sampling: what is left reaches the path with a scattering
  // outside M last before its light. So a lamp's highlight on a metal box, reflected onto the
  // ceiling a record sees (strata that find it rarely and very bright: blotches), is the
  // photons'.
  const CausticMap* caustics = nullptr;
  // Irradiance records' paths where an environment map's sun is direct light
  // (IrrcacheSettings::direct_sun): every non-delta vertex takes one sample of it (by its
  // luminance) with the full BSDF, and the environment's light from its directions is left out
  // where such a sample was made (escapes past a non-delta vertex, the environment's next-event
  // samples) and on the first segment when skip_first_local_emission (the record point's direct
  // light, DirectLight's).
  const EnvironmentSun* direct_sun = nullptr;
  // Mesh lamps' light trees walk with stop_far (LightTree::Sample): cheaper samples where a lamp
  // is far against its size. On for the path integrator's camera paths (the final pass), off in
  // irrcache, whose image noise is its direct light's.
  bool coarse_light_tree = false;
};

// Radiance arriving at the ray's origin along `ray`, whose first hit is path vertex `depth`.
// `skip_first_local_emission`: the ray was sampled at a point whose direct light from local
// (area, point, spot, directional) lights is computed explicitly, so area emission at the first
// hit is not counted; environment light is counted in full along the first segment.
// `first_distance` (optional) receives the distance to the first hit (INFINITY on escape).
// `aov` (optional, camera paths) receives the sample's AOVs, split at the first non-specular
// vertex x: direct = emission seen before x, next-event estimation at x and the light the BSDF
// ray from x hits (the other half of that MIS pair); indirect = the rest. The returned radiance
// is their sum (accumulated in the same order, so equal within float rounding).
// `first_environment` (optional) receives the part of the result that is environment light along
// the first segment (through masks' pass-through included; 0 when the ray hits something).
Vec3 TracePath(const Scene& scene, Ray ray, int depth, bool skip_first_local_emission,
               const PathSettings& settings, Rng& rng, RenderCounters& counters,
               float* first_distance = nullptr, SampleAov* aov = nullptr,
               Vec3* first_environment = nullptr);

}  // namespace irfarm
