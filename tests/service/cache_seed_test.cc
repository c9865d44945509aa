// CanSeed (coordinator/cache_seed.h): which earlier job's records a new job may start from.
#include <gtest/gtest.h>

#include "coordinator/cache_seed.h"

namespace irfarm {
namespace {

v1::StoredJob Job(const std::string& id, bool no_caustics) {
  v1::StoredJob j;
  j.mutable_job()->set_id(id);
  j.mutable_job()->set_scene_hash(42);
  j.mutable_job()->mutable_settings()->set_share_records(true);
  j.mutable_job()->mutable_settings()->set_no_caustics(no_caustics);
  j.set_max_accuracy(0.1f);
  return j;
}

TEST(CacheSeedTest, RecordsCarryOverOnlyBetweenJobsWithTheSameCausticsSetting) {
  // With the caustic photon map a record's rays leave caustics out (the map adds them at every
  // lookup); without it the record holds them. Seeding one from the other would count the
  // caustics twice or not at all: a second job on the same workers with the map, seeded from a
  // --no-caustics job of specular, came out at relMSE 5.0e-3 instead of 1.0e-3.
  EXPECT_TRUE(CanSeed(Job("job-1", false), Job("job-2", false)));
  EXPECT_TRUE(CanSeed(Job("job-1", true), Job("job-2", true)));
  EXPECT_FALSE(CanSeed(Job("job-1", true), Job("job-2", false)));
  EXPECT_FALSE(CanSeed(Job("job-1", false), Job("job-2", true)));
  v1::StoredJob other_scene = Job("job-2", false);
  other_scene.mutable_job()->set_scene_hash(43);
  EXPECT_FALSE(CanSeed(Job("job-1", false), other_scene));
}

TEST(CacheSeedTest, RecordsStayWithTheClientWhoseJobHasThem) {
  // A client's snapshot may hold records that pass every bound and are wrong: they must not
  // reach another client's job of the same scene.
  v1::StoredJob alice = Job("job-1", false), bob = Job("job-2", false);
  alice.mutable_job()->set_owner("alice");
  bob.mutable_job()->set_owner("bob");
  EXPECT_FALSE(CanSeed(alice, bob));
  EXPECT_FALSE(CanSeed(bob, alice));
  v1::StoredJob alice2 = Job("job-3", false);
  alice2.mutable_job()->set_owner("alice");
  EXPECT_TRUE(CanSeed(alice, alice2));
}

}  // namespace
}  // namespace irfarm
