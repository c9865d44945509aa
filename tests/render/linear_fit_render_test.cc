// The cache lookups' linear fit (CacheSettings::linear_fit, on by default) in whole renders: at a
// coarse accuracy, where a cache's error is interpolation bias (records on one side of creases
// and edges), the fit's image is closer to the Mitsuba reference than Ward's weighted mean of
// the same settings. One thread: both renders are deterministic and differ only in the lookups.
// Five seeds per scene, the fit lower on at least four (10 of 10 when written: 4-10% lower).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "render/renderer.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

double CoarseCacheError(const std::string& name, bool linear_fit, uint64_t seed) {
  const LoadedScene s = LoadQuarter(name);
  RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
  settings.spp = 64;
  settings.seed = seed;
  settings.threads = 1;
  settings.irrcache.accuracy = 0.3f;
  settings.irrcache.record_rays = 1024;
  settings.irrcache.balance_record_rays = false;
  settings.irrcache.cache_levels = 1;
  settings.irrcache.choose_cache_levels = false;
  settings.irrcache.linear_fit = linear_fit;
  return CompareImages(Render(*s.scene, settings).image, QuarterReference(name)).relmse;
}

TEST(LinearFitRenderTest, CoarseCacheIsCloserToTheReferenceThanWardsMean) {
  for (const std::string name : {"cornell-box", "room-b"}) {
    int lower = 0;
    for (uint64_t seed = 1; seed <= 5; ++seed) {
      const double fit = CoarseCacheError(name, true, seed);
      const double ward = CoarseCacheError(name, false, seed);
      std::printf("MEASURED %s a = 0.3 seed %d: linear fit %.3g, Ward's mean %.3g\n", name.c_str(),
                  int(seed), fit, ward);
      lower += fit < ward;
    }
    EXPECT_GE(lower, 4) << name;
  }
}

}  // namespace
}  // namespace irfarm
