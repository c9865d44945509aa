// TileScheduler's retry rules (issue 10, part 3): random lease tokens; a failed tile goes to a
// worker it has not failed on while one exists, back to a worker it failed on when every other one
// failed it too (no tile is stranded); the job fails only when a tile failed on
// failure_workers distinct workers or max_attempts times; a silent worker's release is no
// failure.
#include "coordinator/tile_scheduler.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

namespace irfarm {
namespace {

const auto kLease = std::chrono::milliseconds(60000);

TEST(TileSchedulerTest, LeaseTokensAreRandomAndDistinct) {
  TileScheduler s(64, 64, 16, TileRetryPolicy());
  std::set<std::string> tokens;
  for (int i = 0; i < 16; ++i) {
    auto l = s.Lease(1, SteadyTime(), kLease);
    ASSERT_TRUE(l.has_value());
    EXPECT_FALSE(l->token.empty());
    tokens.insert(l->token.Bytes());
    // The tile's lease is found by its token only.
    const TileLeaseInfo* current = s.Current(l->tile, l->token);
    ASSERT_NE(current, nullptr);
    EXPECT_EQ(current->worker, 1u);
    EXPECT_EQ(s.Current(l->tile, LeaseToken()), nullptr);
  }
  EXPECT_EQ(tokens.size(), 16u);
  EXPECT_FALSE(s.Lease(1, SteadyTime(), kLease).has_value());
}

TEST(TileSchedulerTest, FailedTileGoesToAnotherWorkerFirstAndIsNeverStranded) {
  TileScheduler s(16, 16, 16, TileRetryPolicy{3, 10});  // one tile
  auto l = s.Lease(1, SteadyTime(), kLease, {2});
  ASSERT_TRUE(l.has_value());
  ASSERT_TRUE(s.Requeue(l->tile, l->token, "broken").ok());
  EXPECT_FALSE(s.Lease(1, SteadyTime(), kLease, {2}).has_value());  // worker 2 has not failed it
  l = s.Lease(2, SteadyTime(), kLease, {1});
  ASSERT_TRUE(l.has_value());
  ASSERT_TRUE(s.Requeue(l->tile, l->token, "broken too").ok());
  // Both failed it: it goes back to one of them rather than waiting forever.
  l = s.Lease(1, SteadyTime(), kLease, {2});
  ASSERT_TRUE(l.has_value());
  // A silent worker's release does not count.
  ASSERT_TRUE(s.ReleaseWorker(1, "silent", /*count_failure=*/false).ok());
  l = s.Lease(3, SteadyTime(), kLease, {1, 2});
  ASSERT_TRUE(l.has_value());
  const absl::Status st = s.Requeue(l->tile, l->token, "third");
  EXPECT_EQ(st.code(), absl::StatusCode::kAborted);  // third distinct worker
  EXPECT_NE(st.message().find("on 3 workers"), std::string::npos) << st.message();
}

TEST(TileSchedulerTest, OneWorkerFailingRepeatedlyFailsAfterMaxAttempts) {
  TileScheduler s(16, 16, 16, TileRetryPolicy{3, 4});
  for (int i = 1; i <= 4; ++i) {
    auto l = s.Lease(1, SteadyTime(), kLease);
    ASSERT_TRUE(l.has_value());
    const absl::Status st = s.Requeue(l->tile, l->token, "again");
    EXPECT_EQ(st.ok(), i < 4) << i;
  }
}

}  // namespace
}  // namespace irfarm

namespace irfarm {
namespace {

// Affinity (filtered fan-out): a worker's next tile is the far tile nearest to its previous one.
TEST(TileSchedulerTest, LeasePrefersTilesNearTheWorkersPreviousTile) {
  TileScheduler s(64, 64, 16, TileRetryPolicy());        // 4 x 4 tiles, index = 4 y + x
  EXPECT_EQ(s.Lease(1, SteadyTime(), kLease)->tile, 0);  // no previous tile: queue order
  // Worker 2 was at tile 10 = (2, 2): it gets 10's nearest pending tile far from tile 0 (10).
  EXPECT_EQ(s.Lease(2, SteadyTime(), kLease, {1}, 10)->tile, 10);
  // Worker 3 near 10 too: the tiles at least 2 away from both leases ((0, 0) and (2, 2)) nearest
  // to (2, 2) are (2, 0) = 2 and (0, 2) = 8 (squared distance 4); queue order takes 2.
  EXPECT_EQ(s.Lease(3, SteadyTime(), kLease, {1, 2}, 10)->tile, 2);
}

}  // namespace
}  // namespace irfarm
