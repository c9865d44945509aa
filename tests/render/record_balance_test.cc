// Tests of render/record_balance.h: the rays the error x time model picks from pilot figures
// (closed form, clamps, degenerate pilots), and the pilot in a real render: its figures reach
// the stats, its records stay out of the render's cache, a warm cache turns it off.
#include "render/record_balance.h"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

// 100 pilot pixels of which `with_record` have a record; each record's noise N (relMSE), a
// validity area of 1/`per_px` pixels; each pixel's sampling error S1 at one sample.
PilotFigures Pilot(int with_record, double noise, double per_px, double s1, double record_s,
                   double sample_s) {
  PilotFigures p;
  p.samples = 16;
  for (int i = 0; i < 100; ++i) {
    PilotPixel px;
    px.has_record = i < with_record;
    px.record_noise = px.has_record ? noise : 0;
    px.records_per_px = px.has_record ? per_px : 0;
    px.sampling_error = s1 / p.samples;
    p.pixels.push_back(px);
  }
  p.records = with_record;
  p.record_seconds = record_s * with_record;
  p.sample_count = 100L * p.samples;
  p.sample_seconds = sample_s * double(p.sample_count);
  return p;
}

TEST(RecordBalanceTest, ClosedFormWhenSamplesDominate) {
  // Expensive records, small record noise, noisy samples: fewer rays.
  const PilotFigures p = Pilot(100, 1e-4, 1e-3, 0.64, 4e-3, 5e-6);
  BalanceInputs in;
  in.image_pixels = 1e5;
  in.max_spp = 64;
  in.sampling_goal = 1e-4;
  const BalanceResult r = ChooseRecordRays(p, in);
  // S1 = 0.64 needs 6400 spp for the goal: max_spp, S = 0.01.
  EXPECT_DOUBLE_EQ(r.expected_spp, 64);
  EXPECT_NEAR(r.sampling_error, 0.01, 1e-12);
  const double c = kRecordOverlap * 1e-3 * 1e5 * 4e-3, d = 64 * 1e5 * 5e-6;
  EXPECT_NEAR(r.record_seconds, c, 1e-9);
  EXPECT_NEAR(r.sampling_seconds, d, 1e-9);
  const double expect = 1536 * std::sqrt(1e-4 / (kInterpolationFloor * 1e-4 + 0.01) * d / c);
  ASSERT_GT(expect, 1536 / 8.0);  // inside the clamp, so the closed form is what comes out
  EXPECT_EQ(r.record_rays, int(std::lround(expect)));
}

TEST(RecordBalanceTest, KeepsTheRaysWhenRecordsDominate) {
  // Cheap records whose noise is most of the error: the model wants more than R0; R0 it stays.
  const PilotFigures p = Pilot(100, 1e-3, 1e-4, 1e-4, 1e-4, 1e-4);
  BalanceInputs in;
  in.image_pixels = 1e5;
  EXPECT_EQ(ChooseRecordRays(p, in).record_rays, 1536);
}

TEST(RecordBalanceTest, NoiselessSamplesDoNotDecideAlone) {
  // Samples with no error (direct light from rectangles, nothing in penumbra): with I = 0 the
  // model would want rays without end; the interpolation error the cache keeps at any rays bounds
  // them at R0 sqrt(D / (kInterpolationFloor C)).
  const PilotFigures p = Pilot(100, 1e-4, 1e-3, 0.0, 0.1, 5e-6);
  BalanceInputs in;
  in.image_pixels = 1e5;
  in.max_spp = 64;
  in.min_spp = 16;
  const BalanceResult r = ChooseRecordRays(p, in);
  EXPECT_EQ(r.sampling_error, 0);
  const double expect =
      1536 * std::sqrt(r.sampling_seconds / (kInterpolationFloor * r.record_seconds));
  ASSERT_GT(expect, 1536 / 8.0);
  ASSERT_LT(expect, 1536);
  EXPECT_EQ(r.record_rays, int(std::lround(expect)));
}

