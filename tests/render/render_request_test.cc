// RenderRequest (render/render_request.h): the one validation of what a user asks of a render,
// and how the request lands in RenderSettings over the scene's defaults.
#include "render/render_request.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "render/pipeline.h"
#include "render_test_util.h"

namespace irfarm {
namespace {

SceneDesc CornellDesc() {
  absl::StatusOr<SceneDesc> desc = LoadSceneFile(TestScenePath("cornell-box"), {});
  EXPECT_TRUE(desc.ok()) << desc.status();
  return desc.ok() ? *desc : SceneDesc();
}

TEST(RenderRequestTest, EachValueOutOfRangeIsRefusedByName) {
  const double nan = std::nan("");
  const double inf = std::numeric_limits<double>::infinity();
  struct Case {
    const char* name;  // must appear in the message
    std::function<void(RenderRequest&)> set;
  };
  const std::vector<Case> cases = {
      {"integrator", [](RenderRequest& r) { r.integrator = "bdpt"; }},
      {"spp", [](RenderRequest& r) { r.spp = -1; }},
      {"spp", [](RenderRequest& r) { r.spp = (1 << 20) + 1; }},
      {"threads", [](RenderRequest& r) { r.threads = -2; }},
      {"accuracy", [](RenderRequest& r) { r.accuracy = 3; }},
      {"accuracy", [](RenderRequest& r) { r.accuracy = -0.1f; }},
      {"accuracy", [nan](RenderRequest& r) { r.accuracy = float(nan); }},
      {"record_rays", [](RenderRequest& r) { r.record_rays = 2000000000; }},
      {"light_samples", [](RenderRequest& r) { r.light_samples = -1; }},
      {"light_sampling", [](RenderRequest& r) { r.light_sampling = "some"; }},
      {"spacing", [](RenderRequest& r) { r.spacing = "grid"; }},
      {"interpolation", [](RenderRequest& r) { r.interpolation = "cubic"; }},
      {"cache_levels", [](RenderRequest& r) { r.cache_levels = 4; }},
      {"min_spacing", [](RenderRequest& r) { r.min_spacing_px = -1; }},
      {"max_spacing", [inf](RenderRequest& r) { r.max_spacing_px = float(inf); }},
      {"lookup_factor", [](RenderRequest& r) { r.lookup_factor = 0.5f; }},
      {"adaptive", [](RenderRequest& r) { r.adaptive = "yes"; }},
      {"min_spp", [](RenderRequest& r) { r.min_spp = -4; }},
      {"max_spp", [](RenderRequest& r) { r.max_spp = 1 << 21; }},
      {"sampling_error", [nan](RenderRequest& r) { r.sampling_error = nan; }},
      {"target_error", [](RenderRequest& r) { r.target_error = 2; }},
      {"target_error", [](RenderRequest& r) { r.target_error = -1e-3; }},
      {"time_limit", [inf](RenderRequest& r) { r.time_limit = inf; }},
  };
  const SceneDesc desc = CornellDesc();
  for (const Case& c : cases) {
    RenderRequest r;
    c.set(r);
    const absl::Status st = ValidateRequest(r);
    EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument) << c.name;
    EXPECT_NE(st.message().find(c.name), std::string::npos) << st.message();
    // SettingsFor refuses it the same way.
    EXPECT_EQ(SettingsFor(desc, r).status(), st) << c.name;
  }
  EXPECT_EQ(ValidateRequest(RenderRequest{}), absl::OkStatus());
  EXPECT_EQ(ValidateRequest(RenderRequest{}).message(), "");
  RenderRequest r;
  r.accuracy = 3;
  EXPECT_EQ(ValidateRequest(r).message(), "accuracy must be in (0, 1], got 3");
}

// The spacing floor above the ceiling is refused (std::clamp, which the records' radius goes
// through, requires floor <= ceiling: undefined behaviour otherwise), whether the two come from
// a request, from one of them and the defaults (16 px ceiling), or from the scene's integrator.
TEST(RenderRequestTest, MinSpacingAboveMaxSpacingIsRefused) {
  const SceneDesc desc = CornellDesc();
  RenderRequest r;
  r.min_spacing_px = 20;
  r.max_spacing_px = 10;
  absl::StatusOr<RenderSettings> s = SettingsFor(desc, r);
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(s.status().message(), "min_spacing (20 px) must not exceed max_spacing (10 px)");
  r.max_spacing_px = 0;  // the default ceiling
  r.min_spacing_px = 1000;
  EXPECT_EQ(SettingsFor(desc, r).status().code(), absl::StatusCode::kInvalidArgument);
  r.min_spacing_px = 10;
  r.max_spacing_px = 10;
  EXPECT_TRUE(SettingsFor(desc, r).ok());
  SceneDesc scene = desc;
  scene.integrator.type = "irrcache";
  scene.integrator.params = {{"min_spacing_px", "20"}};
  s = SettingsForScene(scene, "irrcache");
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.status().message().find("min_spacing_px (20) must not exceed max_spacing_px (16)"),
            std::string::npos)
      << s.status();
}

