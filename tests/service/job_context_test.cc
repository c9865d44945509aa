// A worker's per-job state (worker/job_context.h): the caustic photon map is built once per job,
// and it is the map a single-process render of the same settings builds, so a tile rendered with
// it equals the same rect rendered alone.
#include <gtest/gtest.h>

#include "irfarm/v1/worker.pb.h"
#include "render/image.h"
#include "render/pipeline.h"
#include "render/renderer.h"
#include "service/job_settings.h"
#include "service/scene_bundle.h"
#include "worker/job_context.h"

namespace irfarm {
namespace {

v1::JobSpec Spec(const std::string& scene, bool no_caustics) {
  v1::JobSpec spec;
  spec.set_job_id("job-1");
  absl::StatusOr<v1::SceneBundle> bundle =
      MakeBundle(std::string(IRFARM_TEST_DATA) + "/scenes/" + scene + "/scene.xml");
  EXPECT_TRUE(bundle.ok()) << bundle.status();
  if (bundle.ok()) *spec.mutable_scene()->mutable_bundle() = *bundle;
  (*spec.mutable_settings()->mutable_defines())["resx"] = "48";
  (*spec.mutable_settings()->mutable_defines())["resy"] = "48";
  spec.mutable_settings()->set_spp(4);
  spec.mutable_settings()->set_seed(3);
  spec.mutable_settings()->set_no_caustics(no_caustics);
  return spec;
}

TEST(JobContextTest, CausticMapIsBuiltOncePerJobAsARenderWouldBuildIt) {
  absl::StatusOr<std::unique_ptr<JobContext>> job = JobContext::Create(Spec("specular", false), 1);
  ASSERT_TRUE(job.ok()) << job.status();
  const RenderSettings& s = (*job)->settings();
  ASSERT_NE(s.irrcache.caustics, nullptr);
  EXPECT_GT(s.irrcache.caustics->sites(), 0u);
  const PixelRect rect{8, 16, 40, 40};
  // A tile with the job's map does not build another.
  IrradianceCache tile_cache(CacheSettingsFor((*job)->scene(), s));
  const RenderOutput tile = RenderRect((*job)->scene(), s, &tile_cache, rect);
  EXPECT_EQ(tile.stats.caustic_photons, 0);
  // The same rect rendered alone (one thread: the same records in the same order) builds its
  // own map from the same seed and image size: the same map, so the same image.
  RenderSettings alone_settings = s;
  alone_settings.irrcache.caustics = nullptr;
  IrradianceCache alone_cache(CacheSettingsFor((*job)->scene(), alone_settings));
  const RenderOutput alone = RenderRect((*job)->scene(), alone_settings, &alone_cache, rect);
  EXPECT_GT(alone.stats.caustic_photons, 0);
  EXPECT_EQ(CompareImages(tile.image, alone.image).relmse, 0.0);
  // And the map matters there: without it the rect differs.
  alone_settings.caustics = false;
  IrradianceCache none_cache(CacheSettingsFor((*job)->scene(), alone_settings));
  const RenderOutput none = RenderRect((*job)->scene(), alone_settings, &none_cache, rect);
  EXPECT_GT(CompareImages(tile.image, none.image).relmse, 0.0);
}

TEST(JobContextTest, NoCausticsAndScenesWithoutCausticsHaveNoMap) {
  absl::StatusOr<std::unique_ptr<JobContext>> off = JobContext::Create(Spec("specular", true), 1);
  ASSERT_TRUE(off.ok()) << off.status();
  EXPECT_EQ((*off)->settings().irrcache.caustics, nullptr);
  EXPECT_FALSE((*off)->settings().caustics);
  absl::StatusOr<std::unique_ptr<JobContext>> cornell =
      JobContext::Create(Spec("cornell-box", false), 1);
  ASSERT_TRUE(cornell.ok()) << cornell.status();
  EXPECT_EQ((*cornell)->settings().irrcache.caustics, nullptr);
}

// A job's wire settings go through the renderer's one validation (render/render_request.h): a
// bad value is refused with the message `irfarm render` prints for the same value, and good ones
// give the settings the command would render with.
TEST(JobContextTest, JobSettingsAreValidatedAndAppliedAsTheCommandsAre) {
  v1::JobSpec bad = Spec("cornell-box", false);
  bad.mutable_settings()->set_accuracy(3);
  const absl::StatusOr<std::unique_ptr<JobContext>> refused = JobContext::Create(bad, 1);
  RenderRequest same;
  same.accuracy = 3;
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(refused.status().message(), ValidateRequest(same).message());
  EXPECT_EQ(refused.status().message(), "accuracy must be in (0, 1], got 3");

  v1::JobSpec good = Spec("cornell-box", false);
  good.mutable_settings()->set_accuracy(0.25f);
  good.mutable_settings()->set_record_rays(300);
  good.mutable_settings()->set_target_error(2e-3);
  const absl::StatusOr<std::unique_ptr<JobContext>> job = JobContext::Create(good, 1);
  ASSERT_TRUE(job.ok()) << job.status();
  LoadOptions load;
  load.defines = {{"resx", "48"}, {"resy", "48"}};
  RenderRequest cli;  // irfarm render --spp 4 --seed 3 --accuracy 0.25 --record-rays 300 ...
  cli.spp = 4;
  cli.seed = 3;
  cli.threads = 1;
  cli.accuracy = 0.25f;
  cli.record_rays = 300;
  cli.target_error = 2e-3;
  const absl::StatusOr<PreparedRender> local =
      PrepareRender(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml", load, cli);
  ASSERT_TRUE(local.ok()) << local.status();
  const RenderSettings &a = (*job)->settings(), &b = local->settings;
  EXPECT_EQ(a.integrator, b.integrator);
  EXPECT_EQ(a.spp, b.spp);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.irrcache.accuracy, b.irrcache.accuracy);
  EXPECT_EQ(a.irrcache.record_rays, b.irrcache.record_rays);
  EXPECT_EQ(a.irrcache.balance_record_rays, b.irrcache.balance_record_rays);
  EXPECT_EQ(a.target_error, b.target_error);
  EXPECT_EQ(a.adaptive, b.adaptive);
  EXPECT_EQ(a.splat, b.splat);
  EXPECT_EQ(a.tile_size, kJobSubTileSize);  // the job's own: sub-tiles of its tiles
}

// Records from the coordinator are held to the scene's bounds, as the coordinator holds them:
// one with R = 1e30 (it would shade every lookup), one far outside the scene and one brighter
// than the scene's emitters allow are dropped and counted; a plausible one is inserted.
TEST(JobContextTest, RemoteRecordsOutsideTheScenesBoundsAreDropped) {
  absl::StatusOr<std::unique_ptr<JobContext>> job =
      JobContext::Create(Spec("cornell-box", true), 1);
  ASSERT_TRUE(job.ok()) << job.status();
  IrradianceRecord good;
  good.position = Vec3(0, 0, 0);
  good.normal = Vec3(0, 1, 0);
  good.irradiance = Vec3(0.5f);
  good.radius = 0.2f;
  good.origin = 7;
  IrradianceRecord wide = good, far = good, bright = good;
  wide.radius = 1e30f;
  far.position = Vec3(1e6f, 0, 0);
  bright.irradiance = Vec3(3e38f);
  EXPECT_EQ((*job)->InsertRemote({good, wide, far, bright}), 1u);
  EXPECT_EQ((*job)->rejected(), 3u);
  EXPECT_EQ((*job)->cache()->size(), 1u);
}

// The publisher takes the worker's own camera records, oldest first, each once, in batches of at
// most `max`: not the records other workers sent, not the secondary ones (they stay local), and
// records made while earlier ones wait in a batch come after them.
TEST(JobContextTest, NewOwnRecordsAreTakenOnceOldestFirst) {
  absl::StatusOr<std::unique_ptr<JobContext>> job =
      JobContext::Create(Spec("cornell-box", true), 1);
  ASSERT_TRUE(job.ok()) << job.status();
  IrradianceCache* cache = (*job)->cache();
  const auto record = [](int tag, uint32_t origin, int level) {
    IrradianceRecord r;
    r.position = Vec3(0.01f * float(tag % 50), 0, 0);
    r.normal = Vec3(0, 1, 0);
    r.irradiance = Vec3(float(tag));  // the tag
    r.radius = 0.2f;
    r.origin = origin;
    r.level = uint8_t(level);
    return r;
  };
  const auto tags = [](const std::vector<IrradianceRecord>& rs) {
    std::vector<int> out;
    for (const IrradianceRecord& r : rs) out.push_back(int(r.irradiance.x));
    return out;
  };
  EXPECT_TRUE((*job)->TakeNewOwnRecords(10).empty());
  for (int i = 1; i <= 5; ++i) cache->Insert(record(i, 0, 0));
  cache->Insert(record(100, 0, 1));                          // secondary: stays local
  EXPECT_EQ((*job)->InsertRemote({record(200, 7, 0)}), 1u);  // another worker's
  cache->Insert(record(6, 0, 0));
  EXPECT_EQ(tags((*job)->TakeNewOwnRecords(4)), (std::vector<int>{1, 2, 3, 4}));
  cache->Insert(record(7, 0, 0));
  EXPECT_EQ(tags((*job)->TakeNewOwnRecords(4)), (std::vector<int>{5, 6, 7}));
  EXPECT_TRUE((*job)->TakeNewOwnRecords(4).empty());
  cache->Insert(record(8, 0, 0));
  EXPECT_EQ(tags((*job)->TakeNewOwnRecords(4)), (std::vector<int>{8}));
}

// The job id comes from the coordinator and names the bundle's temp dir: one with a path in it is
// refused before anything is written ("x/../../../home/u/p" put the bundle elsewhere whenever
// /tmp/irfarm-worker-x existed).
TEST(JobContextTest, AJobIdThatIsNotANameIsRefused) {
  for (const char* id : {"x/../../../tmp/p", "..", "a b", "", "job-1\n"}) {
    v1::JobSpec spec = Spec("cornell-box", true);
    spec.set_job_id(id);
    const absl::StatusOr<std::unique_ptr<JobContext>> job = JobContext::Create(spec, 1);
    EXPECT_EQ(job.status().code(), absl::StatusCode::kInvalidArgument) << id;
  }
  v1::JobSpec spec = Spec("cornell-box", true);
  spec.set_job_id(std::string(65, 'j'));
  EXPECT_FALSE(JobContext::Create(spec, 1).ok());
  spec.set_job_id("job-12.a_b");
  EXPECT_TRUE(JobContext::Create(spec, 1).ok());
}

}  // namespace
}  // namespace irfarm