TEST(RecordBalanceTest, NeverBelowAnEighth) {
  const PilotFigures p = Pilot(100, 1e-8, 1.0, 10.0, 1.0, 1e-9);
  BalanceInputs in;
  in.image_pixels = 1e5;
  EXPECT_EQ(ChooseRecordRays(p, in).record_rays, 192);
}

TEST(RecordBalanceTest, FewerRaysAsRecordsGetDearer) {
  BalanceInputs in;
  in.image_pixels = 1e5;
  int last = 1 << 30;
  for (double record_s : {1e-4, 1e-3, 3e-3, 1e-2}) {
    const int rays = ChooseRecordRays(Pilot(100, 1e-4, 1e-3, 0.64, record_s, 5e-6), in).record_rays;
    EXPECT_LE(rays, last) << record_s;
    last = rays;
  }
  EXPECT_LT(last, 1536);
}

TEST(RecordBalanceTest, NothingToBalance) {
  BalanceInputs in;
  in.image_pixels = 1e5;
  EXPECT_EQ(ChooseRecordRays(PilotFigures{}, in).record_rays, 1536);  // no pilot
  // No diffuse surface in sight: no record, nothing to trade.
  EXPECT_EQ(ChooseRecordRays(Pilot(0, 0, 0, 0.5, 0, 1e-6), in).record_rays, 1536);
}

// The pilots' figures as the renderer measured them (seed 7, forced one and two levels, full
// size; docs/bench/cache-levels-model-2026-12-05): the choice of levels from them.
BalanceResult Figures(int rays, double noise, double sampling, double record_s, double sample_s) {
  BalanceResult b;
  b.record_rays = rays;
  b.record_noise = noise;
  b.sampling_error = sampling;
  b.record_seconds = record_s;
  b.sampling_seconds = sample_s;
  return b;
}

TEST(RecordBalanceTest, TwoLevelsWhereThePilotsPredictThemCheaper) {
  // veach-ajar: the records' noise is the error (light through a door gap); two levels measured
  // 0.35x in error x time.
  const BalanceResult veach1 = Figures(447, 2.22e-2, 7.7e-5, 9.73, 0.414);
  const BalanceResult veach2 = Figures(322, 1.60e-3, 1.0e-4, 17.3, 0.428);
  EXPECT_TRUE(MayPreferTwoLevels(veach1));
  EXPECT_TRUE(TwoLevelsPay(veach1, veach2, 1536));
  // A room lit through a window (make_room 602) whose records' noise is only 1.2x the samples'
  // error, which the ratio of 1.5 alone left at one level: two levels measured 0.70x.
  const BalanceResult room1 = Figures(927, 1.91e-3, 1.60e-3, 12.7, 6.20);
  const BalanceResult room2 = Figures(808, 9.37e-4, 1.58e-3, 9.74, 5.89);
  EXPECT_FALSE(PrefersTwoLevels(room1));
  EXPECT_TRUE(MayPreferTwoLevels(room1));
  EXPECT_TRUE(TwoLevelsPay(room1, room2, 1536));
  // layered_kitchen: N/S 2.5, but the second level's records (15,000 secondary for 8,000) cost
  // more than they save; two levels measured 1.62x.
  const BalanceResult kitchen1 = Figures(720, 4.72e-3, 1.91e-3, 8.88, 1.77);
  const BalanceResult kitchen2 = Figures(352, 2.96e-3, 1.24e-3, 41.9, 2.02);
  EXPECT_TRUE(PrefersTwoLevels(kitchen1));
  EXPECT_FALSE(TwoLevelsPay(kitchen1, kitchen2, 1536));
  // The same figures with the second level's records as cheap as the first level's: two pay.
  EXPECT_TRUE(TwoLevelsPay(kitchen1, Figures(352, 2.96e-3, 1.24e-3, 8.88, 2.02), 1536));
  // living-room (N/S 0.57): a second pilot runs since the gate went to 0.5, and its cost stops it
  // (ADearTwoLevelPilotStopsAndKeepsOneLevel).
  EXPECT_TRUE(MayPreferTwoLevels(Figures(424, 4.09e-3, 7.18e-3, 68.5, 11.8)));
  // make_room 962 (glass and rough plastic; N/S 0.27): the samples' error dominates; no second
  // pilot.
  EXPECT_FALSE(MayPreferTwoLevels(Figures(395, 1.85e-4, 6.84e-4, 17.0, 4.74)));
  // A pilot that measured nothing never decides for two levels.
  EXPECT_FALSE(TwoLevelsPay(veach1, BalanceResult{}, 1536));
  EXPECT_FALSE(TwoLevelsPay(BalanceResult{}, veach2, 1536));
}

