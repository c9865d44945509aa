// A job's wire settings (v1::RenderSettings) reach the settings its tiles render with
// (service/job_settings.h): the switches a client can turn off, and the job's own values checked.
#include <gtest/gtest.h>

#include <string>

#include "service/job_settings.h"

namespace irfarm {
namespace {

SceneDesc CornellBox(const v1::RenderSettings& settings) {
  const absl::StatusOr<SceneDesc> desc =
      LoadJobScene(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml", settings);
  EXPECT_TRUE(desc.ok()) << desc.status();
  return desc.ok() ? *desc : SceneDesc{};
}

TEST(JobSettingsTest, SwitchesAreOnUnlessTheJobTurnsThemOff) {
  v1::RenderSettings wire;
  absl::StatusOr<RenderSettings> s = MakeRenderSettings(CornellBox(wire), wire, 1);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_TRUE(s->firefly_filter);
  EXPECT_TRUE(s->caustics);
  EXPECT_TRUE(s->overture);
  wire.set_no_firefly_filter(true);
  wire.set_no_caustics(true);
  wire.set_no_overture(true);
  s = MakeRenderSettings(CornellBox(wire), wire, 1);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_FALSE(s->firefly_filter);
  EXPECT_FALSE(s->caustics);
  EXPECT_FALSE(s->overture);
  EXPECT_EQ(s->tile_size, kJobSubTileSize);
}

TEST(JobSettingsTest, TheJobsOwnValuesAreChecked) {
  v1::RenderSettings wire;
  wire.set_tile_size(3);
  absl::StatusOr<RenderSettings> s = MakeRenderSettings(CornellBox(wire), wire, 1);
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.status().message().find("tile_size"), std::string::npos) << s.status();
  wire.set_tile_size(0);
  wire.set_tile_time_limit(-1);
  s = MakeRenderSettings(CornellBox(wire), wire, 1);
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.status().message().find("tile_time_limit"), std::string::npos) << s.status();
}

}  // namespace
}  // namespace irfarm
