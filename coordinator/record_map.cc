// The dashboard's record map (see record_map.h).
#include "coordinator/record_map.h"

#include <algorithm>
#include <cmath>

#include "coordinator/job_manager.h"

namespace irfarm {
namespace {

// 12 colours that stay distinct on black (Sasha Trubetskoy's list of distinct colours), 8-bit
// sRGB; the dashboard page's legend repeats this table.
constexpr std::array<std::array<uint8_t, 3>, 12> kPalette = {{{230, 25, 75},
                                                              {60, 180, 75},
                                                              {255, 225, 25},
                                                              {0, 130, 200},
                                                              {245, 130, 48},
                                                              {145, 30, 180},
                                                              {70, 240, 240},
                                                              {240, 50, 230},
                                                              {210, 245, 60},
                                                              {250, 190, 212},
                                                              {0, 128, 128},
                                                              {220, 190, 255}}};

}  // namespace

std::array<uint8_t, 3> RecordMapColor(uint32_t origin) {
  if (origin == kSnapshotOrigin || origin == 0) return {255, 255, 255};
  return kPalette[(origin - 1) % kPalette.size()];
}

Image DrawRecordMap(const Camera& camera, const std::vector<RecordMapPoint>& points) {
  const int w = camera.width(), h = camera.height();
  const float scale = std::min(1.0f, float(kMaxRecordMapSide) / float(std::max(w, h)));
  Image map(std::max(1, int(std::lround(w * scale))), std::max(1, int(std::lround(h * scale))));
  // Linear values whose sRGB encoding at exposure 1 gives back the palette's bytes exactly.
  const auto linear = [](const std::array<uint8_t, 3>& c) {
    return Vec3(SrgbToLinear(c[0] / 255.0f), SrgbToLinear(c[1] / 255.0f),
                SrgbToLinear(c[2] / 255.0f));
  };
  uint32_t last_origin = 0;
  Vec3 colour = linear(RecordMapColor(0));
  for (const RecordMapPoint& p : points) {
    float x, y;
    if (!camera.Project(p.position, &x, &y)) continue;
    const float sx = std::floor(x * scale), sy = std::floor(y * scale);
    if (!(sx >= 0 && sy >= 0 && sx < float(map.width) && sy < float(map.height))) continue;
    if (p.origin != last_origin) {
      last_origin = p.origin;
      colour = linear(RecordMapColor(p.origin));
    }
    map.at(int(sx), int(sy)) = colour;
  }
  return map;
}

}  // namespace irfarm