// Path instead of the cache for a denoised image (ChooseForDenoising): the pilots' figures as the
// renderer measured them with --denoise (full size, seed 10 and seed 2). living-room ((P - S) /
// (I + N R0 / R) 0.49-1.48 over seeds 1-10) is rendered by path, which with the denoiser measured
// 7.4e-3 to 8.4e-3 in 27-38 CPU seconds against the cache's 1.27e-2 to 1.40e-2 in 26-29;
// materials (3.9-7.6) keeps the cache, which measured 6.4e-4 to 6.7e-4 against path's 8.1e-4 to
// 8.4e-4.
TEST(RecordBalanceTest, PathForADenoisedImageWhereTheCachesOwnErrorWouldStay) {
  constexpr double kLivingPixels = 320.0 * 180.0, kMaterialsPixels = 256.0 * 192.0;
  const BalanceResult living = Figures(394, 4.06e-3, 8.34e-3, 66.3, 11.2);
  PathPilotFigures living_path;
  living_path.per_sample_error = 4.36;
  living_path.seconds_per_sample = 3.25e-6;
  const DenoisedChoice l = ChooseForDenoising(living, 1536, living_path, kLivingPixels);
  EXPECT_NEAR(l.cache_seconds, 66.3 * 394 / 1536 + 11.2, 1e-9);
  EXPECT_NEAR(l.cache_own, 4.06e-3 * (kInterpolationFloor + 1536.0 / 394), 1e-12);
  EXPECT_DOUBLE_EQ(l.cache_sampling, 8.34e-3);
  EXPECT_NEAR(l.path, 4.36 * 3.25e-6 * kLivingPixels / l.cache_seconds, 1e-12);
  EXPECT_TRUE(l.path_pays);
  EXPECT_LT((l.path - l.cache_sampling) / l.cache_own, 1.5);

  const BalanceResult materials = Figures(959, 1.56e-4, 2.41e-4, 6.48, 5.16);
  PathPilotFigures materials_path;
  materials_path.per_sample_error = 0.189;
  materials_path.seconds_per_sample = 1.72e-6;
  const DenoisedChoice m = ChooseForDenoising(materials, 1536, materials_path, kMaterialsPixels);
  EXPECT_FALSE(m.path_pays);
  EXPECT_GT((m.path - m.cache_sampling) / m.cache_own, 3.5);

  // The boundary: P - S just under and just over kDenoiserGain (I + N R0 / R).
  PathPilotFigures edge = materials_path;
  const double p_edge = m.cache_sampling + kDenoiserGain * m.cache_own;
  edge.per_sample_error = 0.99 * p_edge * m.cache_seconds / (1.72e-6 * kMaterialsPixels);
  EXPECT_TRUE(ChooseForDenoising(materials, 1536, edge, kMaterialsPixels).path_pays);
  edge.per_sample_error *= 1.02;
  EXPECT_FALSE(ChooseForDenoising(materials, 1536, edge, kMaterialsPixels).path_pays);
  // Nor for an image smaller than kPathChoiceMinPixels (living-room at a quarter of its size,
  // with the same figures per pixel).
  EXPECT_FALSE(ChooseForDenoising(living, 1536, living_path, kLivingPixels / 16).path_pays);
  EXPECT_TRUE(ChooseForDenoising(living, 1536, living_path, kLivingPixels / 16, 0).path_pays);
  // A pilot that measured nothing never decides for path.
  EXPECT_FALSE(ChooseForDenoising(BalanceResult{}, 1536, living_path, kLivingPixels).path_pays);
  EXPECT_FALSE(ChooseForDenoising(living, 1536, PathPilotFigures{}, kLivingPixels).path_pays);

  // The samples that take a given thread time, within the bounds.
  EXPECT_EQ(PathSppForSeconds(l.cache_seconds, living_path, kLivingPixels, 16, 768),
            int(std::lround(l.cache_seconds / (3.25e-6 * kLivingPixels))));
  EXPECT_EQ(PathSppForSeconds(l.cache_seconds, living_path, kLivingPixels, 16, 64), 64);
  EXPECT_EQ(PathSppForSeconds(1e-3, living_path, kLivingPixels, 16, 768), 16);
  EXPECT_EQ(PathSppForSeconds(10, PathPilotFigures{}, kLivingPixels, 16, 768), 16);
}

