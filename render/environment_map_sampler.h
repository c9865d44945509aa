// Importance sampling of the environment by its radiance: a piecewise-constant density over the
// first envmap's (u, v) parameterisation (u = phi / 2 pi, v = theta / pi, as
// LightSampler::EvalEnvironment reads it), proportional to the luminance of every environment
// light in each cell times sin(theta), as pbrt's and Mitsuba's envmap emitters have it. A cell is
// picked with Walker's alias method (one table lookup; a marginal and a conditional CDF searched
// by bisection took 10% of a living-room render, their 0.5 MB missing the caches), then a point
// uniformly within it. A sunset or a small sun in an envmap holds most of its light in a few
// cells; cosine-weighted directions find them rarely.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "core/math.h"
#include "render/light.h"

namespace irfarm {

class EnvironmentMapSampler {
 public:
  // `radiance(d)`: the environment's radiance along world direction d. `world_to_env` maps world
  // directions to the envmap's frame; when it is not a rotation (a scale or shear does not keep
  // solid angle) the sampler stays empty. Cells: nu x nv, each the mean of 2 x 2 sub-samples.
  void Build(const std::function<Vec3(const Vec3&)>& radiance, const Mat4& world_to_env,
             int nu = 512, int nv = 256);
  bool empty() const { return total_ <= 0; }

  // A world direction and its solid-angle density (Pdf(*wi), up to rounding at cell edges) from
  // two uniform numbers. False when empty or the density is 0.
  bool Sample(float u1, float u2, Vec3* wi, float* pdf) const;
  // Solid-angle density of Sample producing the unit world direction wi (0 when empty).
  float Pdf(const Vec3& wi) const;

 private:
  // The density of cell (i, j) at sin(theta), per solid angle.
  float CellPdf(int i, int j, float sin_theta) const;
  Vec3 FromUv(float u, float v) const;

  int nu_ = 0, nv_ = 0;
  // The frame as a float rotation (Build's world_to_env must be one): rows map world to env,
  // columns env to world.
  float rot_[3][3] = {};
  float pdf_scale_ = 0;       // nu nv / (total 2 pi^2)
  std::vector<float> cells_;  // nu x nv, row-major (v rows), luminance x sin(theta)
  // Alias table over the cells: cell k is kept with probability keep_[k], else alias_[k] is
  // taken; each entry has probability 1 / (nu nv) of being looked at.
  std::vector<float> keep_;
  std::vector<uint32_t> alias_;
  double total_ = 0;
};

}  // namespace irfarm
