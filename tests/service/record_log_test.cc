// RecordLog (coordinator/record_log.h): a view of the records so far stays valid and unchanged
// while the log grows past many blocks and after the log is gone, and a thread may read a view
// while another appends (JobManager::AddTileRegion scans a view without its lock).
#include "coordinator/record_log.h"

#include <gtest/gtest.h>

#include <memory>
#include <thread>

namespace irfarm {
namespace {

IrradianceRecord Numbered(size_t i) {
  IrradianceRecord r;
  r.position = Vec3(float(i), float(i % 7), -float(i));
  r.normal = Vec3(0, 0, 1);
  r.radius = 1.0f + float(i % 13);
  r.origin = uint32_t(i);
  return r;
}

void ExpectNumbered(const IrradianceRecord& r, size_t i) {
  ASSERT_EQ(r.origin, uint32_t(i));
  ASSERT_EQ(r.position.x, float(i));
  ASSERT_EQ(r.radius, 1.0f + float(i % 13));
}

TEST(RecordLogTest, AViewKeepsTheRecordsItSawWhileTheLogGrowsAndAfterItIsGone) {
  auto log = std::make_unique<RecordLog>();
  EXPECT_TRUE(log->empty());
  const size_t first = 10000;  // more than two blocks, ending inside one
  for (size_t i = 0; i < first; ++i) log->Append(Numbered(i));
  const RecordLog::View view = log->Snapshot();
  for (size_t i = first; i < 5 * first; ++i) log->Append(Numbered(i));
  ASSERT_EQ(log->size(), 5 * first);
  for (size_t i = 0; i < log->size(); ++i) ExpectNumbered((*log)[i], i);
  const std::vector<IrradianceRecord> all = log->ToVector();
  ASSERT_EQ(all.size(), 5 * first);
  ExpectNumbered(all.back(), 5 * first - 1);
  log.reset();
  ASSERT_EQ(view.size(), first);
  for (size_t i = 0; i < view.size(); ++i) ExpectNumbered(view[i], i);
}

TEST(RecordLogTest, AThreadReadsAViewWhileTheOwnerAppends) {
  RecordLog log;
  for (size_t i = 0; i < 6000; ++i) log.Append(Numbered(i));
  const RecordLog::View view = log.Snapshot();  // taken "under the lock"
  std::thread reader([&view] {
    for (int pass = 0; pass < 20; ++pass)
      for (size_t i = 0; i < view.size(); ++i) ExpectNumbered(view[i], i);
  });
  for (size_t i = 6000; i < 200000; ++i) log.Append(Numbered(i));  // fills the view's last block
  reader.join();
  EXPECT_EQ(log.size(), 200000u);
}

}  // namespace
}  // namespace irfarm
