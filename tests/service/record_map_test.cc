// Tests of the dashboard's record map (coordinator/record_map.h): records drawn at the pixel of
// their camera ray in their worker's colour, and the PNG carrying those colours byte for byte;
// a large film scaled down to kMaxRecordMapSide; and through a JobManager, a record's colour is
// the worker session that sent it, whatever origin the batch claims.
#include "coordinator/record_map.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"
#include "render/record_bounds.h"
#include "service/job_settings.h"
#include "service/record_codec.h"
#include "service/scene_bundle.h"

namespace irfarm {
namespace {

const std::string kScene = std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml";

CameraDesc TestCamera(int w, int h) {
  CameraDesc d;
  d.to_world = Mat4::LookAt(Vec3(0, 1, 4), Vec3(0, 1, 0), Vec3(0, 1, 0));
  d.fov_x_deg = 40;
  d.width = w;
  d.height = h;
  return d;
}

// A point seen at the centre of pixel (x, y), `t` units from the camera.
Vec3 PointAt(const Camera& cam, int x, int y, float t) {
  return cam.origin() + cam.Direction(x + 0.5f, y + 0.5f) * t;
}

Vec3 Linear(const std::array<uint8_t, 3>& c) {
  return Vec3(SrgbToLinear(c[0] / 255.0f), SrgbToLinear(c[1] / 255.0f),
              SrgbToLinear(c[2] / 255.0f));
}

TEST(RecordMapTest, DrawsEachRecordAtItsPixelInItsWorkersColour) {
  const Camera cam(TestCamera(40, 30));
  std::vector<RecordMapPoint> points = {
      {PointAt(cam, 3, 4, 2.0f), 1},
      {PointAt(cam, 30, 20, 5.0f), 2},
      {PointAt(cam, 10, 25, 3.0f), kSnapshotOrigin},
      {cam.origin() - cam.Direction(20.5f, 15.5f) * 2.0f, 1},  // behind the camera: not drawn
      {cam.origin() + cam.Direction(-30, 15) * 2.0f, 2},       // left of the image: not drawn
  };
  const Image map = DrawRecordMap(cam, points);
  ASSERT_EQ(map.width, 40);
  ASSERT_EQ(map.height, 30);
  int lit = 0;
  for (const Vec3& p : map.pixels) lit += p.x + p.y + p.z > 0;
  EXPECT_EQ(lit, 3);
  const Vec3 a = map.at(3, 4), b = map.at(30, 20), s = map.at(10, 25);
  const Vec3 ea = Linear(RecordMapColor(1)), eb = Linear(RecordMapColor(2));
  EXPECT_EQ(a.x, ea.x);
  EXPECT_EQ(a.y, ea.y);
  EXPECT_EQ(b.x, eb.x);
  EXPECT_EQ(b.z, eb.z);
  EXPECT_EQ(s.x, 1.0f);  // imported records are white
  EXPECT_NE(RecordMapColor(1), RecordMapColor(2));
  EXPECT_EQ(RecordMapColor(1), RecordMapColor(13));  // 12 colours, then they repeat

  // The PNG the endpoint serves (exposure 1) carries the palette's bytes exactly.
  absl::StatusOr<std::string> png = EncodePng(map, 1.0f);
  ASSERT_TRUE(png.ok());
  const std::string path = ::testing::TempDir() + "/record_map_test.png";
  std::ofstream(path, std::ios::binary) << *png;
  Image floats;
  ByteImage back;  // the PNG's bytes, not decoded
  ASSERT_TRUE(ReadTextureImage(path, false, &floats, &back).ok());
  std::remove(path.c_str());
  ASSERT_EQ(back.width, map.width);
  const auto byte = [&](int x, int y, int k) {
    return int(back.rgb[3 * (size_t(y) * size_t(back.width) + size_t(x)) + size_t(k)]);
  };
  for (const auto& [x, y, origin] : {std::tuple{3, 4, 1u}, std::tuple{30, 20, 2u}}) {
    const auto c = RecordMapColor(origin);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(byte(x, y, k), int(c[k])) << origin;
  }
  EXPECT_EQ(byte(0, 0, 0), 0);
}

TEST(RecordMapTest, LargeFilmIsScaledDownToTheMaximumSide) {
  const Camera cam(TestCamera(4096, 1024));
  const Image map = DrawRecordMap(cam, {{PointAt(cam, 4000, 1000, 3.0f), 3}});
  EXPECT_EQ(map.width, kMaxRecordMapSide);
  EXPECT_EQ(map.height, kMaxRecordMapSide / 4);
  EXPECT_GT(map.at(1000, 250).x + map.at(1000, 250).y + map.at(1000, 250).z, 0.0f);
}

// Through the JobManager: two worker sessions send records for the Cornell box (the second
// claiming the first's id as origin); the map colours each by the session it came on, and a
// restarted coordinator (same store) draws the same map from the stored camera.
TEST(RecordMapTest, ColoursComeFromTheSendingSession) {
  InMemoryJobStore store;
  JobManagerOptions options;
  auto manager = std::move(*JobManager::Create(options, &store));
  v1::SubmitJobRequest req;
  *req.mutable_scene()->mutable_bundle() = *MakeBundle(kScene);
  (*req.mutable_settings()->mutable_defines())["resx"] = "32";
  (*req.mutable_settings()->mutable_defines())["resy"] = "32";
  req.mutable_settings()->set_tile_size(16);
  req.mutable_settings()->set_share_records(true);
  absl::StatusOr<v1::Job> job = manager->Submit(req);
  ASSERT_TRUE(job.ok()) << job.status();
  absl::StatusOr<SceneDesc> desc = LoadJobScene(kScene, req.settings());
  ASSERT_TRUE(desc.ok());
  const Camera cam(desc->camera);
  const Bounds3 box = SceneShapeBounds(*desc);
  const float t = Length((box.lo + box.hi) * 0.5f - cam.origin());  // inside the box

  const uint32_t w1 = manager->RegisterWorker("w1"), w2 = manager->RegisterWorker("w2");
  for (uint32_t w : {w1, w2}) {
    bool leased = false;
    for (int i = 0; i < 10 && !leased; ++i)
      for (const v1::CoordinatorMessage& m : manager->Poll(w, std::chrono::milliseconds(100)))
        leased |= m.has_lease();
    ASSERT_TRUE(leased) << w;
  }
  const auto send = [&](uint32_t session, uint32_t claimed, int x, int y) {
    IrradianceRecord r;
    r.position = PointAt(cam, x, y, t);
    r.normal = Vec3(0, 1, 0);
    r.irradiance = Vec3(0.1f);
    r.radius = 0.05f;
    v1::JobRecords batch;
    batch.set_job_id(job->id());
    PackRecords({r}, claimed, batch.mutable_batch());
    ASSERT_TRUE(manager->AddRecords(session, batch).ok());
  };
  send(w1, w1, 10, 12);
  send(w2, w1, 20, 16);  // w2 claims to be w1
  const auto check = [&](JobManager& m) {
    absl::StatusOr<Image> map = m.RecordMap(job->id());
    ASSERT_TRUE(map.ok()) << map.status();
    ASSERT_EQ(map->width, 32);
    const Vec3 c1 = Linear(RecordMapColor(w1)), c2 = Linear(RecordMapColor(w2));
    EXPECT_EQ(map->at(10, 12).x, c1.x);
    EXPECT_EQ(map->at(10, 12).y, c1.y);
    EXPECT_EQ(map->at(20, 16).x, c2.x);
    EXPECT_EQ(map->at(20, 16).y, c2.y);
  };
  check(*manager);
  EXPECT_EQ(manager->RecordMap("no-such-job").status().code(), absl::StatusCode::kNotFound);
  Caller other{"mallory", false};
  EXPECT_EQ(manager->RecordMap(job->id(), other).status().code(), absl::StatusCode::kNotFound);
  manager->FlushStore(std::chrono::seconds(5));
  manager.reset();
  auto restarted = std::move(*JobManager::Create(options, &store));
  check(*restarted);
}

}  // namespace
}  // namespace irfarm