// The trimmed mean leaves out the largest kTrimmed of the values (fireflies), at least one kept.
TEST(RecordBalanceTest, TrimmedMeanLeavesOutTheLargest) {
  EXPECT_EQ(TrimmedMean({}), 0);
  EXPECT_EQ(TrimmedMean({5}), 5);
  std::vector<double> v(100, 1.0);
  v[17] = 1e6;
  v[60] = 1e6;  // 2 of 100: both left out
  EXPECT_DOUBLE_EQ(TrimmedMean(v), 1.0);
  v[3] = 1e6;  // a third one stays in
  EXPECT_DOUBLE_EQ(TrimmedMean(v), (97.0 + 1e6) / 98.0);
}

// A denoised render at default settings with its integrator left to it
// (RenderSettings::choose_integrator) runs the path pilot, and renders with what
// ChooseForDenoising chose from the figures in its stats: by path at PathSppForSeconds' samples,
// not adaptive, with no records; or with the cache. The scenes are a quarter of their size, below
// kPathChoiceMinPixels, which is lowered to 0 here: materials (glass and metal spheres, whose
// camera samples are the error; (P - S) / (I + N R0 / R) 0.6-1.8 over seeds 1-6) goes to path on
// at least one of three seeds; cornell-box (above 25) never. At the default limit neither does;
// named, the integrator is kept and no path pilot runs.
TEST(RecordBalanceTest, ADenoisedRenderChoosesItsIntegrator) {
  for (const std::string name : {"materials", "cornell-box"}) {
    SCOPED_TRACE(name);
    const LoadedScene s = LoadQuarter(name);
    const double pixels = double(s.scene->camera().width()) * s.scene->camera().height();
    ASSERT_LT(pixels, kPathChoiceMinPixels);
    RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
    settings.denoise = true;
    settings.splat = false;
    settings.choose_integrator = true;
    settings.choose_integrator_min_pixels = 0;
    int paths = 0;
    for (uint64_t seed = 1; seed <= 3; ++seed) {
      settings.seed = seed;
      const RenderOutput out = Render(*s.scene, settings);
      ASSERT_TRUE(out.stats.balanced);
      ASSERT_TRUE(out.stats.integrator_chosen);
      const PathPilotFigures& path = out.stats.path_pilot;
      EXPECT_GT(path.per_sample_error, 0);
      EXPECT_GT(path.seconds_per_sample, 0);
      const DenoisedChoice c =
          ChooseForDenoising(out.stats.balance, settings.irrcache.record_rays, path, pixels, 0);
      EXPECT_DOUBLE_EQ(out.stats.denoised_choice.path, c.path);
      EXPECT_EQ(out.stats.denoised_choice.path_pays, c.path_pays);
      EXPECT_EQ(out.stats.integrator, c.path_pays ? "path" : "irrcache")
          << "P " << c.path << " S " << c.cache_sampling << " I + N " << c.cache_own;
      if (c.path_pays) {
        ++paths;
        EXPECT_EQ(out.stats.spp, PathSppForSeconds(c.cache_seconds, path, pixels, settings.min_spp,
                                                   kMaxSppFactor * settings.spp));
        EXPECT_EQ(out.stats.counters.records_computed, 0u);
        EXPECT_EQ(out.stats.spp_min, out.stats.spp);  // not adaptive: every pixel its spp
        EXPECT_EQ(out.stats.spp_max, out.stats.spp);
      } else {
        EXPECT_GT(out.stats.counters.records_computed, 0u);
      }
    }
    if (name == "materials")
      EXPECT_GE(paths, 1);
    else
      EXPECT_EQ(paths, 0);

    RenderSettings limited = settings;
    limited.seed = 1;
    limited.choose_integrator_min_pixels = kPathChoiceMinPixels;
    const RenderOutput small = Render(*s.scene, limited);
    EXPECT_TRUE(small.stats.integrator_chosen);
    EXPECT_FALSE(small.stats.denoised_choice.path_pays);
    EXPECT_EQ(small.stats.integrator, "irrcache");

    RenderSettings named = settings;
    named.choose_integrator = false;
    const RenderOutput kept = Render(*s.scene, named);
    EXPECT_FALSE(kept.stats.integrator_chosen);
    EXPECT_EQ(kept.stats.integrator, "irrcache");
  }
}

