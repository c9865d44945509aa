// Cache seeding across jobs: irradiance records do not depend on the view, so a job whose scene
// differs from an earlier job's of the same client only in the sensor (same sensor-free scene hash,
// service/ scene_hash.h) and whose record settings match (integrator irrcache, accuracy a, record
// rays, caustics: with the photon map a record leaves caustics out, without it a record holds them;
// max_depth is part of the hash) can start from the records the earlier job merged, for
// example the frames of a camera move submitted as one batch. CanSeed says whether a job may
// take another's records; SeedSet collects the records of several such jobs without duplicates
// (a job seeded from another holds copies of that job's records).
#pragma once

#include <cstdint>
#include <unordered_set>
#include <vector>

#include "cache/irradiance_record.h"
#include "irfarm/v1/store.pb.h"

namespace irfarm {

// True when `from`'s records are valid in `to` and may go there: both irradiance-cache jobs of
// the same client (a client's snapshot holds records that pass every bound yet are wrong, e.g.
// black with wide radii: they must not reach another client's image) and of the same
// sensor-free scene with the same accuracy, record rays and caustics setting, and `to` shares
// records (a job submitted with sharing off is a measurement of isolated workers and takes none).
bool CanSeed(const v1::StoredJob& from, const v1::StoredJob& to);

class SeedSet {
 public:
  // Adds the records not added before (same position, normal and radius bits).
  void Add(const std::vector<IrradianceRecord>& records);
  void Add(const IrradianceRecord& r);
  const std::vector<IrradianceRecord>& records() const { return records_; }

 private:
  std::unordered_set<uint64_t> seen_;
  std::vector<IrradianceRecord> records_;
};

}  // namespace irfarm
