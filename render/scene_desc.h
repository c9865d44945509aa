// The plain description of a scene that the XML loader produces and the scene builder consumes
// (parse -> describe -> build). Everything is already in world space; meshes are loaded;
// nothing here knows Embree. Every element keeps the line it came from for later errors.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/math.h"

namespace irfarm {

struct SourceLoc {
  std::string file;  // path of the scene file as given to the loader
  int line = 0;
  std::string ToString() const { return file + ":" + std::to_string(line); }
};

// The film's reconstruction filter (hdrfilm's <rfilter>), as Mitsuba 3 defines it: a pixel's
// value is the average of the radiance over the film weighted by w(x - cx) w(y - cy) around its
// centre (cx, cy), the filter truncated to the image (Mitsuba samples only inside the crop
// window, sample_border = false). Separable, non-negative, in pixel units:
//   box:      w = 1 for |t| <= 0.5 (the pixel's own square)
//   tent:     w = max(0, 1 - |t| / radius)                       radius default 1
//   gaussian: w = max(0, exp(-t^2 / (2 stddev^2)) - exp(-8))     stddev default 0.5, cut at
//             radius = 4 stddev, where the subtracted exp(-8) takes it to 0
// A film that names no filter gets gaussian, Mitsuba's default.
enum class FilterType { kBox, kTent, kGaussian };

struct FilterDesc {
  FilterType type = FilterType::kGaussian;
  float radius = 2;     // pixels: the support is [-radius, radius] (box: 0.5)
  float stddev = 0.5f;  // gaussian only, pixels
};

struct CameraDesc {
  Mat4 to_world;         // camera space: +z forward, +y up, +x image left (Mitsuba)
  float fov_x_deg = 45;  // horizontal field of view over the whole image, after fov_axis
  float near_clip = 0.01f, far_clip = 1e4f;  // camera rays see from near to far (Camera::Clip)
  int width = 768, height = 576;  // the rendered image: the film's crop window (all of it)
  // hdrfilm's crop_*: the full film is film_width x film_height (0 = width x height) and the
  // image is its window at (crop_x, crop_y), as Mitsuba 3 renders it.
  int film_width = 0, film_height = 0, crop_x = 0, crop_y = 0;
  // perspective's principal_point_offset_x / _y: the image centre moved by these fractions of
  // the film's width and height (Mitsuba 3's; its Blender exporter writes them).
  float principal_x = 0, principal_y = 0;
  int spp = 4;  // sampler sample_count
  FilterDesc filter;
  // thinlens: the lens's radius (scene units; 0 = the pinhole `perspective`) and the distance
  // of the plane in focus along the view direction.
  float aperture_radius = 0, focus_distance = 1e4f;
  SourceLoc loc;
};

struct IntegratorDesc {
  std::string type = "path";  // "path" or "irrcache"
  int max_depth = -1;         // Mitsuba's count of path vertices; -1 = unbounded
  int rr_depth = 5;
  // Other parameters given in the XML (irrcache settings), name -> value text.
  std::map<std::string, std::string> params;
  SourceLoc loc;
};

struct TextureDesc {
  std::string type = "bitmap";  // Mitsuba plugin name: "bitmap" or "checkerboard"
  // bitmap
  std::string filename;  // resolved absolute/relative path on disk (inside the scene folder)
  bool raw = false;      // true: values are linear already (no sRGB decoding)
  std::string filter_type = "bilinear";  // "bilinear" or "nearest"
  std::string wrap_mode = "repeat";      // "repeat", "mirror", "clamp"
  // checkerboard
  Vec3 color0{0.4f, 0.4f, 0.4f}, color1{0.2f, 0.2f, 0.2f};
  // to_uv, as Mitsuba reduces it to 2D: (u, v) -> (a[0] u + a[1] v + a[2], a[3] u + a[4] v + a[5]).
  std::array<float, 6> to_uv{1, 0, 0, 0, 1, 0};
  SourceLoc loc;
};

// A reflectance: constant rgb, or a bitmap texture (index into SceneDesc::textures).
struct ColorParam {
  Vec3 value{0.5f, 0.5f, 0.5f};
  int texture = -1;  // >= 0: use textures[texture] instead of value
};

// One <bsdf> element, described generically: its plugin name and every parameter the plugin
// read (with defaults filled in), by parameter name. Only render/bsdfs/<type>.cc interprets
// them (see render/bsdfs/registry.h); the scene hash hashes them all.
struct BsdfDesc {
  std::string id;
  std::string type = "diffuse";         // Mitsuba plugin name
  std::map<std::string, float> floats;  // numbers, iors, booleans (0 / 1)
  std::map<std::string, std::string> strings;
  std::map<std::string, ColorParam> colors;  // rgb values or bitmap textures
  std::vector<int> nested;                   // nested bsdfs: indices into SceneDesc::bsdfs
  SourceLoc loc;

