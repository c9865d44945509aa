// A cache snapshot's records against the scene's RecordBounds (render/record_bounds.h), the check
// the coordinator makes on a submitted snapshot and `irfarm render --cache-in` on a file: a
// record that passes IsValidRecord (finite, unit normal, R > 0) but covers the whole scene, lies
// outside it or is brighter than its emitters allow is refused, naming the record and why.
#include <gtest/gtest.h>

#include "render/record_bounds.h"
#include "render_test_util.h"

namespace irfarm {
namespace {

TEST(RecordBoundsTest, ASnapshotRecordOutsideTheScenesBoundsIsNamed) {
  const absl::StatusOr<SceneDesc> desc = LoadSceneFile(TestScenePath("cornell-box"), {});
  ASSERT_TRUE(desc.ok()) << desc.status();
  const RecordBounds b = RecordBoundsForScene(*desc);
  IrradianceRecord good;
  good.normal = Vec3(0, 1, 0);
  good.irradiance = Vec3(0.5f);
  good.radius = 0.2f;
  EXPECT_TRUE(SnapshotRecordsProblem(b, {good, good}, "snap").ok());
  IrradianceRecord wide = good, far = good, bright = good;
  wide.radius = 1e30f;
  far.position = Vec3(0, 1e6f, 0);
  bright.irradiance = Vec3(3e38f);
  const std::pair<IrradianceRecord, const char*> cases[] = {
      {wide, "snap: record 1: radius larger than the scene"},
      {far, "snap: record 1: position outside the scene's bounds"},
      {bright, "snap: record 1: irradiance above the bound from the scene's emitters"}};
  for (const auto& [bad, message] : cases) {
    const absl::Status st = SnapshotRecordsProblem(b, {good, bad, good}, "snap");
    EXPECT_TRUE(absl::IsInvalidArgument(st)) << st;
    EXPECT_EQ(st.message(), message);
  }
}

}  // namespace
}  // namespace irfarm
