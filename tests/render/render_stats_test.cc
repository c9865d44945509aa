// The stats file (`--stats`, RenderStats::ToJson): valid JSON whatever the strings hold, with the
// figures scripts read, from a real render.
#include "render/render_stats.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "render/renderer.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

TEST(RenderStatsTest, JsonOfARealRenderHoldsItsFigures) {
  const LoadedScene s = LoadQuarter("cornell-box");
  RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
  settings.spp = 4;
  const RenderOutput out = Render(*s.scene, settings);
  const nlohmann::json j = nlohmann::json::parse(out.stats.ToJson());
  EXPECT_EQ(j["integrator"], "irrcache");
  EXPECT_EQ(j["width"], out.stats.width);
  EXPECT_EQ(j["records"]["computed"], out.stats.counters.records_computed);
  EXPECT_GT(j["records"]["computed"].get<uint64_t>(), 0u);
  EXPECT_EQ(j["rays"]["total"], out.stats.counters.camera_rays + out.stats.counters.bounce_rays +
                                    out.stats.counters.shadow_rays +
                                    out.stats.counters.record_rays);
  EXPECT_DOUBLE_EQ(j["sampling"]["spp_mean"].get<double>(), out.stats.spp_mean);
  // Floats are written as a short decimal that reads back as the same float (0.1f as 0.1, not
  // 0.10000000149011612).
  EXPECT_EQ(float(j["settings"]["accuracy"].get<double>()), out.stats.accuracy);
  EXPECT_LE(j["settings"]["accuracy"].dump().size(), 10u) << j["settings"]["accuracy"].dump();
  double phases = 0;
  for (const PhaseTime& p : out.stats.phases) {
    ASSERT_TRUE(j["seconds"].contains(p.name)) << p.name;
    phases += p.wall_seconds;
  }
  EXPECT_NEAR(j["seconds"]["total"].get<double>(), phases, 1e-9);
}

TEST(RenderStatsTest, StringsWithQuotesControlsAndInvalidUtf8StayValidJson) {
  RenderStats st;
  st.scene = "/tmp/a \"quoted\"\\dir/\xff\xfe/scene.xml";
  st.warnings = {"line one\nline two\t\"x\"", std::string("nul \0 byte", 10)};
  st.estimated_sampling_relmse = NAN;  // not expected; must still be JSON (null)
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(st.ToJson()));
  EXPECT_EQ(j["warnings"][0], "line one\nline two\t\"x\"");
  EXPECT_EQ(j["warnings"][1].get<std::string>().size(), 10u);
  // The invalid bytes are replaced (U+FFFD), the rest of the path kept.
  const std::string scene = j["scene"];
  EXPECT_NE(scene.find("/tmp/a \"quoted\"\\dir/"), std::string::npos);
  EXPECT_NE(scene.find("/scene.xml"), std::string::npos);
  EXPECT_TRUE(j["error_estimate"]["sampling_relmse"].is_null());
}

// error_estimate.relmse is the whole image's estimate only where each part was estimated: an
// irrcache render without cross-validated records (cache_relmse -1) writes null, not its camera
// samples' part as if it were the total.
TEST(RenderStatsTest, TotalErrorEstimateOnlyWhenTheCacheWasEstimated) {
  RenderStats st;
  st.integrator = "irrcache";
  st.estimated_sampling_relmse = 5e-5;
  st.estimated_cache_relmse = -1;
  nlohmann::json j = nlohmann::json::parse(st.ToJson());
  EXPECT_TRUE(j["error_estimate"]["relmse"].is_null());
  EXPECT_DOUBLE_EQ(j["error_estimate"]["sampling_relmse"].get<double>(), 5e-5);

  st.estimated_cache_relmse = 3e-4;
  j = nlohmann::json::parse(st.ToJson());
  EXPECT_DOUBLE_EQ(j["error_estimate"]["relmse"].get<double>(), 3.5e-4);

  st.integrator = "path";  // no cache: the samples' estimate is the image's
  st.estimated_cache_relmse = -1;
  j = nlohmann::json::parse(st.ToJson());
  EXPECT_DOUBLE_EQ(j["error_estimate"]["relmse"].get<double>(), 5e-5);
}

// --target-error's refinement rounds are listed in order under error_estimate.cache_rounds; a
// render without them writes no list.
TEST(RenderStatsTest, CacheRoundsAreListedInOrder) {
  RenderStats st;
  st.integrator = "irrcache";
  nlohmann::json j = nlohmann::json::parse(st.ToJson());
  EXPECT_FALSE(j["error_estimate"].contains("cache_rounds"));
  st.cache_rounds.push_back(CacheRound{0.36f, 1.0f, 128, 1.8e-2, 1.6e-2, 2e-3, false});
  st.cache_rounds.push_back(CacheRound{0.15f, 1.5f, 2048, 4.4e-3, 8e-4, 2e-3, true});
  j = nlohmann::json::parse(st.ToJson());
  const nlohmann::json& rounds = j["error_estimate"]["cache_rounds"];
  ASSERT_EQ(rounds.size(), 2u);
  EXPECT_EQ(rounds[0]["record_rays"], 128);
  EXPECT_DOUBLE_EQ(rounds[0]["cache_relmse"].get<double>(), 1.8e-2);
  EXPECT_FALSE(rounds[0]["rebuilt"].get<bool>());
  EXPECT_EQ(rounds[1]["record_rays"], 2048);
  EXPECT_DOUBLE_EQ(rounds[1]["noise_relmse"].get<double>(), 8e-4);
  EXPECT_DOUBLE_EQ(rounds[1]["share"].get<double>(), 2e-3);
  EXPECT_NEAR(rounds[1]["lookup_factor"].get<double>(), 1.5, 1e-6);
  EXPECT_TRUE(rounds[1]["rebuilt"].get<bool>());
}

}  // namespace
}  // namespace irfarm