TEST(RecordBalanceTest, PilotInARealRender) {
  const LoadedScene s = LoadQuarter("cornell-box");
  RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
  settings.seed = 3;
  ASSERT_TRUE(settings.irrcache.balance_record_rays);
  const RenderOutput out = Render(*s.scene, settings);
  ASSERT_TRUE(out.stats.balanced);
  // The stats give the rays the strata make (T x P) for the count chosen.
  IrrcacheSettings chosen = settings.irrcache;
  chosen.record_rays = out.stats.balance.record_rays;
  IrradianceCache scratch(CacheSettingsFor(*s.scene, settings));
  const IrrcacheIntegrator strata(*s.scene, &scratch, chosen);
  EXPECT_EQ(out.stats.record_rays, strata.strata_theta() * strata.strata_phi());
  EXPECT_GE(out.stats.record_rays, 192);
  EXPECT_LE(out.stats.record_rays, 1536);
  EXPECT_GT(out.stats.balance.record_noise, 0);
  EXPECT_GT(out.stats.balance.sampling_seconds, 0);
  EXPECT_GT(out.stats.PhaseWall("pilot"), 0);
  EXPECT_GT(out.stats.balance.pilot_records, 64);  // most pilot pixels see a diffuse wall
  EXPECT_EQ(out.stats.records_in_cache, out.stats.counters.records_computed);  // none kept

  // BalancedSettings keeps the pilot apart from `cache` (its records stay out of the render's
  // cache) and turns the balance off; a cache that holds records already (a snapshot, the
  // service's) keeps the settings as they are.
  IrradianceCache cache(CacheSettingsFor(*s.scene, settings));
  BalanceResult b;
  const RenderSettings balanced = BalancedSettings(*s.scene, settings, &cache, &b);
  EXPECT_FALSE(balanced.irrcache.balance_record_rays);
  EXPECT_EQ(balanced.irrcache.record_rays, b.record_rays);
  EXPECT_EQ(cache.size(), 0u);
  RenderSettings fixed = settings;
  fixed.irrcache.balance_record_rays = false;
  const RenderOutput first = Render(*s.scene, fixed, &cache);
  EXPECT_FALSE(first.stats.balanced);
  ASSERT_GT(cache.size(), 0u);
  const RenderSettings again = BalancedSettings(*s.scene, settings, &cache);
  EXPECT_TRUE(again.irrcache.balance_record_rays);
  EXPECT_EQ(again.irrcache.record_rays, settings.irrcache.record_rays);
  const RenderOutput warm = Render(*s.scene, settings, &cache);
  EXPECT_FALSE(warm.stats.balanced);
  const IrrcacheIntegrator full(*s.scene, &scratch, settings.irrcache);
  EXPECT_EQ(warm.stats.record_rays, full.strata_theta() * full.strata_phi());
}

