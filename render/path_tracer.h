// The unbiased path tracer (Mitsuba's `path`): next-event estimation at every non-delta vertex
// with multiple importance sampling (power heuristic) against BSDF sampling, specular chains
// followed exactly, Russian roulette from rr_depth on. Also used by the irradiance-cache
// integrator to estimate the radiance arriving along each hemisphere ray of a new record.
#pragma once

#include "render/aov.h"
#include "render/render_counters.h"
#include "render/sampling.h"
#include "render/scene.h"

namespace irfarm {

struct PathSettings {
  int max_depth = -1;  // path vertices as Mitsuba counts them; -1 = unbounded
  int rr_depth = 5;
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
Vec3 TracePath(const Scene& scene, Ray ray, int depth, bool skip_first_local_emission,
               const PathSettings& settings, Rng& rng, RenderCounters& counters,
               float* first_distance = nullptr, SampleAov* aov = nullptr);

}  // namespace irfarm
