// GlobalCache::RecordsNear (coordinator/global_cache.h): for random records (small and huge
// radii, secondary levels, positions on the bounds' faces) and random boxes (inside, straddling,
// outside, flat, empty), the records it yields include every record RecordReachesBox accepts,
// each once; and for a small box it yields far fewer than all (it is a filter, not a copy).
#include "coordinator/global_cache.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

#include "coordinator/fanout_region.h"

namespace irfarm {
namespace {

TEST(GlobalCacheTest, RecordsNearABoxIncludeEveryRecordThatReachesIt) {
  std::mt19937 gen(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  RecordBounds bounds;
  bounds.box.lo = Vec3(-3, 0, 10);
  bounds.box.hi = Vec3(5, 2, 14);
  CacheSettings settings;
  settings.max_accuracy = 0.3f;
  GlobalCache cache(settings, bounds);
  const Vec3 lo = bounds.box.lo, size = bounds.box.hi - bounds.box.lo;
  std::vector<IrradianceRecord> records;
  for (int i = 0; i < 20000; ++i) {
    IrradianceRecord r;
    r.position = lo + Vec3(u(gen) * size.x, u(gen) * size.y, u(gen) * size.z);
    if (i % 50 == 0) r.position.x = bounds.box.hi.x;  // on a face of the bounds
    if (i % 77 == 0) r.position.z = bounds.box.lo.z;
    r.normal = Vec3(0, 1, 0);
    r.irradiance = Vec3(1, 1, 1);
    r.radius = i % 100 == 0 ? 5.0f * u(gen) + 0.01f : 0.2f * u(gen) + 1e-4f;
    r.origin = uint32_t(i);  // identifies the record
    r.level = i % 40 == 0 ? 1 : 0;
    records.push_back(r);
  }
  ASSERT_EQ(cache.Merge(records).size(), records.size());
  const float a = cache.max_accuracy();
  size_t small_box_yield = 0, small_boxes = 0;
  for (int q = 0; q < 300; ++q) {
    Bounds3 box;
    const Vec3 c = lo + Vec3((1.4f * u(gen) - 0.2f) * size.x, (1.4f * u(gen) - 0.2f) * size.y,
                             (1.4f * u(gen) - 0.2f) * size.z);
    const float extent = q % 3 == 0 ? 0.05f : 2.0f * u(gen);
    box.lo = c - Vec3(extent * u(gen), q % 7 == 0 ? 0.0f : extent * u(gen), extent * u(gen));
    box.hi = c + Vec3(extent * u(gen), q % 7 == 0 ? 0.0f : extent * u(gen), extent * u(gen));
    if (q % 29 == 0) box = Bounds3();  // empty
    std::multiset<uint32_t> yielded;
    cache.RecordsNear(box).ForEach([&](const IrradianceRecord& r) { yielded.insert(r.origin); });
    for (const IrradianceRecord& r : records) {
      if (RecordReachesBox(r, box, a)) {
        ASSERT_EQ(yielded.count(r.origin), 1u) << "query " << q;
      }
      ASSERT_LE(yielded.count(r.origin), 1u);
    }
    if (q % 3 == 0 && q % 29 != 0) {
      small_box_yield += yielded.size();
      ++small_boxes;
    }
  }
  // Small boxes (0.05 on a side) see their neighbourhood, the huge records and the secondary
  // level, not the whole cache.
  EXPECT_LT(double(small_box_yield) / double(small_boxes), 0.25 * double(records.size()));
}

}  // namespace
}  // namespace irfarm
