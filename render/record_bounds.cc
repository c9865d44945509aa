// RecordBounds: scene-derived limits on records (see record_bounds.h).
#include "render/record_bounds.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "render/emitters/registry.h"

namespace irfarm {
namespace {

constexpr float kInterreflectionFactor = 100.0f;  // 1 / (1 - 0.99), see record_bounds.h

}  // namespace

Bounds3 SceneShapeBounds(const SceneDesc& desc) {
  Bounds3 b = ShapeBounds(desc);
  if (b.Empty()) {
    b.Extend(Vec3(-1));
    b.Extend(Vec3(1));
  }
  return b;
}

float EmitterIrradianceBound(const SceneDesc& desc) {
  const Bounds3 shapes = SceneShapeBounds(desc);
  const float diag = std::max(Length(shapes.Diagonal()), 1e-6f);
  const float d_min = 1e-3f * diag;
  double direct = 0;  // W/m^2, summed over emitters (double: many emitters, no overflow)
  for (const ShapeDesc& s : desc.shapes)
    if (s.area_radiance) direct += kPi * std::max(0.0f, MaxComponent(*s.area_radiance));
  for (const EmitterDesc& e : desc.emitters) {
    const EmitterPlugin* plugin = FindEmitterPlugin(e.type);
    if (plugin == nullptr) return std::numeric_limits<float>::max();
    direct += plugin->irradiance_bound(e, double(d_min));
  }
  const double bound = direct * kInterreflectionFactor;
  if (!(bound < double(std::numeric_limits<float>::max())))
    return std::numeric_limits<float>::max();
  // A scene without emitters is black: allow a tiny positive value for rounding.
  return std::max(float(bound), 1e-6f);
}

RecordBounds RecordBoundsForScene(const SceneDesc& desc) {
  RecordBounds b;
  const Bounds3 shapes = SceneShapeBounds(desc);
  const float margin = 0.01f * Length(shapes.Diagonal());
  b.box.lo = shapes.lo - Vec3(margin);
  b.box.hi = shapes.hi + Vec3(margin);
  Bounds3 with_camera = shapes;
  const Mat4& m = desc.camera.to_world;
  with_camera.Extend(Vec3(float(m.m[0][3]), float(m.m[1][3]), float(m.m[2][3])));
  b.max_radius = 2.0f * std::max(Length(with_camera.Diagonal()), 1e-6f);
  b.max_irradiance = EmitterIrradianceBound(desc);
  return b;
}

const char* RecordProblem(const RecordBounds& b, const IrradianceRecord& r) {
  if (!IsValidRecord(r)) return "not finite, normal not unit, R <= 0 or E < 0";
  const Vec3& p = r.position;
  if (p.x < b.box.lo.x || p.y < b.box.lo.y || p.z < b.box.lo.z || p.x > b.box.hi.x ||
      p.y > b.box.hi.y || p.z > b.box.hi.z)
    return "position outside the scene's bounds";
  if (r.radius > b.max_radius) return "radius larger than the scene";
  if (MaxComponent(r.irradiance) > b.max_irradiance)
    return "irradiance above the bound from the scene's emitters";
  return nullptr;
}

absl::Status SnapshotRecordsProblem(const RecordBounds& b,
                                    const std::vector<IrradianceRecord>& records,
                                    const std::string& name) {
  for (size_t i = 0; i < records.size(); ++i)
    if (const char* why = RecordProblem(b, records[i]))
      return absl::InvalidArgumentError(name + ": record " + std::to_string(i) + ": " + why);
  return absl::OkStatus();
}

}  // namespace irfarm
