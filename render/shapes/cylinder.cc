// `cylinder`: Mitsuba's open tube of `radius` (default 1) from `p0` (default the origin) to `p1`
// (default (0, 0, 1)), as a mesh of kCylinderSegments around and enough rings along its length
// that no triangle is a full-length sliver (render/mesh_loader.h: CylinderRings). Its faces point
// out whatever to_world does (Mitsuba keeps only its rotation).
#include "absl/strings/str_cat.h"
#include "render/mesh_loader.h"
#include "render/shapes/registry.h"

namespace irfarm {
namespace {

absl::StatusOr<ShapeGeometry> Parse(ShapeParams& p) {
  absl::StatusOr<ShapeGeometry> g = TriangleShape(p);
  if (!g.ok()) return g;
  std::array<double, 3> p0{0, 0, 0}, p1{0, 0, 1};
  absl::StatusOr<std::optional<std::array<double, 3>>> a = p.Point("p0");
  if (!a.ok()) return a.status();
  absl::StatusOr<std::optional<std::array<double, 3>>> b = p.Point("p1");
  if (!b.ok()) return b.status();
  if (*a) p0 = **a;
  if (*b) p1 = **b;
  absl::StatusOr<float> radius_or = p.Float("radius", 1);
  if (!radius_or.ok()) return radius_or.status();
  const float radius = *radius_or;
  // Mitsuba's unit tube (radius 1, z in [0, 1]) with p0 at the origin, the axis p1 - p0 along z in
  // Mitsuba's frame of it (which fixes where u = 0 is), scaled by the radius and length.
  const Vec3 axis(float(p1[0] - p0[0]), float(p1[1] - p0[1]), float(p1[2] - p0[2]));
  const float length = Length(axis);
  if (!(radius > 0) || !(length > 0) || !std::isfinite(radius) || !std::isfinite(length)) {
    return p.Error("", absl::StrCat("cylinder needs a positive radius and p0 != p1 (radius ",
                                    radius, ", length ", length, ")"));
  }
  Vec3 sx, sy;
  const Vec3 sz = axis / length;
  MakeFrame(sz, &sx, &sy);
  Mat4 frame;
  for (int r = 0; r < 3; ++r) {
    frame.m[r][0] = sx[r];
    frame.m[r][1] = sy[r];
    frame.m[r][2] = sz[r];
  }
  g->placement = Mat4::Translate(p0[0], p0[1], p0[2]) * frame * Mat4::Scale(radius, radius, length);
  g->mesh = MakeCylinderMesh(kCylinderSegments, CylinderRings(length, radius));
  g->turns_with_mirror = true;
  return g;
}

}  // namespace

extern const ShapePlugin kCylinderShape = {"cylinder", Parse};

}  // namespace irfarm