// A scene's own irrcache counts are bounded as the flags are: record_rays 1e300 was cast to int
// (undefined), light_samples 3e9 overflowed spp x light samples.
TEST(RenderRequestTest, AScenesIrrcacheCountsAreBounded) {
  SceneDesc scene = CornellDesc();
  scene.integrator.type = "irrcache";
  for (const char* name : {"record_rays", "light_samples", "spp"}) {
    for (const char* value : {"1e300", "3e9", "1048577"}) {
      scene.integrator.params = {{name, value}};
      const absl::StatusOr<RenderSettings> s = SettingsForScene(scene, "irrcache");
      EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument) << name << " " << value;
      EXPECT_NE(s.status().message().find("up to 1048576"), std::string::npos) << s.status();
    }
    scene.integrator.params = {{name, "1048576"}};
    EXPECT_TRUE(SettingsForScene(scene, "irrcache").ok()) << name;
  }
}

TEST(RenderRequestTest, AnEmptyRequestIsTheScenesDefaults) {
  const SceneDesc desc = CornellDesc();
  const absl::StatusOr<RenderSettings> s = SettingsFor(desc, RenderRequest{});
  ASSERT_TRUE(s.ok()) << s.status();
  const RenderSettings d = *SettingsForScene(desc, "irrcache");
  EXPECT_EQ(s->integrator, "irrcache");
  EXPECT_EQ(s->spp, d.spp);
  EXPECT_EQ(s->irrcache.accuracy, d.irrcache.accuracy);
  EXPECT_EQ(s->irrcache.record_rays, d.irrcache.record_rays);
  EXPECT_TRUE(s->irrcache.balance_record_rays);
  EXPECT_TRUE(s->irrcache.choose_cache_levels);
  EXPECT_EQ(s->adaptive, d.adaptive);
  EXPECT_TRUE(s->splat);
  EXPECT_FALSE(s->aovs);
  EXPECT_TRUE(s->choose_integrator);  // no integrator named
}

TEST(RenderRequestTest, RequestedValuesReachTheSettings) {
  const SceneDesc desc = CornellDesc();
  RenderRequest r;
  r.integrator = "irrcache";
  r.spp = 12;
  r.accuracy = 0.3f;
  r.record_rays = 200;
  r.cache_levels = 2;
  r.spacing = "split-sphere";
  r.interpolation = "ward";
  r.light_sampling = "one";
  r.target_error = 1e-3;
  r.denoise = true;
  r.seed = 9;
  const absl::StatusOr<RenderSettings> s = SettingsFor(desc, r);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->spp, 12);
  EXPECT_FLOAT_EQ(s->irrcache.accuracy, 0.3f);
  EXPECT_EQ(s->irrcache.record_rays, 200);
  EXPECT_FALSE(s->irrcache.balance_record_rays);  // the user's rays, as asked
  EXPECT_EQ(s->irrcache.cache_levels, 2);
  EXPECT_FALSE(s->irrcache.choose_cache_levels);
  EXPECT_EQ(s->irrcache.spacing, RecordSpacing::kSplitSphere);
  EXPECT_FALSE(s->irrcache.linear_fit);
  EXPECT_FALSE(s->irrcache.path.all_lights);
  EXPECT_DOUBLE_EQ(s->target_error, 1e-3);
  EXPECT_TRUE(s->adaptive);  // a target error samples adaptively
  EXPECT_TRUE(s->denoise);
  EXPECT_TRUE(s->aovs);    // the denoiser's guides
  EXPECT_FALSE(s->splat);  // each sample in its own pixel for the denoiser
  EXPECT_FALSE(s->choose_integrator);
  EXPECT_EQ(s->seed, 9u);
}

// The pipeline stops at the first failing step, with that step's error: the scene's file:line
// before the request's values, the request's before the (costlier) build.
TEST(RenderRequestTest, PrepareRenderReportsTheFirstFailingStep) {
  RenderRequest bad;
  bad.cache_levels = 7;
  const std::string missing = std::string(IRFARM_TEST_DATA) + "/scenes/none/scene.xml";
  EXPECT_EQ(PrepareRender(missing, {}, bad).status().code(), absl::StatusCode::kNotFound);
  const absl::StatusOr<PreparedRender> p = PrepareRender(TestScenePath("cornell-box"), {}, bad);
  EXPECT_EQ(p.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(p.status().message().find("cache_levels"), std::string::npos) << p.status();
  const absl::StatusOr<PreparedRender> good =
      PrepareRender(TestScenePath("cornell-box"), {}, RenderRequest{});
  ASSERT_TRUE(good.ok()) << good.status();
  EXPECT_NE(good->scene, nullptr);
  EXPECT_EQ(good->settings.integrator, "irrcache");
  EXPECT_EQ(good->load_time.name, "load");
  EXPECT_EQ(good->build_time.name, "build");
}

}  // namespace
}  // namespace irfarm