// Cache levels at default settings (MayPreferTwoLevels, then TwoLevelsPay, then ThreeLevelsPay):
// veach-ajar, whose error is its records' noise (the light found through the door gap by few of a
// record's rays), gets more than one level and is the better for it (quarter size, seeds 3 and 4:
// relMSE 7.3e-3 and 9.0e-3 at two levels against 2.4e-2 and 2.5e-2 at one level), and a third
// since most of its secondary records are one ray's light; materials, whose error is its glass
// and metal spheres' camera samples, keeps one.
TEST(RecordBalanceTest, ThePilotChoosesTheCacheLevels) {
  const LoadedScene veach = LoadQuarter("veach-ajar");
  const Image ref = QuarterReference("veach-ajar");
  RenderSettings settings = *SettingsForScene(veach.desc, "irrcache");
  ASSERT_TRUE(settings.irrcache.choose_cache_levels);
  const RenderOutput chosen = RenderWith(veach, "irrcache", 0, 3);
  ASSERT_TRUE(chosen.stats.balanced);
  EXPECT_EQ(chosen.stats.balance.cache_levels, 3);
  EXPECT_EQ(chosen.stats.cache_levels, 3);
  EXPECT_GT(chosen.stats.balance.one_level_record_noise,
            kTwoLevelsPilotRatio * chosen.stats.balance.one_level_sampling_error);
  EXPECT_GT(chosen.stats.balance.secondary_heavy_share, kThreeLevelsHeavyShare);
  // With three levels, at least half the settings' rays (ThreeLevelsRecordRays; the model alone
  // chose 325-472 of 1536 on veach-ajar at full size).
  EXPECT_GE(chosen.stats.balance.record_rays, settings.irrcache.record_rays / 2);
  RecordProperty("veach_three_levels_rays", std::to_string(chosen.stats.balance.record_rays));
  // The images at the levels chosen and at one level, both at the default rays: the pilot's rays
  // follow measured times, and under load they varied the two-level image 0.006 to 0.017 (one
  // level: 0.024 every time), which is not what this test is about.
  settings.seed = 3;
  settings.irrcache.choose_cache_levels = false;
  settings.irrcache.balance_record_rays = false;
  const RenderOutput single = Render(*veach.scene, settings);
  EXPECT_EQ(single.stats.cache_levels, 1);
  settings.irrcache.cache_levels = 2;
  const RenderOutput two = Render(*veach.scene, settings);
  EXPECT_EQ(two.stats.cache_levels, 2);
  const double two_levels = CompareImages(two.image, ref).relmse;
  const double one_level = CompareImages(single.image, ref).relmse;
  RecordProperty("veach_two_levels", std::to_string(two_levels));
  RecordProperty("veach_one_level", std::to_string(one_level));
  EXPECT_LT(two_levels, one_level / 2);

  const RenderOutput kept = RenderWith(LoadQuarter("materials"), "irrcache", 0, 3);
  ASSERT_TRUE(kept.stats.balanced);
  EXPECT_EQ(kept.stats.balance.cache_levels, 1);
  EXPECT_EQ(kept.stats.cache_levels, 1);

  // room-b's two levels stay two: its secondary records are each many rays' light.
  const RenderOutput room = RenderWith(LoadQuarter("room-b"), "irrcache", 0, 3);
  ASSERT_TRUE(room.stats.balanced);
  EXPECT_EQ(room.stats.balance.cache_levels, 2);
  EXPECT_GE(room.stats.balance.secondary_heavy_share, 0.0);
  EXPECT_LT(room.stats.balance.secondary_heavy_share, kThreeLevelsHeavyShare);
}

