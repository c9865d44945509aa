// Shape plugins by their Mitsuba 3 XML name. Each shape is one file in render/shapes/ that
// defines a ShapePlugin and one line in registry.cc's list; nothing else in the loader names a
// shape type. The path of a <shape type="..."> element:
//   the XML loader reads what every shape shares (id, to_world, flip_normals, its bsdf and area
//   emitter), finds the plugin by name and calls plugin.parse with a ShapeParams reader. The
//   plugin reads its own parameters (each getter marks one read) and returns its geometry in its
//   own space: a triangle mesh with the placement that goes before to_world, or an analytic
//   sphere. Parameters nobody asked for are then an error with file:line (Mitsuba 3's property
//   check), and the loader moves the geometry to world space and cleans it up the same way for
//   every shape. shapegroup and instance hold other shapes and stay the loader's own.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/math.h"
#include "render/scene_desc.h"

namespace irfarm {

// What a shape plugin may ask of the XML loader while parsing one <shape> element.
class ShapeParams {
 public:
  virtual ~ShapeParams() = default;
  virtual absl::StatusOr<float> Float(absl::string_view name, float def) = 0;
  virtual absl::StatusOr<int> Int(absl::string_view name, int def) = 0;
  virtual absl::StatusOr<bool> Bool(absl::string_view name, bool def) = 0;
  // A point or vector in double (it may be far from the origin), if given.
  virtual absl::StatusOr<std::optional<std::array<double, 3>>> Point(absl::string_view name) = 0;
  // A file named relative to the scene folder, resolved; it must exist and stay inside the folder.
  virtual absl::StatusOr<std::string> File(absl::string_view name) = 0;
  // INVALID_ARGUMENT with file:line of the named parameter (of the element when not given).
  virtual absl::Status Error(absl::string_view name, absl::string_view what) const = 0;
  // `s` (a mesh reader's status) with the element's file:line and `what` in front, code kept.
  virtual absl::Status ElementError(const absl::Status& s, absl::string_view what) const = 0;
};

// A shape's geometry in its own space, before to_world.
struct ShapeGeometry {
  // An analytic sphere (center and radius in the shape's own space) instead of a mesh.
  bool sphere = false;
  std::array<double, 3> center{0, 0, 0};
  float radius = 1;
  // A triangle mesh and the transform from the mesh's space to the shape's own space.
  TriangleMesh mesh;
  Mat4 placement;
  // Mitsuba's analytic rectangle, disk and cylinder: their normal is to_world's normal transform
  // of +z even when to_world mirrors, so their triangles turn with a mirroring to_world (meshes
  // from files keep their order).
  bool turns_with_mirror = false;
  // A mesh from a file: when it emits, it is sliced across its length as a cylinder is cut into
  // rings, so a tube's full-length slivers become short pieces for light sampling.
  bool slice_when_emitting = false;
  bool face_normals = false;  // flat shading: the face_normals parameter of triangle shapes
};

struct ShapePlugin {
  const char* name;  // the XML type
  absl::StatusOr<ShapeGeometry> (*parse)(ShapeParams& params);
};

// The plugin for an XML type name, or nullptr.
const ShapePlugin* FindShapePlugin(absl::string_view name);
// All registered names, in registry order (for "supported: ..." messages).
std::vector<std::string> ShapePluginNames();

// Triangle shapes' shared parameter (face_normals), read first as Mitsuba's mesh base does.
inline absl::StatusOr<ShapeGeometry> TriangleShape(ShapeParams& p) {
  ShapeGeometry g;
  absl::StatusOr<bool> face_normals = p.Bool("face_normals", false);
  if (!face_normals.ok()) return face_normals.status();
  g.face_normals = *face_normals;
  return g;
}

// A triangle shape read from the file named by `filename`: read(path) loads it, reading any
// further parameters of its own first. Meshes from files are sliced when they emit.
template <typename Read>
absl::StatusOr<ShapeGeometry> FileMeshShape(ShapeParams& p, Read read) {
  absl::StatusOr<ShapeGeometry> g = TriangleShape(p);
  if (!g.ok()) return g;
  absl::StatusOr<std::string> filename = p.File("filename");
  if (!filename.ok()) return filename.status();
  absl::StatusOr<TriangleMesh> mesh = read(*filename);
  if (!mesh.ok()) return p.ElementError(mesh.status(), "mesh ");
  g->mesh = *std::move(mesh);
  g->slice_when_emitting = true;
  return g;
}

}  // namespace irfarm
