// Tests of coordinator/fanout_index.h: on random scenes, regions and records, the grid selects
// exactly the workers the brute-force test (RecordReachesBox against every region) selects:
// small and large regions, empty ones, regions spanning the whole scene, records inside and
// outside the scene, small and huge reaches, secondary records, flat scenes, and records
// exactly at the edge of their reach.
#include "coordinator/fanout_index.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "coordinator/fanout_region.h"

namespace irfarm {
namespace {

class FanoutIndexTest : public ::testing::TestWithParam<int> {};

Vec3 Lerp(const Bounds3& b, const Vec3& t) {
  return Vec3(b.lo.x + t.x * (b.hi.x - b.lo.x), b.lo.y + t.y * (b.hi.y - b.lo.y),
              b.lo.z + t.z * (b.hi.z - b.lo.z));
}

// Compares Query with the brute force (RecordReachesBox against every region, here) for
// `records` random records over `workers` random regions in `scene`. Returns the mean number of
// workers a level-0 record reached, -1 on a mismatch; *grid: level-0 queries the grid answered.
double Compare(std::mt19937& rng, const Bounds3& scene, int workers, int records,
               uint64_t* grid = nullptr) {
  std::uniform_real_distribution<float> u(0, 1);
  const auto point = [&](float margin) {
    const Vec3 t(u(rng) * (1 + 2 * margin) - margin, u(rng) * (1 + 2 * margin) - margin,
                 u(rng) * (1 + 2 * margin) - margin);
    return Lerp(scene, t);
  };
  const float diag = Length(scene.Diagonal());
  std::vector<FanoutIndex::Entry> entries;
  for (int i = 0; i < workers; ++i) {
    FanoutIndex::Entry e{uint32_t(100 + i), Bounds3()};
    const int kind = int(u(rng) * 10);
    if (kind == 0) {
      // no region yet: stays empty
    } else if (kind == 1) {
      e.box = scene;  // the whole scene
    } else {
      // A tile's region: a box 0.1% to 20% of the scene's size (larger for kind 2).
      const Vec3 c = point(0);
      const float s = diag * (kind == 2 ? 0.2f : 0.001f + 0.05f * u(rng));
      e.box.Extend(Max(scene.lo, Min(scene.hi, c - Vec3(s * u(rng), s * u(rng), s * u(rng)))));
      e.box.Extend(Max(scene.lo, Min(scene.hi, c + Vec3(s * u(rng), s * u(rng), s * u(rng)))));
    }
    entries.push_back(e);
  }
  FanoutIndex index;
  index.Build(scene, entries);
  EXPECT_EQ(index.size(), entries.size());
  for (size_t s = 0; s < entries.size(); ++s) EXPECT_EQ(index.worker(s), entries[s].worker);
  std::vector<uint32_t> got, want;
  size_t reached = 0, level0 = 0;
  for (int i = 0; i < records; ++i) {
    IrradianceRecord r;
    r.position = point(0.05f);
    r.normal = Vec3(0, 0, 1);
    r.irradiance = Vec3(1);
    // Radii over 5 decades: most small, some reaching across the scene.
    r.radius = diag * std::pow(10.0f, -4.0f + 4.0f * u(rng));
    r.level = u(rng) < 0.1f ? 1 : 0;
    const float a = 0.1f + 0.4f * u(rng);
    if (i % 7 == 0 && !entries.empty()) {
      // Exactly at the edge: R such that a R is the distance to a region's box.
      const Bounds3& b = entries[size_t(u(rng) * entries.size()) % entries.size()].box;
      if (!b.Empty()) {
        double d2 = 0;
        for (int k = 0; k < 3; ++k) {
          const double p = r.position[k];
          const double d = std::max({double(b.lo[k]) - p, 0.0, p - double(b.hi[k])});
          d2 += d * d;
        }
        if (d2 > 0) r.radius = float(std::sqrt(d2) / a);
      }
    }
    index.Query(r, a, &got);
    want.clear();
    for (size_t s = 0; s < entries.size(); ++s)
      if (RecordReachesBox(r, entries[s].box, a)) want.push_back(uint32_t(s));
    std::sort(got.begin(), got.end());
    EXPECT_TRUE(std::adjacent_find(got.begin(), got.end()) == got.end()) << "a slot twice";
    EXPECT_EQ(got, want) << "record " << i << " level " << int(r.level) << " R " << r.radius;
    if (got != want) return -1;
    if (r.level == 0) {
      reached += got.size();
      ++level0;
    }
  }
  if (grid) *grid = index.grid_queries();
  return level0 ? double(reached) / level0 : 0;
}

TEST_P(FanoutIndexTest, SelectsExactlyTheBruteForceWorkers) {
  const int workers = GetParam();
  std::mt19937 rng(1234 + workers);
  Bounds3 scene;
  scene.Extend(Vec3(-3, 0, -1));
  scene.Extend(Vec3(5, 2.5f, 4));
  uint64_t grid = 0;
  const double mean = Compare(rng, scene, workers, 3000, &grid);
  std::printf(
      "MEASURED %d workers: a level-0 record reached %.2f of them on average; the grid "
      "answered %llu queries\n",
      workers, mean, static_cast<unsigned long long>(grid));
  EXPECT_NE(mean, -1.0);
  if (workers > 0) {
    // The grid answered most level-0 queries (not the brute-force fallback the comparison is
    // against), some records reached a worker, and with many workers most were not reached.
    EXPECT_GT(grid, 3000u / 2);
    EXPECT_GT(mean, 0);
  }
  if (workers >= 64) {
    EXPECT_LT(mean, 0.5 * workers);
  }
  // Far from the origin (large coordinates, float rounding of boxes and positions).
  Bounds3 far;
  far.Extend(Vec3(1e5f, -2e5f, 3e4f));
  far.Extend(Vec3(1e5f + 40, -2e5f + 10, 3e4f + 25));
  EXPECT_NE(Compare(rng, far, workers, 1000, &grid), -1.0);
  if (workers > 0) {
    EXPECT_GT(grid, 0u);
  }
  // Flat: no extent along y.
  Bounds3 flat;
  flat.Extend(Vec3(0, 1, 0));
  flat.Extend(Vec3(10, 1, 10));
  EXPECT_NE(Compare(rng, flat, workers, 1000, &grid), -1.0);
  if (workers > 0) {
    EXPECT_GT(grid, 0u);
  }
}

INSTANTIATE_TEST_SUITE_P(Workers, FanoutIndexTest, ::testing::Values(0, 1, 2, 7, 64, 256, 1000));

}  // namespace
}  // namespace irfarm
