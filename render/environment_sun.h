// The sun of an environment map: the few directions of a photographed sky (an HDRI) whose
// radiance is far above the rest, and which light a room through its window as a directional
// light would. Where the scene has a sharp metal or a mirror, the sun's highlight on it, reflected
// onto the walls, is a caustic that a record's rays find rarely and very bright; the caustic map
// takes it (CausticMap: photons from these directions), and the record paths leave out the
// environment's light from exactly these directions where it reaches them through the map's
// lobes (CausticMap::CoversEnvironment).
//
// Found on a latitude-longitude grid over world directions (u = phi / 2 pi, v = theta / pi, as
// EnvmapUv has them), kCellsU x kCellsV cells, each evaluated at its centre: the cells at or
// above kSunRatio times the environment's mean radiance, grown by one cell (the sun's edge and the
// texture's bilinear filtering spill into them). They are the sun only where they lie within
// kSunMaxRadius of their luminance-weighted mean direction (a studio's softboxes or a bright
// horizon are not one); otherwise there is none. The region is a union of whole cells, so the
// photons' directions and the records' test agree exactly.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "core/cdf_guide.h"
#include "core/math.h"

namespace irfarm {

class EnvironmentSun {
 public:
  static constexpr int kCellsU = 1024, kCellsV = 512;
  static constexpr float kSunRatio = 100;
  static constexpr float kSunMaxRadius = 0.1f;  // radians (about 6 degrees)
  // Sample's resolution: each cell is kSubCells x kSubCells sub-cells (0.044 degrees), finer than
  // a 2048 x 1024 map's texels, so a sample's value over its density hardly varies across a sun
  // that covers part of a cell.
  static constexpr int kSubCells = 8;

  // The environment's sun, from its radiance along world directions (all environment lights
  // summed, as LightSampler::EvalEnvironment has it); empty when the scene has no envmap
  // (`has_envmap` false: a constant has none) or the envmap has no sun. Scene::Build finds it.
  static EnvironmentSun Find(const std::function<Vec3(const Vec3&)>& radiance, bool has_envmap);
  bool empty() const { return cells_.empty(); }

  // Whether world direction d (towards the sky, unit) is in the sun's region.
  bool Contains(const Vec3& d) const;
  // A direction in the region (unit, towards the sky) and its solid-angle density, from three
  // uniform numbers; sub-cells are picked by the luminance at their centres times their solid
  // angle, a point uniformly within the sub-cell.
  void Sample(float u1, float u2, float u3, Vec3* d, float* pdf) const;
  // The luminance-weighted mean direction of the region (unit, towards the sky) and the largest
  // angle of a cell's corner from it.
  const Vec3& axis() const { return axis_; }
  float radius() const { return radius_; }
  // The region's irradiance (luminance) on a plane facing the axis, as the cells' weights sum it.
  float irradiance() const { return irradiance_; }

 private:
  std::vector<uint8_t> marked_;  // kCellsU x kCellsV, row-major (v rows); empty when none
  std::vector<uint32_t> cells_;  // the marked cells' sub-cells (row-major, kSubCells finer)
  std::vector<float> cdf_;       // cumulative weights over cells_
  CdfGuide guide_;               // over cdf_, one bucket per sub-cell
  Vec3 axis_;
  float radius_ = 0, irradiance_ = 0;
  float cos_radius_ = 2;  // Contains' quick rejection: below it, outside (2: empty)
};

}  // namespace irfarm
