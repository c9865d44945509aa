// Adaptive sampling of the final pass (FinalPass in render/final_pass.cc): without a target error
// the samples have a budget, --spp per pixel on average in counted work (irrcache's default
// kIrrcacheSpp), and go where they remove the most error per unit of work, up to max_spp in one
// pixel.
#include <gtest/gtest.h>

#include "render/image.h"
#include "render/renderer.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

// Rays traced and cache queries of the final pass's samples (the records they made left out).
double SampleWork(const RenderStats& st) {
  return double(st.counters.Work() - st.counters.record_work);
}

RenderOutput RenderMaterials(bool adaptive, double carry = 0) {
  static const LoadedScene s = LoadQuarter("materials");
  RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
  settings.seed = 3;
  settings.threads = 2;
  // The default rays, not the pilot's (it times records against samples: the same rays for both).
  settings.irrcache.balance_record_rays = false;
  settings.adaptive = adaptive;
  settings.budget_carry = carry;
  return Render(*s.scene, settings);
}

// materials: its error is the frosted and smooth glass spheres' and the metals' path-traced
// chains, a fifth of the image; the walls converge at their first 16 samples. At the same
// budget the adaptive image moves the samples there: at quarter size 1.07e-3 against 2.36e-3
// uniform at 48 spp (seed 3), in 0.96x the work. Before the budget, the rounds doubled every pixel
// while the estimate was above the goal, up to spp: the uniform image.
TEST(AdaptiveSamplingTest, BudgetGoesWhereTheErrorIs) {
  const Image ref = QuarterReference("materials");
  const RenderOutput uniform = RenderMaterials(false);
  const RenderOutput adaptive = RenderMaterials(true);
  EXPECT_EQ(uniform.stats.spp_max, kIrrcacheSpp);
  EXPECT_EQ(adaptive.stats.spp_min, 16);            // pixels that stopped at their first samples
  EXPECT_GT(adaptive.stats.spp_max, kIrrcacheSpp);  // and pixels that got more than the average
  EXPECT_GT(adaptive.stats.pixels_stopped_early, 0);
  const double work_ratio = SampleWork(adaptive.stats) / SampleWork(uniform.stats);
  const double uniform_err = CompareImages(uniform.image, ref).relmse;
  const double adaptive_err = CompareImages(adaptive.image, ref).relmse;
  RecordProperty("work_ratio", std::to_string(work_ratio));
  RecordProperty("uniform_relmse", std::to_string(uniform_err));
  RecordProperty("adaptive_relmse", std::to_string(adaptive_err));
  // The budget is estimated from each pixel's first samples' cost: within 10%.
  EXPECT_LT(work_ratio, 1.1);
  // Below the uniform image's error by more than the reference's own error.
  EXPECT_LT(adaptive_err + ReferenceError("materials"), uniform_err);
  EXPECT_EQ(adaptive.stats.nonfinite_pixels, 0);
}

// An image whose estimate reaches the goal (--sampling-error) stops there, under its budget.
TEST(AdaptiveSamplingTest, EasyImageStopsAtTheGoalBelowItsBudget) {
  const LoadedScene s = LoadQuarter("cornell-box");
  RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
  settings.seed = 3;
  ASSERT_TRUE(settings.adaptive);
  const RenderOutput out = Render(*s.scene, settings);
  EXPECT_LE(out.stats.estimated_sampling_relmse, settings.sampling_error);
  EXPECT_LT(out.stats.spp_mean, 0.75 * settings.spp);
  EXPECT_GT(out.stats.pixels_stopped_early, 0);
}

// A worker passes what its tiles left unspent to its next tile (RenderSettings::budget_carry):
// an image that stops at the goal gives the carry back whole, plus its own unspent budget; one
// whose budget binds spends at most as much again as its own and gives back the rest.
TEST(AdaptiveSamplingTest, CarriedBudgetIsSpentWhereItBindsAndGivenBackWhereNot) {
  const LoadedScene s = LoadQuarter("cornell-box");
  RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
  settings.seed = 3;
  const RenderOutput easy = Render(*s.scene, settings);
  EXPECT_GT(easy.stats.budget_left, 0);  // stopped at the goal
  constexpr double kCarry = 1e12;
  settings.budget_carry = kCarry;
  const RenderOutput easy_carry = Render(*s.scene, settings);
  EXPECT_GT(easy_carry.stats.budget_left, kCarry);
  EXPECT_NEAR(easy_carry.stats.spp_mean, easy.stats.spp_mean, 0.25 * easy.stats.spp_mean);

  const Image ref = QuarterReference("materials");
  const RenderOutput own = RenderMaterials(true);
  const RenderOutput carried = RenderMaterials(true, kCarry);
  RecordProperty("own_spp_mean", std::to_string(own.stats.spp_mean));
  RecordProperty("carried_spp_mean", std::to_string(carried.stats.spp_mean));
  EXPECT_GT(carried.stats.spp_mean, 1.4 * own.stats.spp_mean);
  EXPECT_LT(carried.stats.spp_mean, 2.2 * own.stats.spp_mean);  // at most twice its own work
  EXPECT_GT(carried.stats.budget_left, 0.99 * kCarry);
  EXPECT_LT(CompareImages(carried.image, ref).relmse, CompareImages(own.image, ref).relmse);
}

}  // namespace
}  // namespace irfarm
