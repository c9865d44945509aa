// The dashboard's record map (issue 11): where a job's irradiance records were computed, each
// drawn as one pixel at its position projected through the job's camera (Camera::Project), in the
// colour of the worker that computed it, on black. Which worker computed a record is the record's
// `origin`, which the coordinator sets itself from the authenticated worker session the record
// came in on (JobManager::AddRecords), never from anything the worker sent. Only level-0 records
// are drawn: they were made for camera paths, at surfaces the camera sees; secondary records
// (level > 0) sit at hemisphere-ray hits, often hidden, and would clutter the map.
//
// Bounds: at most kMaxRecordMapPoints records are drawn per map (an even stride through the job's
// records beyond that: the map shows where records are, not how many), and the map is the film
// scaled down to at most kMaxRecordMapSide pixels on its longer side.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/math.h"
#include "render/camera.h"
#include "render/image.h"

namespace irfarm {

constexpr size_t kMaxRecordMapPoints = size_t(1) << 18;  // 262,144 records, 4 MB copied
constexpr int kMaxRecordMapSide = 1024;                  // pixels

// What the map needs of a record.
struct RecordMapPoint {
  Vec3 position;    // world space
  uint32_t origin;  // worker id (JobManager's), or kSnapshotOrigin for imported records
};

// The 8-bit sRGB colour of records of `origin`: worker ids 1, 2, ... cycle through 12 distinct
// colours (dashboard_page.cc's legend has the same table); imported records are white.
std::array<uint8_t, 3> RecordMapColor(uint32_t origin);

// The map of `points` for a film of `camera`'s size, scaled down to kMaxRecordMapSide; encoded
// with EncodePng(map, 1) its pixels are exactly RecordMapColor's bytes (or black).
Image DrawRecordMap(const Camera& camera, const std::vector<RecordMapPoint>& points);

}  // namespace irfarm
