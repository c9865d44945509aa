// Where the environment is seen from: grids of cells over the points the camera's paths reach,
// each cell with a histogram over directions of the environment's light that arrives there
// unblocked. A room lit through its windows sees the sky through a few tenths of a steradian;
// drawn by its radiance (or cosine-weighted) from such a point, most environment samples hit a
// wall, and the few that pass carry all the light: the estimate is mostly zeros. LightSampler
// draws a share of its environment samples from the cell's histogram instead (a mixture, so its
// density stays positive wherever it was before: the histogram only moves samples, and the
// estimate stays unbiased whatever it learned). Path guiding (Vorba et al. 2014, Mueller et al.
// 2017) learns such densities for every bounce; this one is for the environment's next-event
// samples alone, learned once before the render.
//
// Learned in Scene::Build from fixed random streams (every process learns the same guide):
// kPaths camera paths through random pixels, up to kVertices diffuse bounces each. At every
// vertex, kRaysPerVertex environment samples; the unblocked ones add their estimate (radiance over
// density) to their direction's bin in the 8 cells around the vertex (trilinear weights), in both
// grids. Round 1 samples the unguided mixture; round 2 draws half of its samples from round 1's
// histograms, which find the openings far more often. A cell whose histogram gathered less than
// kMinWeight unblocked samples stays unguided; a point takes the fine grid's cell where it has a
// histogram, else the coarse grid's, else none. No guide where the scene is open to the sky (more
// than kMaxPassFraction of the unguided samples pass) or where the environment gives less than
// kMinEnvironmentShare of the vertices' direct light (a room lit by its lamps or by a sun).
//
// Directions: kBandsZ x kBandsPhi bins of equal solid angle (bands of equal world z, sectors of
// equal azimuth).
#pragma once

#include <cstdint>
#include <vector>

#include "core/math.h"

namespace irfarm {

class Scene;

class EnvironmentGuide {
 public:
  static constexpr int kBandsZ = 16, kBandsPhi = 32, kBins = kBandsZ * kBandsPhi;
  static constexpr uint32_t kOne = 65535;  // a histogram's probabilities are in units of 1 / kOne
  // The grids' cubic cells along the vertices' longest side: fine, then coarse.
  static constexpr int kLevels = 2;
  static constexpr int kCells[kLevels] = {16, 5};
  static constexpr int kPaths = 8192, kVertices = 3, kRaysPerVertex = 8;
  static constexpr float kMinWeight = 4;
  // A guide is learned only where fewer than kMaxPassFraction of round 1's (unguided) samples
  // reached the environment, and where it gives at least kMinEnvironmentShare of the vertices'
  // direct light.
  static constexpr float kMaxPassFraction = 0.05f;
  static constexpr float kMinEnvironmentShare = 0.1f;

  // The scene's guide; empty without an environment light.
  static EnvironmentGuide Learn(const Scene& scene);
  bool empty() const { return cdf_.empty(); }
  int cells() const { return int(cdf_.size() / kStride); }

  // Histograms are kept per cell and per normal class (the normal's dominant axis and its sign):
  // a box's face turned away from the window must not draw samples towards it from the floor's
  // histogram beside it (they would fall below its horizon and be lost).
  static constexpr int kClasses = 6;
  static int ClassOf(const Vec3& n);  // -1 for the zero vector
  // The histogram that guides samples from p with normal n, or -1 (none: unguided).
  int CellOf(const Vec3& p, const Vec3& n) const;
  // A direction drawn from cell's histogram and its solid-angle density.
  bool Sample(int cell, float u1, float u2, Vec3* wi, float* pdf) const;
  // Solid-angle density of Sample(cell, ...) giving the unit direction wi.
  float Pdf(int cell, const Vec3& wi) const;

  static int BinOf(const Vec3& wi);

 private:
  struct Grid {
    Vec3 lo;
    float cell = 0;
    int res[3] = {0, 0, 0};
    std::vector<int32_t> index;    // res cells (x fastest) x kClasses: histogram or -1
    int Key(const Vec3& p) const;  // the cell containing p, or -1
  };
  Grid levels_[kLevels];
  // Per histogram, kStride values: the z bands' cumulative probabilities (kBandsZ, last 1), then
  // each band's sectors' cumulative probabilities within it (kBandsZ x kBandsPhi, each run ending
  // at 1), in units of 1 / kOne. A sample reads two cache lines (the bands, then one band's
  // sectors), where one search over kBins floats read nine: the lookups' cache misses were 5% of
  // a guided render.
  static constexpr int kStride = kBandsZ + kBins;
  std::vector<uint16_t> cdf_;
};

}  // namespace irfarm