// The two-level pilot stops at its time cap (IrrcacheSettings::two_level_pilot_cost_cap, a
// multiple of the one-level pilot's thread time) and one level is kept: room-b, which takes two
// levels, keeps one when the cap is a hundredth of the one-level pilot's time, and takes two again
// at the default cap, its second pilot uncapped.
TEST(RecordBalanceTest, ADearTwoLevelPilotStopsAndKeepsOneLevel) {
  const LoadedScene room = LoadQuarter("room-b");
  RenderSettings settings = *SettingsForScene(room.desc, "irrcache");
  settings.seed = 3;
  const RenderOutput free = Render(*room.scene, settings);
  ASSERT_TRUE(free.stats.balanced);
  EXPECT_EQ(free.stats.cache_levels, 2);
  EXPECT_FALSE(free.stats.balance.two_level_pilot_capped);
  settings.irrcache.two_level_pilot_cost_cap = 0.01;
  const RenderOutput capped = Render(*room.scene, settings);
  ASSERT_TRUE(capped.stats.balanced);
  EXPECT_TRUE(capped.stats.balance.two_level_pilot_capped);
  EXPECT_EQ(capped.stats.balance.cache_levels, 1);
  EXPECT_EQ(capped.stats.cache_levels, 1);
}

// The rule itself: a quarter of the secondary records made of one ray's light, at the default
// accuracy or finer.
TEST(RecordBalanceTest, ThreeLevelsWhereSecondaryRecordsAreOneRaysLight) {
  EXPECT_TRUE(ThreeLevelsPay(1000, 300, IrrcacheSettings{}.accuracy));  // the default, 0.1
  EXPECT_TRUE(ThreeLevelsPay(1000, 300, 0.05f));
  EXPECT_FALSE(ThreeLevelsPay(1000, 200, 0.1f));  // 20%: the secondary records are many rays'
  EXPECT_FALSE(ThreeLevelsPay(1000, 600, 0.2f));  // coarse accuracy: two levels
  EXPECT_FALSE(ThreeLevelsPay(0, 0, 0.1f));       // no two-level pilot records
}

// A third cache level on veach-ajar against two, at the settings' rays (quarter size, one thread,
// seeds 1-3): the third level's records smooth the second level's, each of which is otherwise
// the light of a few rays through the door gap. Measured when written, seeds 1-8: lower on 7 of
// 8, mean 4.3e-3 against 5.2e-3. The secondary records made of one ray's light are counted
// (RenderCounters::records_secondary_heavy), and fewer are so with the third level.
TEST(RecordBalanceTest, AThirdLevelSmoothsVeachAjarsSecondaryRecords) {
  const LoadedScene veach = LoadQuarter("veach-ajar");
  const Image ref = QuarterReference("veach-ajar");
  double error[2] = {0, 0};
  for (int seed = 1; seed <= 3; ++seed) {
    uint64_t heavy[2], secondary[2];
    for (int levels = 2; levels <= 3; ++levels) {
      RenderSettings settings = *SettingsForScene(veach.desc, "irrcache");
      settings.seed = uint64_t(seed);
      settings.threads = 1;
      settings.irrcache.choose_cache_levels = false;
      settings.irrcache.balance_record_rays = false;
      settings.irrcache.cache_levels = levels;
      const RenderOutput out = Render(*veach.scene, settings);
      EXPECT_EQ(out.stats.cache_levels, levels);
      error[levels - 2] += CompareImages(out.image, ref).relmse / 3;
      heavy[levels - 2] = out.stats.counters.records_secondary_heavy;
      secondary[levels - 2] = out.stats.counters.records_secondary;
    }
    EXPECT_GT(heavy[0], 0u) << seed;
    EXPECT_LT(double(heavy[1]) / double(secondary[1]), double(heavy[0]) / double(secondary[0]))
        << seed;
  }
  RecordProperty("veach_two_levels_mean", std::to_string(error[0]));
  RecordProperty("veach_three_levels_mean", std::to_string(error[1]));
  EXPECT_LT(error[1], error[0]);
}

}  // namespace
}  // namespace irfarm