  float Float(const std::string& name, float def) const {
    const auto it = floats.find(name);
    return it == floats.end() ? def : it->second;
  }
  std::string String(const std::string& name, const std::string& def) const {
    const auto it = strings.find(name);
    return it == strings.end() ? def : it->second;
  }
  // Mitsuba's get_flag for a colour or texture parameter: given, and not the number 0 (a
  // plugin that erases the parameters it was not given can tell "absent" from a default).
  bool Given(const std::string& name) const {
    const auto it = colors.find(name);
    return it != colors.end() && (it->second.texture >= 0 || !IsBlack(it->second.value));
  }
  ColorParam Color(const std::string& name, Vec3 def) const {
    const auto it = colors.find(name);
    if (it != colors.end()) return it->second;
    ColorParam c;
    c.value = def;
    return c;
  }
};

struct TriangleMesh {
  std::vector<Vec3> positions;    // world space
  std::vector<Vec3> normals;      // world space, per vertex; empty = use face normals
  std::vector<float> uvs;         // 2 per vertex (already v-flipped for OBJ); may be empty
  std::vector<uint32_t> indices;  // 3 per triangle, counter-clockwise = front
};

enum class ShapeType { kMesh, kSphere };

struct ShapeDesc {
  std::string id;
  ShapeType type = ShapeType::kMesh;
  TriangleMesh mesh;  // kMesh (obj, ply, rectangle, cube, disk)
  Vec3 center;        // kSphere, world space
  float radius = 1;   // kSphere, world space
  // kSphere: the orthonormal 3 x 3 (row-major; a mirror where to_world mirrors) that takes the
  // sphere's own directions to world ones. Its (u, v) and tangents come from its own coordinates,
  // as Mitsuba's do, so they turn with to_world.
  std::array<float, 9> frame{1, 0, 0, 0, 1, 0, 0, 0, 1};
  bool flip_normals = false;          // already applied to mesh winding/normals; kept for spheres
  int bsdf = -1;                      // index into SceneDesc::bsdfs
  std::optional<Vec3> area_radiance;  // area emitter on this shape (front side only)
  int degenerate_dropped = 0;         // triangles removed for zero area / repeated vertices
  SourceLoc loc;
};

struct EmitterDesc {
  std::string type;          // the XML type: its plugin (render/emitters/registry.h)
  Vec3 position;             // point, spot (world)
  Vec3 direction{0, 0, 1};   // directional, spot: the direction light travels (unit, world)
  Vec3 intensity{1, 1, 1};   // point, spot: W/sr
  Vec3 irradiance{1, 1, 1};  // directional: W/m^2 on a perpendicular surface
  Vec3 radiance{1, 1, 1};    // constant, area
  float cutoff_angle_deg = 20, beam_width_deg = 15;  // spot (Mitsuba defaults 20 and 15)
  std::string filename;                              // envmap (lat-long EXR/PNG), resolved path
  Mat4 to_world;                                     // envmap
  float scale = 1;                                   // envmap
  SourceLoc loc;
};

struct SceneDesc {
  std::string path;  // scene file
  CameraDesc camera;
  IntegratorDesc integrator;
  std::vector<TextureDesc> textures;
  std::vector<BsdfDesc> bsdfs;
  std::vector<ShapeDesc> shapes;
  std::vector<EmitterDesc> emitters;  // non-area emitters
  // World coordinates of this description's origin. A scene far from the origin compared with
  // its size (a building at x = 1e6, georeferenced) is re-centred on load: its transforms are
  // composed in double with a translation by minus this point before anything is rounded to
  // float, so it keeps the precision it would have at the origin (float32 alone has 0.06-unit
  // steps at 1e6). Every position in this description is relative to it; the image is the same.
  std::array<double, 3> world_origin{0, 0, 0};
  std::vector<std::string>
      warnings;  // e.g. "scene.xml:12: sampler 'stratified' treated as independent"
};

// Bounds of the shapes' positions (meshes' vertices, spheres' extents); empty for a scene without
// shapes.
inline Bounds3 ShapeBounds(const SceneDesc& desc) {
  Bounds3 b;
  for (const ShapeDesc& s : desc.shapes) {
    if (s.type == ShapeType::kSphere) {
      b.Extend(s.center - Vec3(s.radius));
      b.Extend(s.center + Vec3(s.radius));
    }
    for (const Vec3& p : s.mesh.positions) b.Extend(p);
  }
  return b;
}

}  // namespace irfarm
