// The Mitsuba-subset XML scene loader (see scene_loader.h). A Parser walks the document in order.
// Each plugin element is first collected into Params (its property children and nested objects);
// the plugin's code then reads the parameters it supports, and Finish() rejects anything that was
// not read, listing the names the plugin asked for. Meshes are loaded by mesh_loader.

#include "render/scene_loader.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <utility>
#include <vector>
#include "absl/strings/string_view.h"

#include <pugixml.hpp>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "render/bsdfs/registry.h"
#include "render/emitters/registry.h"
#include "render/mesh_loader.h"
#include "render/parse_number.h"
#include "render/shapes/registry.h"
#include "render/spectrum.h"
#include "render/textures/registry.h"

#define LOADER_RETURN_IF_ERROR(expr)   \
  do {                                 \
    absl::Status status_ = (expr);     \
    if (!status_.ok()) return status_; \
  } while (false)
#define LOADER_CONCAT_INNER(a, b) a##b
#define LOADER_CONCAT(a, b) LOADER_CONCAT_INNER(a, b)
#define LOADER_ASSIGN_OR_RETURN(lhs, expr) \
  LOADER_ASSIGN_OR_RETURN_IMPL(LOADER_CONCAT(statusor_, __LINE__), lhs, expr)
#define LOADER_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                                 \
  if (!tmp.ok()) return tmp.status();                \
  lhs = std::move(*tmp)

namespace irfarm {
namespace {

// How much a sphere placed by `m` grows: cbrt |det| of its 3x3 part where that part scales
// uniformly (its columns' lengths agree within 1e-4). Else, as Mitsuba 3's sphere does, the x
// scale (its first column's length: exact for to_world = translate rotate scale), and *uniform
// false so that the caller warns: a sphere stays round, it is not made an ellipsoid.
double SphereScale(const Mat4& m, bool* uniform) {
  double len[3];
  for (int k = 0; k < 3; ++k) {
    const Vec3 c = m.ApplyVector(Vec3(k == 0, k == 1, k == 2));
    len[k] = std::sqrt(double(c.x) * c.x + double(c.y) * c.y + double(c.z) * c.z);
  }
  const double lo = std::min({len[0], len[1], len[2]}), hi = std::max({len[0], len[1], len[2]});
  *uniform = hi <= lo * (1 + 1e-4);
  return *uniform ? std::cbrt(std::abs(m.Determinant3())) : len[0];
}

// The orthonormal part of m's 3 x 3 (row-major), mirrored where m mirrors: a sphere's own frame
// (ShapeDesc::frame). Exact for translate, rotate, uniform scale and mirrors; for an uneven scale
// (kept round, as above) its columns are made orthonormal in order (Gram-Schmidt).
std::array<float, 9> SphereFrame(const Mat4& m) {
  const Vec3 c0 = m.ApplyVector(Vec3(1, 0, 0)), c1 = m.ApplyVector(Vec3(0, 1, 0));
  const Vec3 a = Normalize(c0), b = Normalize(c1 - a * Dot(a, c1));
  const Vec3 c = Cross(a, b) * (m.Determinant3() < 0 ? -1.0f : 1.0f);
  return {a.x, b.x, c.x, a.y, b.y, c.y, a.z, b.z, c.z};
}

// p * q for row-major 3 x 3s.
std::array<float, 9> Compose(const std::array<float, 9>& p, const std::array<float, 9>& q) {
  std::array<float, 9> r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k)
        r[size_t(3 * i + j)] += p[size_t(3 * i + k)] * q[size_t(3 * k + j)];
  return r;
}

namespace fs = std::filesystem;

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

// Mitsuba's named indices of refraction (mitsuba/render/ior.h).
constexpr std::pair<const char*, float> kNamedIors[] = {
    {"vacuum", 1.0f},      {"helium", 1.000036f},        {"hydrogen", 1.000132f},
    {"air", 1.000277f},    {"carbon dioxide", 1.00045f}, {"water", 1.3330f},
    {"acetone", 1.36f},    {"ethanol", 1.361f},          {"carbon tetrachloride", 1.461f},
    {"glycerol", 1.4729f}, {"benzene", 1.501f},          {"silicone oil", 1.52045f},
    {"bromine", 1.661f},   {"water ice", 1.31f},         {"fused quartz", 1.458f},
    {"pyrex", 1.470f},     {"acrylic glass", 1.49f},     {"polypropylene", 1.49f},
    {"bk7", 1.5046f},      {"sodium chloride", 1.544f},  {"amber", 1.55f},
    {"pet", 1.5750f},      {"diamond", 2.419f}};

bool IsOneOf(absl::string_view s, std::initializer_list<absl::string_view> options) {
  return std::find(options.begin(), options.end(), s) != options.end();
}

bool IsPropertyTag(absl::string_view tag) {
  return IsOneOf(tag,
                 {"float", "integer", "boolean", "string", "rgb", "point", "vector", "transform"});
}

bool IsObjectTag(absl::string_view tag) {
  return IsOneOf(tag, {"bsdf", "texture", "emitter", "shape", "sensor", "film", "sampler",
                       "rfilter", "integrator"});
}

// Mitsuba's parse_fov: the horizontal fov for a fov measured along `axis`; aspect = width/height.
std::optional<double> FovX(double fov, absl::string_view axis, double aspect) {
  const auto y_to_x = [aspect](double f) {
    return 2 * std::atan(std::tan(0.5 * f * kDegToRad) * aspect) / kDegToRad;
  };
  if (axis == "x") return fov;
  if (axis == "y") return y_to_x(fov);
  if (axis == "diagonal") {
    const double diagonal = 2 * std::tan(0.5 * fov * kDegToRad);
    const double width = diagonal / std::sqrt(1 + 1 / (aspect * aspect));
    return 2 * std::atan(0.5 * width) / kDegToRad;
  }
  if (axis == "smaller") return aspect > 1 ? y_to_x(fov) : fov;
  if (axis == "larger") return aspect < 1 ? y_to_x(fov) : fov;
  return std::nullopt;
}

// One child of a plugin element: a property (<float name=...>) or a nested object or <ref>.
struct Entry {
  std::string tag;   // property tag, or the object kind ("bsdf", "texture", ...)
  std::string name;  // the name attribute; "" for an unnamed nested object
  pugi::xml_node node;
  int ref = -1;  // a <ref>: index into the scene's bsdfs or textures
  bool used = false;
  Vec3 rgb;  // a <spectrum>: its value converted as Mitsuba converts it (render/spectrum.h)
};

struct Params {
  pugi::xml_node node;                 // the plugin element
  std::string what;                    // e.g. "bsdf 'diffuse'", for messages
  std::vector<Entry> entries;          // in document order
  std::vector<std::string> supported;  // the names the plugin asked for, in order
};

struct IdInfo {
  std::string kind;
  int index = -1;
  pugi::xml_node node;  // where it is defined
};

class Parser {
 public:
  Parser(const std::string& path, const LoadOptions& options)
      : path_(path), base_dir_(fs::path(path).parent_path()), options_(options) {}

  absl::StatusOr<SceneDesc> Parse(const std::string& xml);

 private:
  // The scene file (files_[0]) and every file it includes (<include filename=...>), each with
  // its own document and line table, so that a node's messages name the file it came from.
  struct SourceFile {
    std::string path;              // as messages show it
    fs::path rel_dir;              // its folder, relative to the scene folder ("" for the scene)
    int depth = 0;                 // includes above it
    int parent = -1;               // the file that includes it (index into files_)
    bool upgraded = false;         // a Mitsuba 0.5/0.6 file, upgraded on load
    std::vector<size_t> newlines;  // offsets of '\n' in its text, for line numbers
    pugi::xml_document doc;
    // The line (from 1) of byte `offset` of its text.
    int LineAt(ptrdiff_t offset) const {
      return int(std::lower_bound(newlines.begin(), newlines.end(),
                                  size_t(std::max<ptrdiff_t>(offset, 0))) -
                 newlines.begin()) +
             1;
    }
    // Parses `xml` into doc: INVALID_ARGUMENT "path:line: malformed XML: ..." when it is not.
    absl::Status Load(const std::string& xml) {
      for (size_t i = 0; i < xml.size(); ++i)
        if (xml[i] == '\n') newlines.push_back(i);
      const pugi::xml_parse_result result =
          doc.load_buffer(xml.data(), xml.size(), pugi::parse_default);
      if (result) return absl::OkStatus();
      return absl::InvalidArgumentError(absl::StrCat(path, ":", LineAt(result.offset),
                                                     ": malformed XML: ", result.description()));
    }
  };
  // With kMaxIncludeDepth (scene_loader.h), the file count bounds what an upload can make the
  // loader read (a file including itself twice, 15 deep, would be 2^15 reads).
  static constexpr size_t kMaxIncludedFiles = 1024;
  static constexpr uintmax_t kMaxIncludedBytes = uintmax_t{256} << 20;  // all included files read
  // Parse calls nested in each other (objects in objects, includes, references to objects defined
  // later): bounded together, so that no combination of them (an include restarts a file's own
  // nesting count) can exhaust the stack; real scenes nest a handful.
  static constexpr int kMaxParseDepth = 128;
  // $name substitution: what one attribute may expand to, and all attributes together (a 1 MiB
  // <default> named a million times in one attribute was a 1 TiB string: the process died).
  static constexpr size_t kMaxAttributeBytes = size_t{1} << 20;
  static constexpr size_t kMaxExpandedBytes = size_t{256} << 20;
  const SourceFile& FileOf(pugi::xml_node n) const;
  // A file the scene names, relative to the scene folder and inside it. A parameter's file is
  // looked up in the scene folder; an <include>'s next to the file that names it, then next to
  // each file that includes that one, then in the scene folder (Mitsuba's file resolver: while
  // an included file is read its folder is searched first; its plugins' files are resolved after,
  // with the scene's resolver). `full` is the path to open, `rel` the path in the folder.
  struct FoundFile {
    std::string full;
    fs::path rel;
  };
  absl::StatusOr<FoundFile> ResolveFile(pugi::xml_node at, const std::string& value,
                                        absl::string_view what, bool include = false) const;
  // Reads the file an <include> names: the root of its document (a <scene>, whose children are
  // read in the include's place, or one object), nesting-checked and upgraded.
  absl::StatusOr<pugi::xml_node> LoadInclude(pugi::xml_node inc);
  // Indexes the top-level bsdfs, textures and shapegroups with an id under `root`, included
  // scenes' too (their files are read now), for <ref>s that come before them.
  absl::Status IndexForward(pugi::xml_node root);
  // A <default>'s name, its attributes checked (name and value, both given).
  absl::StatusOr<std::string> DefaultName(pugi::xml_node d) const;
  class DepthGuard;
  absl::Status CheckNesting(pugi::xml_node root) const;

  // Locations and messages.
  int Line(pugi::xml_node n) const;
  // "line N" in the scene file, "PATH:N" in an included one (for messages about another node).
  std::string LineOf(pugi::xml_node n) const {
    const SourceFile& f = FileOf(n);
    return &f == files_[0].get() ? absl::StrCat("line ", Line(n))
                                 : absl::StrCat(f.path, ":", Line(n));
  }
  SourceLoc Loc(pugi::xml_node n) const { return {FileOf(n).path, Line(n)}; }
  std::string Where(pugi::xml_node n) const {
    return absl::StrCat(FileOf(n).path, ":", Line(n), ": ");
  }
  absl::Status Error(pugi::xml_node n, absl::string_view what) const {
    return absl::InvalidArgumentError(absl::StrCat(Where(n), what));
  }
  void Warn(pugi::xml_node n, absl::string_view what) {
    scene_.warnings.push_back(absl::StrCat(Where(n), what));
  }
  static std::string Describe(pugi::xml_node n);
  // An error for values a float cannot hold (FitsFloat, render/parse_number.h).
  absl::Status InFloatRange(pugi::xml_node n, const std::vector<double>& values) const {
    for (double v : values)
      if (!FitsFloat(v))
        return Error(n, absl::StrCat("value ", v, " in ", Describe(n),
                                     " is beyond the range of a float (3.4e38)"));
    return absl::OkStatus();
  }

  // Attributes, with $name substitution.
  absl::StatusOr<std::string> Attr(pugi::xml_node n, const char* name) const;
  absl::StatusOr<std::string> RequiredAttr(pugi::xml_node n, const char* name) const;
  absl::Status CheckAttributes(pugi::xml_node n,
                               std::initializer_list<absl::string_view> allowed) const;
  absl::StatusOr<std::vector<double>> Numbers(pugi::xml_node n, const char* attr) const;
  absl::StatusOr<double> Number(pugi::xml_node n, const char* attr) const;
  absl::StatusOr<std::array<double, 3>> Xyz(pugi::xml_node n, double def, bool scalar_ok) const;
  absl::StatusOr<Mat4> ParseTransform(pugi::xml_node n) const;

  // The parameters of one plugin element.
  absl::StatusOr<Params> Collect(pugi::xml_node obj, absl::string_view kind);
  absl::Status AddEntry(Params& p, pugi::xml_node c, absl::string_view kind);
  // A <ref> to an id not read yet: parses the top-level bsdf, texture or shapegroup that defines
  // it further down (Mitsuba 3 resolves references after reading the whole scene).
  absl::Status ParseForward(pugi::xml_node at, const std::string& id);
  absl::StatusOr<const Entry*> Find(Params& p, absl::string_view name,
                                    std::initializer_list<absl::string_view> tags) const;
  pugi::xml_node NodeOf(const Params& p, absl::string_view name) const;
  // A plugin's error (the readers' Error): at parameter `name`'s line, or the element's when
  // `name` is empty or not given (NodeOf alone would match an unnamed nested object for "").
  absl::Status ParamError(const Params& p, absl::string_view name, absl::string_view what) const {
    return Error(name.empty() ? p.node : NodeOf(p, name), what);
  }
  std::vector<const Entry*> TakeObjects(Params& p, absl::string_view kind) const;
  absl::Status Finish(const Params& p) const;
  absl::StatusOr<float> GetFloat(Params& p, absl::string_view name, float def) const;
  absl::StatusOr<int> GetInt(Params& p, absl::string_view name, int def) const;
  absl::StatusOr<bool> GetBool(Params& p, absl::string_view name, bool def) const;
  absl::StatusOr<std::string> GetString(Params& p, absl::string_view name,
                                        absl::string_view def) const;
  absl::StatusOr<Vec3> GetRgb(Params& p, absl::string_view name, Vec3 def) const;
  absl::StatusOr<std::optional<Vec3>> GetVec3(Params& p, absl::string_view name) const;
  absl::StatusOr<std::optional<Mat4>> GetTransform(Params& p, absl::string_view name) const;
  absl::StatusOr<float> GetIor(Params& p, absl::string_view name, float def) const;
  absl::StatusOr<ColorParam> GetColor(Params& p, absl::string_view name, Vec3 def);
  absl::StatusOr<std::string> GetFile(Params& p, absl::string_view name) const;
  absl::StatusOr<std::map<std::string, std::string>> TakeRestAsText(Params& p) const;

  // Plugins.
  absl::Status RegisterId(pugi::xml_node n, absl::string_view kind, int index);
  absl::StatusOr<std::string> PluginType(pugi::xml_node n, absl::string_view kind,
                                         std::initializer_list<absl::string_view> supported) const;
  absl::Status ParseChildren(pugi::xml_node root);
  absl::Status ParseTopLevel(pugi::xml_node c);
  absl::Status ParseIntegrator(pugi::xml_node n);
  absl::Status ParseSensor(pugi::xml_node n);
  absl::Status ParseFilm(pugi::xml_node n);
  absl::Status UpgradeOldSyntax(pugi::xml_node root);
  absl::Status ParseSampler(pugi::xml_node n);
  class BsdfReader;
  friend class BsdfReader;
  class ShapeReader;
  friend class ShapeReader;
  class TextureReader;
  friend class TextureReader;
  absl::StatusOr<BsdfDesc> ParseBsdf(pugi::xml_node n);
  absl::StatusOr<int> AddBsdf(pugi::xml_node n, BsdfDesc bsdf);
  absl::StatusOr<int> ParseTexture(pugi::xml_node n);
  absl::Status ParseShape(pugi::xml_node n);
  absl::Status ParseShapeGroup(pugi::xml_node n);
  absl::Status ParseInstance(pugi::xml_node n);
  class EmitterReader;
  friend class EmitterReader;
  absl::StatusOr<const EmitterPlugin*> EmitterPluginOf(pugi::xml_node n) const;
  absl::StatusOr<EmitterDesc> ParseEmitterDesc(pugi::xml_node n, const EmitterPlugin& plugin);
  absl::StatusOr<Vec3> ParseAreaEmitter(pugi::xml_node n);
  absl::Status ParseEmitter(pugi::xml_node n);

  const std::string path_;
  const fs::path base_dir_;
  const LoadOptions& options_;
  std::vector<std::unique_ptr<SourceFile>> files_;
  std::map<pugi::xml_node_struct*, pugi::xml_node> includes_;  // <include> -> its file's root
  uintmax_t included_bytes_ = 0;
  int parse_depth_ = 0;  // DepthGuard
  // Top-level bsdfs, textures and shapegroups by id, for <ref>s before them; parsed_ holds those
  // parsed early (skipped where they stand), resolving_ those being parsed (a cycle check).
  std::map<std::string, pugi::xml_node> forward_;
  std::set<pugi::xml_node_struct*> parsed_;
  std::vector<pugi::xml_node> resolving_;
  std::map<std::string, std::string> vars_;  // $name -> value: <default>s, then -D defines
  mutable size_t expanded_bytes_ = 0;        // what $name substitutions added, for the bound
  std::map<std::string, IdInfo> ids_;
  SceneDesc scene_;
  pugi::xml_node sensor_, integrator_, environment_;  // to reject a second one
  int default_bsdf_ = -1;                             // diffuse 0.5, for shapes without a bsdf
  int default_emitter_bsdf_ = -1;                     // diffuse 0, for emitting shapes without one
  // Translation by minus SceneDesc::world_origin, composed (in double) into every to_world.
  Mat4 recentre_;
  // <shape type="shapegroup">: its shapes, in the group's own space, copied into the scene by
  // every <shape type="instance"> that refers to it (by index). While a group's shapes are parsed,
  // shape_sink_ points at it.
  std::vector<std::vector<ShapeDesc>> groups_;
  std::vector<ShapeDesc>* shape_sink_ = nullptr;
  size_t instanced_triangles_ = 0;

 public:
  void SetWorldOrigin(const std::array<double, 3>& o) {
    scene_.world_origin = o;
    recentre_ = Mat4::Translate(-o[0], -o[1], -o[2]);
  }

 private:
  // An object's to_world (identity if none) as it goes into the scene: re-centred.
  Mat4 World(const std::optional<Mat4>& to_world) const {
    return recentre_ * to_world.value_or(Mat4());
  }
  Mat4 World(const Mat4& m) const { return recentre_ * m; }
  // The point `name` (point, vector or three numbers) in double, if given.
  absl::StatusOr<std::optional<std::array<double, 3>>> GetPoint(Params& p,
                                                                absl::string_view name) const;
};

// Counts one level of nested parsing for as long as it lives; Check fails past kMaxParseDepth.
class Parser::DepthGuard {
 public:
  explicit DepthGuard(Parser& p) : p_(p) { ++p_.parse_depth_; }
  ~DepthGuard() { --p_.parse_depth_; }
  DepthGuard(const DepthGuard&) = delete;
  DepthGuard& operator=(const DepthGuard&) = delete;
  absl::Status Check(pugi::xml_node n) const {
    if (p_.parse_depth_ <= kMaxParseDepth) return absl::OkStatus();
    return p_.Error(n, absl::StrCat("objects, includes and references nested more than ",
                                    kMaxParseDepth, " deep"));
  }

 private:
  Parser& p_;
};

const Parser::SourceFile& Parser::FileOf(pugi::xml_node n) const {
  const pugi::xml_node root = n.root();
  for (const std::unique_ptr<SourceFile>& f : files_)
    if (f->doc == root) return *f;
  return *files_[0];
}

int Parser::Line(pugi::xml_node n) const {
  const ptrdiff_t offset = n.offset_debug();
  return offset < 0 ? 0 : FileOf(n).LineAt(offset);
}

std::string Parser::Describe(pugi::xml_node n) {
  const pugi::xml_attribute name = n.attribute("name");
  return name ? absl::StrCat("<", n.name(), " name=\"", name.value(), "\">")
              : absl::StrCat("<", n.name(), ">");
}

absl::StatusOr<std::string> Parser::Attr(pugi::xml_node n, const char* name) const {
  const absl::string_view raw = n.attribute(name).value();
  std::string out;
  for (size_t i = 0; i < raw.size();) {
    size_t end = i + 1;
    while (raw[i] == '$' && end < raw.size() &&
           (absl::ascii_isalnum(raw[end]) || raw[end] == '_')) {
      ++end;
    }
    if (raw[i] != '$' || end == i + 1) {  // plain text, or a lone '$'
      out += raw[i++];
      continue;
    }
    const std::string var(raw.substr(i + 1, end - i - 1));
    const auto it = vars_.find(var);
    if (it == vars_.end()) {
      return Error(n, absl::StrCat("undefined parameter '$", var, "' in ", Describe(n),
                                   " (declare <default name=\"", var,
                                   "\" value=\"...\"/> or pass -D ", var, "=...)"));
    }
    if (out.size() + it->second.size() > kMaxAttributeBytes ||
        it->second.size() > kMaxExpandedBytes - expanded_bytes_) {
      return Error(n, absl::StrCat("'$", var, "' in ", Describe(n), " expands past the limit (",
                                   kMaxAttributeBytes >> 20, " MiB an attribute, ",
                                   kMaxExpandedBytes >> 20, " MiB a scene)"));
    }
    expanded_bytes_ += it->second.size();
    out += it->second;
    i = end;
  }
  return out;
}

absl::StatusOr<std::string> Parser::RequiredAttr(pugi::xml_node n, const char* name) const {
  if (!n.attribute(name)) {
    return Error(n, absl::StrCat("missing attribute '", name, "' on ", Describe(n)));
  }
  return Attr(n, name);
}

absl::Status Parser::CheckAttributes(pugi::xml_node n,
                                     std::initializer_list<absl::string_view> allowed) const {
  for (const pugi::xml_attribute a : n.attributes()) {
    if (!IsOneOf(a.name(), allowed)) {
      return Error(n, absl::StrCat("unexpected attribute '", a.name(), "' on ", Describe(n),
                                   " (allowed: ", absl::StrJoin(allowed, ", "), ")"));
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<double>> Parser::Numbers(pugi::xml_node n, const char* attr) const {
  LOADER_ASSIGN_OR_RETURN(const std::string text, RequiredAttr(n, attr));
  std::vector<double> values;
  for (absl::string_view token :
       absl::StrSplit(text, absl::ByAnyChar(", \t\r\n"), absl::SkipEmpty())) {
    double v = 0;
    if (std::string why = ParseFinite(token, &v); !why.empty()) {
      const std::string where = absl::string_view(attr) == "value"
                                    ? Describe(n)
                                    : absl::StrCat("attribute '", attr, "' of ", Describe(n));
      return Error(n, absl::StrCat(why, " in ", where));
    }
    values.push_back(v);
  }
  return values;
}

absl::StatusOr<double> Parser::Number(pugi::xml_node n, const char* attr) const {
  LOADER_ASSIGN_OR_RETURN(const std::vector<double> v, Numbers(n, attr));
  if (v.size() != 1) {
    return Error(n, absl::StrCat("expected one number in attribute '", attr, "' of ", Describe(n),
                                 ", got ", v.size()));
  }
  return v[0];
}

// value="x, y, z" (or one number if scalar_ok), else attributes x, y, z defaulting to `def`.
absl::StatusOr<std::array<double, 3>> Parser::Xyz(pugi::xml_node n, double def,
                                                  bool scalar_ok) const {
  std::array<double, 3> r = {def, def, def};
  if (n.attribute("value")) {
    LOADER_ASSIGN_OR_RETURN(const std::vector<double> v, Numbers(n, "value"));
    if (v.size() == 1 && scalar_ok) return std::array<double, 3>{v[0], v[0], v[0]};
    if (v.size() != 3) {
      return Error(n, absl::StrCat("expected 3 numbers in ", Describe(n), ", got ", v.size()));
    }
    return std::array<double, 3>{v[0], v[1], v[2]};
  }
  const char* names[3] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    if (n.attribute(names[i])) {
      LOADER_ASSIGN_OR_RETURN(r[i], Number(n, names[i]));
    }
  }
  return r;
}

absl::StatusOr<Mat4> Parser::ParseTransform(pugi::xml_node t) const {
  Mat4 m;
  for (const pugi::xml_node c : t.children()) {
    if (c.type() == pugi::node_pcdata) return Error(c, "unexpected text in <transform>");
    if (c.type() != pugi::node_element) continue;
    const absl::string_view tag = c.name();
    Mat4 step;
    if (tag == "translate" || tag == "scale") {
      LOADER_RETURN_IF_ERROR(CheckAttributes(c, {"x", "y", "z", "value"}));
      const bool scale = tag == "scale";
      LOADER_ASSIGN_OR_RETURN(const auto v, Xyz(c, scale ? 1 : 0, scale));
      step = scale ? Mat4::Scale(v[0], v[1], v[2]) : Mat4::Translate(v[0], v[1], v[2]);
    } else if (tag == "rotate") {
      LOADER_RETURN_IF_ERROR(CheckAttributes(c, {"x", "y", "z", "axis", "value", "angle"}));
      std::array<double, 3> axis;
      if (c.attribute("axis")) {
        LOADER_ASSIGN_OR_RETURN(const std::vector<double> v, Numbers(c, "axis"));
        if (v.size() != 3) return Error(c, "<rotate> axis needs 3 numbers");
        axis = {v[0], v[1], v[2]};
      } else {
        LOADER_ASSIGN_OR_RETURN(axis, Xyz(c, 0, false));
      }
      double angle = 0;
      if (c.attribute("angle")) {
        LOADER_ASSIGN_OR_RETURN(angle, Number(c, "angle"));
      }
      if (axis[0] == 0 && axis[1] == 0 && axis[2] == 0) {
        return Error(c, "<rotate> needs a non-zero axis");
      }
      step = Mat4::Rotate(axis[0], axis[1], axis[2], angle);
    } else if (tag == "matrix") {
      LOADER_RETURN_IF_ERROR(CheckAttributes(c, {"value"}));
      LOADER_ASSIGN_OR_RETURN(const std::vector<double> v, Numbers(c, "value"));
      if (v.size() != 16 && v.size() != 9) {
        return Error(c, absl::StrCat("<matrix> needs 16 numbers (a row-major 4x4) or 9 (3x3), got ",
                                     v.size()));
      }
      const int dim = v.size() == 16 ? 4 : 3;
      for (int i = 0; i < dim; ++i) {
        for (int j = 0; j < dim; ++j) step.m[i][j] = v[i * dim + j];
      }
    } else if (tag == "lookat") {
      LOADER_RETURN_IF_ERROR(CheckAttributes(c, {"origin", "target", "up"}));
      std::array<double, 3> p[3] = {};  // double: origin and target may be far from the origin
      const char* names[3] = {"origin", "target", "up"};
      for (int i = 0; i < 3; ++i) {
        if (i == 2 && !c.attribute("up")) break;
        LOADER_ASSIGN_OR_RETURN(const std::vector<double> v, Numbers(c, names[i]));
        if (v.size() != 3) {
          return Error(c, absl::StrCat("<lookat> ", names[i], " needs 3 numbers, got ", v.size()));
        }
        p[i] = {v[0], v[1], v[2]};
      }
      // The view direction subtracted and normalised in double: a camera far from the origin
      // (1e6, where float steps are 0.06) looking at something near it keeps its direction.
      const double d[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
      const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (!(len > 0)) return Error(c, "<lookat> origin and target coincide");
      const Vec3 dir(static_cast<float>(d[0] / len), static_cast<float>(d[1] / len),
                     static_cast<float>(d[2] / len));
      Vec3 up(static_cast<float>(p[2][0]), static_cast<float>(p[2][1]),
              static_cast<float>(p[2][2]));
      if (!c.attribute("up") || (up.x == 0 && up.y == 0 && up.z == 0)) {
        // Mitsuba's choice (parser.cpp): the first vector of coordinate_system(dir), which is
        // MakeFrame's s (Duff et al. 2017 both).
        Vec3 t;
        MakeFrame(dir, &up, &t);
      }
      if (!(Length(Cross(Normalize(up), dir)) > 1e-6f)) {
        return Error(c, "<lookat> up is zero or parallel to the view direction");
      }
      step = Mat4::LookAt(Vec3(0.0f), dir, up);
      for (int i = 0; i < 3; ++i) step.m[i][3] = p[0][i];  // the camera's position in double
    } else {
      return Error(c, absl::StrCat("unknown transform <", tag,
                                   "> (supported: translate, rotate, scale, matrix, lookat)"));
    }
    m = step * m;  // each new step acts after the previous ones: M = T_n ... T_1
  }
  return m;
}

absl::StatusOr<Params> Parser::Collect(pugi::xml_node obj, absl::string_view kind) {
  LOADER_RETURN_IF_ERROR(CheckAttributes(obj, {"type", "id", "name"}));
  Params p;
  p.node = obj;
  LOADER_ASSIGN_OR_RETURN(const std::string type, Attr(obj, "type"));
  p.what = absl::StrCat(kind, " '", type, "'");
  for (const pugi::xml_node c : obj.children()) LOADER_RETURN_IF_ERROR(AddEntry(p, c, kind));
  return p;
}

absl::Status Parser::AddEntry(Params& p, pugi::xml_node c, absl::string_view kind) {
  if (c.type() == pugi::node_pcdata) return Error(c, absl::StrCat("unexpected text in ", p.what));
  if (c.type() != pugi::node_element) return absl::OkStatus();
  const absl::string_view tag = c.name();
  if (tag == "include") {
    // In an object: an included object is one child (named by the include), an included scene's
    // children are children here.
    LOADER_ASSIGN_OR_RETURN(const pugi::xml_node inc, LoadInclude(c));
    if (absl::string_view(inc.name()) != "scene") return AddEntry(p, inc, kind);
    for (const pugi::xml_node d : inc.children()) {
      if (absl::string_view(d.name()) == "default")
        return Error(d, "a <default> in a file included inside an object is not read");
      LOADER_RETURN_IF_ERROR(AddEntry(p, d, kind));
    }
    return absl::OkStatus();
  }
  Entry e;
  e.node = c;
  if (tag == "spectrum") {
    if (c.attribute("filename") || c.attribute("type")) {
      return Error(c,
                   "spectrum files (filename=) and spectrum plugins (type=) are not read: give "
                   "value=\"...\" (a number or wavelength:value pairs) or an <rgb>");
    }
    LOADER_RETURN_IF_ERROR(CheckAttributes(c, {"name", "value"}));
    e.tag = "spectrum";
    LOADER_ASSIGN_OR_RETURN(e.name, RequiredAttr(c, "name"));
    LOADER_ASSIGN_OR_RETURN(const std::string text, RequiredAttr(c, "value"));
    absl::StatusOr<Vec3> rgb = SpectrumToRgb(text, kind == "emitter");
    if (!rgb.ok()) return Error(c, std::string(rgb.status().message()));
    if (rgb->x < 0 || rgb->y < 0 || rgb->z < 0) {
      Warn(c, absl::StrCat("spectrum '", e.name, "' lies outside sRGB (", rgb->x, ", ", rgb->y,
                           ", ", rgb->z, "): negative parts set to 0, as Mitsuba does"));
      *rgb = Max(*rgb, Vec3(0.0f));
    }
    e.rgb = *rgb;
  } else if (IsPropertyTag(tag)) {
    LOADER_RETURN_IF_ERROR(tag == "transform" ? CheckAttributes(c, {"name"})
                           : IsOneOf(tag, {"point", "vector"})
                               ? CheckAttributes(c, {"name", "value", "x", "y", "z"})
                               : CheckAttributes(c, {"name", "value"}));
    e.tag = std::string(tag);
    LOADER_ASSIGN_OR_RETURN(e.name, RequiredAttr(c, "name"));
  } else if (tag == "ref") {
    LOADER_RETURN_IF_ERROR(CheckAttributes(c, {"id", "name"}));
    LOADER_ASSIGN_OR_RETURN(const std::string id, RequiredAttr(c, "id"));
    auto it = ids_.find(id);
    if (it == ids_.end()) {
      LOADER_RETURN_IF_ERROR(ParseForward(c, id));
      it = ids_.find(id);
    }
    if (it == ids_.end()) {
      return Error(c, absl::StrCat("unknown id '", id,
                                   "' (a <ref> names a bsdf, texture or shapegroup of the "
                                   "scene)"));
    }
    if (it->second.index < 0) {
      return Error(c, absl::StrCat("id '", id, "' names a ", it->second.kind,
                                   "; only bsdfs and textures can be referenced"));
    }
    e.tag = it->second.kind;
    e.ref = it->second.index;
    LOADER_ASSIGN_OR_RETURN(e.name, Attr(c, "name"));
  } else if (IsObjectTag(tag)) {
    e.tag = std::string(tag);
    LOADER_ASSIGN_OR_RETURN(e.name, Attr(c, "name"));
  } else {
    return Error(c, absl::StrCat("unknown element <", tag, "> in ", p.what));
  }
  for (const Entry& other : p.entries) {
    if (!e.name.empty() && other.name == e.name) {
      return Error(c, absl::StrCat("parameter '", e.name, "' given twice in ", p.what,
                                   " (first at ", LineOf(other.node), ")"));
    }
  }
  p.entries.push_back(std::move(e));
  return absl::OkStatus();
}

absl::StatusOr<const Entry*> Parser::Find(Params& p, absl::string_view name,
                                          std::initializer_list<absl::string_view> tags) const {
  if (std::find(p.supported.begin(), p.supported.end(), name) == p.supported.end()) {
    p.supported.emplace_back(name);
  }
  for (Entry& e : p.entries) {
    if (e.name != name) continue;
    if (!IsOneOf(e.tag, tags)) {
      return Error(e.node, absl::StrCat("parameter '", name, "' of ", p.what, " must be <",
                                        absl::StrJoin(tags, "> or <"), ">, not <", e.tag, ">"));
    }
    e.used = true;
    return &e;
  }
  return nullptr;
}

pugi::xml_node Parser::NodeOf(const Params& p, absl::string_view name) const {
  for (const Entry& e : p.entries) {
    if (e.name == name) return e.node;
  }
  return p.node;
}

std::vector<const Entry*> Parser::TakeObjects(Params& p, absl::string_view kind) const {
  std::vector<const Entry*> found;
  for (Entry& e : p.entries) {
    if (e.tag == kind && !e.used) {
      e.used = true;
      found.push_back(&e);
    }
  }
  return found;
}

absl::Status Parser::Finish(const Params& p) const {
  for (const Entry& e : p.entries) {
    if (e.used) continue;
    if (IsPropertyTag(e.node.name())) {
      const std::string supported =
          p.supported.empty() ? "it takes none" : absl::StrJoin(p.supported, ", ");
      return Error(e.node, absl::StrCat("unknown parameter '", e.name, "' for ", p.what,
                                        " (supported: ", supported, ")"));
    }
    return Error(e.node,
                 absl::StrCat("unexpected <", e.node.name(), ">",
                              e.ref >= 0 ? absl::StrCat(" to a ", e.tag) : "", " in ", p.what));
  }
  return absl::OkStatus();
}

absl::StatusOr<float> Parser::GetFloat(Params& p, absl::string_view name, float def) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"float", "integer"}));
  if (e == nullptr) return def;
  LOADER_ASSIGN_OR_RETURN(const double v, Number(e->node, "value"));
  LOADER_RETURN_IF_ERROR(InFloatRange(e->node, {v}));
  return float(v);
}

absl::StatusOr<int> Parser::GetInt(Params& p, absl::string_view name, int def) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"integer"}));
  if (e == nullptr) return def;
  LOADER_ASSIGN_OR_RETURN(std::string text, RequiredAttr(e->node, "value"));
  absl::string_view s = absl::StripAsciiWhitespace(text);
  const bool one_sign = StripOnePlus(&s);
  int v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (!one_sign || s.empty() || ec != std::errc() || end != s.data() + s.size()) {
    return Error(e->node, absl::StrCat("malformed integer '", text, "' in ", Describe(e->node)));
  }
  return v;
}

absl::StatusOr<bool> Parser::GetBool(Params& p, absl::string_view name, bool def) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"boolean"}));
  if (e == nullptr) return def;
  LOADER_ASSIGN_OR_RETURN(const std::string text, RequiredAttr(e->node, "value"));
  const std::string lower = absl::AsciiStrToLower(absl::StripAsciiWhitespace(text));
  if (lower != "true" && lower != "false") {
    return Error(e->node, absl::StrCat("malformed boolean '", text, "' in ", Describe(e->node),
                                       " (expected true or false)"));
  }
  return lower == "true";
}

absl::StatusOr<std::string> Parser::GetString(Params& p, absl::string_view name,
                                              absl::string_view def) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"string"}));
  if (e == nullptr) return std::string(def);
  return RequiredAttr(e->node, "value");
}

absl::StatusOr<Vec3> Parser::GetRgb(Params& p, absl::string_view name, Vec3 def) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"rgb", "float", "integer", "spectrum"}));
  if (e == nullptr) return def;
  if (e->tag == "spectrum") return e->rgb;
  LOADER_ASSIGN_OR_RETURN(const std::vector<double> v, Numbers(e->node, "value"));
  LOADER_RETURN_IF_ERROR(InFloatRange(e->node, v));
  if (v.size() == 1) return Vec3(float(v[0]));
  if (v.size() != 3) {
    return Error(e->node, absl::StrCat("expected 1 or 3 numbers in ", Describe(e->node), ", got ",
                                       v.size()));
  }
  return Vec3(float(v[0]), float(v[1]), float(v[2]));
}

absl::StatusOr<std::optional<Vec3>> Parser::GetVec3(Params& p, absl::string_view name) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"point", "vector"}));
  if (e == nullptr) return std::optional<Vec3>();
  LOADER_ASSIGN_OR_RETURN(const auto v, Xyz(e->node, 0, false));
  LOADER_RETURN_IF_ERROR(InFloatRange(e->node, {v[0], v[1], v[2]}));
  return std::optional<Vec3>(Vec3(float(v[0]), float(v[1]), float(v[2])));
}

absl::StatusOr<std::optional<std::array<double, 3>>> Parser::GetPoint(
    Params& p, absl::string_view name) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"point", "vector"}));
  if (e == nullptr) return std::optional<std::array<double, 3>>();
  LOADER_ASSIGN_OR_RETURN(const auto v, Xyz(e->node, 0, false));
  LOADER_RETURN_IF_ERROR(InFloatRange(e->node, {v[0], v[1], v[2]}));
  return std::optional<std::array<double, 3>>(v);
}

absl::StatusOr<std::optional<Mat4>> Parser::GetTransform(Params& p, absl::string_view name) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"transform"}));
  if (e == nullptr) return std::optional<Mat4>();
  LOADER_ASSIGN_OR_RETURN(const Mat4 m, ParseTransform(e->node));
  return std::optional<Mat4>(m);
}

absl::StatusOr<float> Parser::GetIor(Params& p, absl::string_view name, float def) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"float", "integer", "string"}));
  if (e == nullptr) return def;
  float ior = 0;
  if (e->tag == "string") {
    LOADER_ASSIGN_OR_RETURN(const std::string text, RequiredAttr(e->node, "value"));
    const std::string key = absl::AsciiStrToLower(text);
    std::vector<std::string> names;
    for (const auto& [n, value] : kNamedIors) {
      if (key == n) ior = value;
      names.push_back(n);
    }
    if (ior == 0) {
      return Error(e->node,
                   absl::StrCat("unknown index of refraction '", text,
                                "' (give a number or one of: ", absl::StrJoin(names, ", "), ")"));
    }
  } else {
    LOADER_ASSIGN_OR_RETURN(const double v, Number(e->node, "value"));
    ior = float(v);
  }
  if (!(ior > 0)) return Error(e->node, absl::StrCat(name, " must be positive"));
  return ior;
}

absl::StatusOr<ColorParam> Parser::GetColor(Params& p, absl::string_view name, Vec3 def) {
  LOADER_ASSIGN_OR_RETURN(const Entry* e,
                          Find(p, name, {"rgb", "float", "integer", "spectrum", "texture"}));
  ColorParam color;
  color.value = def;
  if (e != nullptr && e->tag == "texture") {
    if (e->ref >= 0) {
      color.texture = e->ref;
    } else {
      LOADER_ASSIGN_OR_RETURN(color.texture, ParseTexture(e->node));
    }
  } else if (e != nullptr) {
    LOADER_ASSIGN_OR_RETURN(color.value, GetRgb(p, name, def));
  }
  return color;
}

// A file named by a string parameter: relative to the scene folder and inside it, and existing.
absl::StatusOr<std::string> Parser::GetFile(Params& p, absl::string_view name) const {
  LOADER_ASSIGN_OR_RETURN(const Entry* e, Find(p, name, {"string"}));
  if (e == nullptr) return Error(p.node, absl::StrCat(p.what, " needs a '", name, "' parameter"));
  LOADER_ASSIGN_OR_RETURN(const std::string value, RequiredAttr(e->node, "value"));
  LOADER_ASSIGN_OR_RETURN(const FoundFile f, ResolveFile(e->node, value, name));
  return f.full;
}

absl::StatusOr<Parser::FoundFile> Parser::ResolveFile(pugi::xml_node at, const std::string& value,
                                                      absl::string_view what, bool include) const {
  const fs::path rel(value);
  if (value.empty()) return Error(at, absl::StrCat("empty ", what));
  if (rel.has_root_path()) {
    return Error(at, absl::StrCat(what, " '", value,
                                  "' is absolute; file names must be relative to the scene "
                                  "folder and stay inside it"));
  }
  std::vector<fs::path> candidates;
  if (include) {
    for (const SourceFile* f = &FileOf(at); f != nullptr;
         f = f->parent >= 0 ? files_[size_t(f->parent)].get() : nullptr)
      if (!f->rel_dir.empty()) candidates.push_back((f->rel_dir / rel).lexically_normal());
  }
  candidates.push_back(rel.lexically_normal());
  std::vector<std::string> tried;
  for (const fs::path& normal : candidates) {
    if (normal.empty() || *normal.begin() == "..") continue;
    const fs::path full = base_dir_.empty() ? normal : base_dir_ / normal;
    std::error_code ec;
    if (fs::is_regular_file(full, ec)) return FoundFile{full.string(), normal};
    tried.push_back(full.string());
  }
  if (tried.empty()) return Error(at, absl::StrCat(what, " '", value, "' leaves the scene folder"));
  return absl::NotFoundError(
      absl::StrCat(Where(at), "file '", value, "' not found (", absl::StrJoin(tried, ", "), ")"));
}

absl::StatusOr<pugi::xml_node> Parser::LoadInclude(pugi::xml_node inc) {
  if (const auto it = includes_.find(inc.internal_object()); it != includes_.end())
    return it->second;  // read ahead by IndexForward
  LOADER_RETURN_IF_ERROR(CheckAttributes(inc, {"filename", "name"}));
  const SourceFile& from = FileOf(inc);
  if (from.depth + 1 >= kMaxIncludeDepth) {
    return Error(inc, absl::StrCat("<include>s nested ", kMaxIncludeDepth,
                                   " deep (Mitsuba's limit; a file including itself?)"));
  }
  if (files_.size() > kMaxIncludedFiles)
    return Error(inc, absl::StrCat("more than ", kMaxIncludedFiles, " included files"));
  LOADER_ASSIGN_OR_RETURN(const std::string value, RequiredAttr(inc, "filename"));
  LOADER_ASSIGN_OR_RETURN(const FoundFile found, ResolveFile(inc, value, "include filename", true));
  std::error_code ec;
  const uintmax_t size = fs::file_size(found.full, ec);
  if (ec) return Error(inc, absl::StrCat("cannot read included file '", found.full, "'"));
  if (size > kMaxIncludedBytes - included_bytes_) {
    return Error(inc, absl::StrCat("included files would take more than ", kMaxIncludedBytes >> 20,
                                   " MB in all"));
  }
  included_bytes_ += size;
  int parent = 0;
  while (files_[size_t(parent)].get() != &from) ++parent;
  std::ifstream in(found.full, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in) return Error(inc, absl::StrCat("cannot read included file '", found.full, "'"));
  const std::string xml = text.str();
  auto file = std::make_unique<SourceFile>();
  file->path = found.full;
  file->rel_dir = found.rel.parent_path();
  file->depth = from.depth + 1;
  file->parent = parent;
  if (const absl::Status st = file->Load(xml); !st.ok())
    return absl::InvalidArgumentError(
        absl::StrCat(st.message(), " (included at ", Where(inc), ")"));
  pugi::xml_node root = file->doc.document_element();
  files_.push_back(std::move(file));
  if (!root) return Error(inc, absl::StrCat("included file '", found.full, "' has no element"));
  const absl::string_view tag = root.name();
  if (tag != "scene" && !IsObjectTag(tag)) {
    return Error(root,
                 absl::StrCat("an included file holds a <scene> or one object, not <", tag, ">"));
  }
  LOADER_RETURN_IF_ERROR(CheckNesting(root));
  LOADER_RETURN_IF_ERROR(UpgradeOldSyntax(root));
  if (tag == "scene") {
    LOADER_RETURN_IF_ERROR(CheckAttributes(root, {"version"}));
  } else {
    root.remove_attribute("version");
    // Mitsuba names an included object after the include.
    if (const pugi::xml_attribute name = inc.attribute("name")) {
      pugi::xml_attribute own = root.attribute("name");
      if (!own) own = root.append_attribute("name");
      own.set_value(name.value());
    }
  }
  includes_.emplace(inc.internal_object(), root);
  return root;
}

// Elements are read recursively (a bsdf's nested bsdfs, a shapegroup's shapes, the old-syntax
// upgrade): a file nesting thousands deep (an upload to the coordinator) would overflow the
// stack. Real scenes nest a handful of levels; the depth is checked here without recursion.
absl::Status Parser::CheckNesting(pugi::xml_node root) const {
  constexpr int kMaxDepth = 64;
  for (pugi::xml_node n = root.first_child(); n;) {
    int depth = 1;
    for (pugi::xml_node a = n.parent(); a != root; a = a.parent()) ++depth;
    if (n.type() == pugi::node_element && depth > kMaxDepth)
      return Error(n, absl::StrCat("elements nested more than ", kMaxDepth, " deep"));
    if (n.first_child() && depth <= kMaxDepth) {
      n = n.first_child();
      continue;
    }
    while (n && n != root && !n.next_sibling()) n = n.parent();
    if (!n || n == root) break;
    n = n.next_sibling();
  }
  return absl::OkStatus();
}

absl::StatusOr<std::string> Parser::DefaultName(pugi::xml_node d) const {
  LOADER_RETURN_IF_ERROR(CheckAttributes(d, {"name", "value"}));
  const std::string name = d.attribute("name").value();
  if (name.empty() || !d.attribute("value")) return Error(d, "<default> needs a name and a value");
  return name;
}

absl::Status Parser::IndexForward(pugi::xml_node root) {
  for (const pugi::xml_node c : root.children()) {
    const absl::string_view tag = c.name();
    pugi::xml_node object = c;
    if (tag == "include") {
      LOADER_ASSIGN_OR_RETURN(object, LoadInclude(c));
      if (absl::string_view(object.name()) == "scene") {
        // An included scene's <default>s set what is not set yet (the including file's defaults
        // and the -D defines win), before anything in it is parsed.
        for (const pugi::xml_node d : object.children("default")) {
          LOADER_ASSIGN_OR_RETURN(const std::string name, DefaultName(d));
          vars_.try_emplace(name, d.attribute("value").value());
        }
        LOADER_RETURN_IF_ERROR(IndexForward(object));
        continue;
      }
    }
    const absl::string_view kind = object.name();
    if (!object.attribute("id") ||
        !(kind == "bsdf" || kind == "texture" ||
          (kind == "shape" && absl::string_view(object.attribute("type").value()) == "shapegroup")))
      continue;
    const absl::StatusOr<std::string> id = Attr(object, "id");
    if (id.ok() && !id->empty()) forward_.try_emplace(*id, object);  // errors: where it is parsed
  }
  return absl::OkStatus();
}

absl::Status Parser::ParseForward(pugi::xml_node at, const std::string& id) {
  const auto f = forward_.find(id);
  if (f == forward_.end()) return absl::OkStatus();
  const pugi::xml_node target = f->second;
  if (std::find(resolving_.begin(), resolving_.end(), target) != resolving_.end())
    return Error(at, absl::StrCat("circular reference to id '", id, "'"));
  if (parsed_.count(target.internal_object()) != 0) return absl::OkStatus();
  resolving_.push_back(target);
  parsed_.insert(target.internal_object());
  const absl::Status st = ParseTopLevel(target);
  resolving_.pop_back();
  return st;
}

// irrcache: every parameter not read yet, as name -> value text.
absl::StatusOr<std::map<std::string, std::string>> Parser::TakeRestAsText(Params& p) const {
  std::map<std::string, std::string> rest;
  for (Entry& e : p.entries) {
    if (e.used || !IsPropertyTag(e.tag) || e.tag == "transform") continue;
    std::string text;
    if (e.node.attribute("value") || !IsOneOf(e.tag, {"point", "vector"})) {
      LOADER_ASSIGN_OR_RETURN(text, RequiredAttr(e.node, "value"));
    } else {
      LOADER_ASSIGN_OR_RETURN(const auto v, Xyz(e.node, 0, false));
      text = absl::StrJoin(v, ", ");
    }
    rest[e.name] = text;
    e.used = true;
  }
  return rest;
}

absl::Status Parser::RegisterId(pugi::xml_node n, absl::string_view kind, int index) {
  LOADER_ASSIGN_OR_RETURN(const std::string id, Attr(n, "id"));
  if (id.empty()) return absl::OkStatus();
  const auto [it, inserted] = ids_.try_emplace(id, IdInfo{std::string(kind), index, n});
  if (!inserted) {
    return Error(n, absl::StrCat("duplicate id '", id, "' (first defined at ",
                                 LineOf(it->second.node), ")"));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::string> Parser::PluginType(
    pugi::xml_node n, absl::string_view kind,
    std::initializer_list<absl::string_view> supported) const {
  LOADER_ASSIGN_OR_RETURN(const std::string type, RequiredAttr(n, "type"));
  if (!IsOneOf(type, supported)) {
    return Error(n, absl::StrCat("unknown ", kind, " type '", type,
                                 "' (supported: ", absl::StrJoin(supported, ", "), ")"));
  }
  return type;
}

absl::Status Parser::ParseIntegrator(pugi::xml_node n) {
  if (integrator_) {
    return Error(n,
                 absl::StrCat("a second <integrator> (the first is at ", LineOf(integrator_), ")"));
  }
  integrator_ = n;
  // Mitsuba 0.6's other estimators of the same image (global illumination, unbiased or
  // consistent), in upgraded 0.x files: irfarm renders with its own integrator whatever the file
  // names, so these read as `path` (max_depth, rr_depth), with a warning naming the parameters
  // left unread. Mitsuba 3 has none of them: in a 3.x file they are an error, as there.
  const bool old_estimator =
      FileOf(n).upgraded &&
      IsOneOf(n.attribute("type").value(), {"bdpt", "pssmlt", "mlt", "erpt", "photonmapper", "ppm",
                                            "sppm", "ptracer", "volpath_simple"});
  LOADER_ASSIGN_OR_RETURN(
      const std::string type,
      old_estimator ? RequiredAttr(n, "type")
                    : PluginType(n, "integrator",
                                 {"path", "irrcache", "volpath", "prbvolpath", "prb", "direct"}));
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "integrator"));
  IntegratorDesc& d = scene_.integrator;
  // Mitsuba's volumetric and differentiable path tracers render a scene without media (irfarm
  // refuses <medium>) to the same image as `path`, with the same max_depth and rr_depth.
  d.type = type == "irrcache" ? type : "path";
  d.loc = Loc(n);
  if (type == "direct") {
    // Mitsuba's direct illumination integrator: emitters seen and their light after one
    // scattering, which is `path` at max_depth 2 (its Cornell box: 0.1637 0.1139 0.0519 against
    // path at max_depth 2's 0.1644 0.1145 0.0522, within noise). Its sample counts only divide
    // the same estimate differently: read, not used.
    for (const char* name : {"emitter_samples", "bsdf_samples", "shading_samples"}) {
      LOADER_ASSIGN_OR_RETURN(const int v, GetInt(p, name, 1));
      if (v < 0) return Error(NodeOf(p, name), absl::StrCat(name, " must not be negative"));
    }
    d.max_depth = 2;
  } else {
    LOADER_ASSIGN_OR_RETURN(d.max_depth, GetInt(p, "max_depth", -1));
  }
  LOADER_ASSIGN_OR_RETURN(d.rr_depth, GetInt(p, "rr_depth", 5));
  if (d.max_depth < -1) {
    return Error(NodeOf(p, "max_depth"), "max_depth must be -1 (unbounded) or >= 0");
  }
  if (d.rr_depth < 1) return Error(NodeOf(p, "rr_depth"), "rr_depth must be >= 1");
  LOADER_ASSIGN_OR_RETURN(const bool hide_emitters, GetBool(p, "hide_emitters", false));
  if (hide_emitters) {
    return Error(NodeOf(p, "hide_emitters"), "hide_emitters=true is not supported");
  }
  // Mitsuba 0.5's strictNormals: irfarm always checks both normals' sides.
  if (FileOf(n).upgraded) {
    LOADER_RETURN_IF_ERROR(GetBool(p, "strict_normals", false).status());
  }
  if (type == "irrcache") {
    LOADER_ASSIGN_OR_RETURN(d.params, TakeRestAsText(p));
  }
  if (old_estimator) {
    LOADER_ASSIGN_OR_RETURN(const auto unread, TakeRestAsText(p));
    std::vector<std::string> names;
    for (const auto& [name, value] : unread) names.push_back(name);
    Warn(n, absl::StrCat("Mitsuba 0.6 integrator '", type,
                         "' read as path (the same image; irfarm renders with its own integrator)",
                         names.empty() ? "" : "; not read: ", absl::StrJoin(names, ", ")));
  }
  LOADER_RETURN_IF_ERROR(Finish(p));
  return RegisterId(n, "integrator", -1);
}

absl::Status Parser::ParseSensor(pugi::xml_node n) {
  if (sensor_) {
    return Error(n, absl::StrCat("a second <sensor> (the first is at ", LineOf(sensor_),
                                 "); irfarm renders one camera"));
  }
  sensor_ = n;
  LOADER_ASSIGN_OR_RETURN(const std::string sensor_type,
                          PluginType(n, "sensor", {"perspective", "thinlens"}));
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "sensor"));
  CameraDesc& cam = scene_.camera;
  cam.loc = Loc(n);
  LOADER_ASSIGN_OR_RETURN(const Entry* fov_entry, Find(p, "fov", {"float", "integer"}));
  LOADER_ASSIGN_OR_RETURN(const Entry* focal_entry, Find(p, "focal_length", {"string"}));
  if (fov_entry && focal_entry) {
    return Error(focal_entry->node, "give either fov or focal_length, not both");
  }
  // Without fov Mitsuba uses focal_length (35 mm film equivalent, "50mm" by default) on a
  // 36 x 24 mm film, measured along the diagonal.
  double focal_mm = 50;
  if (focal_entry) {
    LOADER_ASSIGN_OR_RETURN(std::string f, GetString(p, "focal_length", "50mm"));
    f = absl::AsciiStrToLower(f);
    if (absl::EndsWith(f, "mm")) f.resize(f.size() - 2);
    if (!absl::SimpleAtod(f, &focal_mm) || !(focal_mm > 0) || !std::isfinite(focal_mm)) {
      return Error(focal_entry->node,
                   absl::StrCat("focal_length must be a positive length such as \"50mm\""));
    }
  }
  float fov = float(2 * std::atan(std::sqrt(36.0 * 36 + 24 * 24) / (2 * focal_mm)) / kDegToRad);
  LOADER_ASSIGN_OR_RETURN(fov, GetFloat(p, "fov", fov));
  // Read by Mitsuba's perspective camera and without effect on its image (a pinhole has no focus;
  // nothing in a scene moves during the shutter): accepted, checked, ignored.
  for (const char* name : {"shutter_open", "shutter_close"}) {
    LOADER_ASSIGN_OR_RETURN(const float v, GetFloat(p, name, 0));
    if (!(v >= 0) || !std::isfinite(v)) {
      return Error(NodeOf(p, name), absl::StrCat(name, " must be finite and not negative"));
    }
  }
  LOADER_ASSIGN_OR_RETURN(std::string axis,
                          GetString(p, "fov_axis", fov_entry != nullptr ? "x" : "diagonal"));
  axis = absl::AsciiStrToLower(axis);
  LOADER_ASSIGN_OR_RETURN(cam.near_clip, GetFloat(p, "near_clip", 0.01f));
  LOADER_ASSIGN_OR_RETURN(cam.far_clip, GetFloat(p, "far_clip", 1e4f));
  // Mitsuba's thinlens: aperture_radius has no default (0 becomes its float epsilon: a pinhole),
  // focus_distance defaults to far_clip.
  LOADER_ASSIGN_OR_RETURN(cam.focus_distance, GetFloat(p, "focus_distance", cam.far_clip));
  if (!(cam.focus_distance >= 0) || !std::isfinite(cam.focus_distance)) {
    return Error(NodeOf(p, "focus_distance"), "focus_distance must be finite and not negative");
  }
  if (sensor_type == "thinlens") {
    if (!Find(p, "aperture_radius", {"float", "integer"}).value_or(nullptr)) {
      return Error(n, "a thinlens sensor needs aperture_radius");
    }
    LOADER_ASSIGN_OR_RETURN(cam.aperture_radius, GetFloat(p, "aperture_radius", 0));
    if (!(cam.aperture_radius >= 0) || !std::isfinite(cam.aperture_radius)) {
      return Error(NodeOf(p, "aperture_radius"), "aperture_radius must be finite and not negative");
    }
    if (!(cam.focus_distance > 0) || !std::isfinite(cam.focus_distance)) {
      return Error(NodeOf(p, "focus_distance"), "focus_distance must be positive and finite");
    }
  }
  if (sensor_type == "perspective") {
    LOADER_ASSIGN_OR_RETURN(cam.principal_x, GetFloat(p, "principal_point_offset_x", 0));
    LOADER_ASSIGN_OR_RETURN(cam.principal_y, GetFloat(p, "principal_point_offset_y", 0));
    if (!std::isfinite(cam.principal_x) || !std::isfinite(cam.principal_y) ||
        std::abs(cam.principal_x) > 1e3f || std::abs(cam.principal_y) > 1e3f) {
      return Error(NodeOf(p, "principal_point_offset_x"),
                   "principal_point_offset_x / _y must be finite fractions of the film");
    }
  }
  LOADER_ASSIGN_OR_RETURN(const std::optional<Mat4> to_world, GetTransform(p, "to_world"));
  cam.to_world = World(to_world);
  // Mitsuba refuses scale (and shear) in the camera's to_world (Transform::has_scale: the rows
  // of its 3 x 3 part orthonormal within 1e-3); a mirror is allowed.
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) {
      double dot = 0;
      for (int k = 0; k < 3; ++k) dot += cam.to_world.m[i][k] * cam.to_world.m[j][k];
      if (!(std::abs(dot - (i == j ? 1.0 : 0.0)) <= 1e-3))  // NaN too
        return Error(NodeOf(p, "to_world"),
                     "scale factors in the camera's to_world are not allowed (Mitsuba refuses "
                     "them too)");
    }
  const std::vector<const Entry*> films = TakeObjects(p, "film");
  const std::vector<const Entry*> samplers = TakeObjects(p, "sampler");
  LOADER_RETURN_IF_ERROR(Finish(p));
  if (films.size() > 1) return Error(films[1]->node, "a sensor has at most one <film>");
  if (samplers.size() > 1) return Error(samplers[1]->node, "a sensor has at most one <sampler>");
  if (films.empty()) {
    Warn(n, "no <film>: using Mitsuba's default hdrfilm, 768 x 576 with a gaussian filter");
  } else {
    LOADER_RETURN_IF_ERROR(ParseFilm(films[0]->node));
  }
  if (!samplers.empty()) LOADER_RETURN_IF_ERROR(ParseSampler(samplers[0]->node));

  if (!(fov > 0 && fov < 180)) {
    return Error(NodeOf(p, "fov"), absl::StrCat("fov must be in (0, 180) degrees, got ", fov));
  }
  // The whole film's aspect (Mitsuba's parse_fov takes film->size()), not a crop window's: a
  // crop renders its part of the full image, at the full image's zoom.
  const int film_w = cam.film_width > 0 ? cam.film_width : cam.width;
  const int film_h = cam.film_height > 0 ? cam.film_height : cam.height;
  const std::optional<double> fov_x = FovX(fov, axis, double(film_w) / film_h);
  if (!fov_x) {
    return Error(NodeOf(p, "fov_axis"), absl::StrCat("unknown fov_axis '", axis,
                                                     "' (supported: x, y, diagonal, smaller, "
                                                     "larger)"));
  }
  cam.fov_x_deg = float(*fov_x);
  if (!(cam.near_clip > 0)) return Error(NodeOf(p, "near_clip"), "near_clip must be positive");
  if (!(cam.far_clip > cam.near_clip)) {
    return Error(NodeOf(p, "far_clip"), "far_clip must be greater than near_clip");
  }
  return RegisterId(n, "sensor", -1);
}

absl::Status Parser::ParseFilm(pugi::xml_node n) {
  LOADER_RETURN_IF_ERROR(PluginType(n, "film", {"hdrfilm"}).status());
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "film"));
  CameraDesc& cam = scene_.camera;
  LOADER_ASSIGN_OR_RETURN(const int film_w, GetInt(p, "width", 768));
  LOADER_ASSIGN_OR_RETURN(const int film_h, GetInt(p, "height", 576));
  // Output format: irfarm always writes float32 RGB OpenEXR; other choices are accepted with a
  // warning (they change the file, not the image).
  LOADER_ASSIGN_OR_RETURN(const std::string file_format, GetString(p, "file_format", "openexr"));
  LOADER_ASSIGN_OR_RETURN(const std::string pixel_format, GetString(p, "pixel_format", "rgb"));
  LOADER_ASSIGN_OR_RETURN(const std::string component_format,
                          GetString(p, "component_format", "float16"));
  LOADER_RETURN_IF_ERROR(GetBool(p, "banner", false).status());
  LOADER_RETURN_IF_ERROR(GetBool(p, "sample_border", false).status());
  if (FileOf(n).upgraded) {  // Mitsuba 0.5/0.6 hdrfilm parameters that Mitsuba 3 no longer has
    LOADER_RETURN_IF_ERROR(GetBool(p, "high_quality_edges", false).status());
    LOADER_RETURN_IF_ERROR(GetBool(p, "attach_log", false).status());
  }
  LOADER_ASSIGN_OR_RETURN(cam.crop_x, GetInt(p, "crop_offset_x", 0));
  LOADER_ASSIGN_OR_RETURN(cam.crop_y, GetInt(p, "crop_offset_y", 0));
  LOADER_ASSIGN_OR_RETURN(cam.width, GetInt(p, "crop_width", film_w));
  LOADER_ASSIGN_OR_RETURN(cam.height, GetInt(p, "crop_height", film_h));
  const std::vector<const Entry*> filters = TakeObjects(p, "rfilter");
  LOADER_RETURN_IF_ERROR(Finish(p));
  if (film_w <= 0 || film_h <= 0) {
    return Error(NodeOf(p, film_w <= 0 ? "width" : "height"),
                 absl::StrCat("film size must be positive, got ", film_w, " x ", film_h));
  }
  // A render keeps several float buffers per pixel (about 50 bytes): 60000 x 60000 ended in an
  // uncaught bad_alloc. 2^28 pixels (16384 x 16384, about 13 GB) is the most a render takes; the
  // coordinator's own limit (--max-film-pixels) is lower by default.
  constexpr int64_t kMaxFilmPixels = int64_t(1) << 28;
  if (int64_t(film_w) * int64_t(film_h) > kMaxFilmPixels) {
    return Error(NodeOf(p, "width"),
                 absl::StrCat("film of ", film_w, " x ", film_h, " pixels is larger than ",
                              kMaxFilmPixels, " pixels (16384 x 16384), the most irfarm renders"));
  }
  if (!IsOneOf(file_format, {"openexr", "exr", "rgbe", "pfm"}))
    return Error(NodeOf(p, "file_format"),
                 absl::StrCat("unknown file_format '", file_format, "' (openexr, rgbe, pfm)"));
  if (file_format != "openexr" && file_format != "exr")
    Warn(NodeOf(p, "file_format"),
         absl::StrCat("file_format '", file_format, "': irfarm writes OpenEXR"));
  if (!IsOneOf(pixel_format, {"rgb", "rgba", "luminance", "luminance_alpha", "xyz", "xyza"}))
    return Error(NodeOf(p, "pixel_format"),
                 absl::StrCat("unknown pixel_format '", pixel_format, "'"));
  if (pixel_format != "rgb")
    Warn(NodeOf(p, "pixel_format"),
         absl::StrCat("pixel_format '", pixel_format, "': irfarm writes rgb"));
  if (!IsOneOf(component_format, {"float16", "float32", "uint32"}))
    return Error(NodeOf(p, "component_format"),
                 absl::StrCat("unknown component_format '", component_format, "'"));
  if (cam.crop_x < 0 || cam.crop_y < 0 || cam.width <= 0 || cam.height <= 0 ||
      int64_t(cam.crop_x) + cam.width > film_w || int64_t(cam.crop_y) + cam.height > film_h) {
    return Error(
        NodeOf(p, "crop_width"),
        absl::StrCat("crop window ", cam.width, " x ", cam.height, " at (", cam.crop_x, ", ",
                     cam.crop_y, ") is not inside the ", film_w, " x ", film_h, " film"));
  }
  cam.film_width = film_w;
  cam.film_height = film_h;
  if (filters.size() > 1) return Error(filters[1]->node, "a film has at most one <rfilter>");
  // No <rfilter>: the default FilterDesc, gaussian with stddev 0.5, as Mitsuba 3.
  if (!filters.empty()) {
    const pugi::xml_node f = filters[0]->node;
    LOADER_ASSIGN_OR_RETURN(
        const std::string type,
        PluginType(f, "rfilter", {"box", "gaussian", "tent", "mitchell", "catmullrom", "lanczos"}));
    LOADER_ASSIGN_OR_RETURN(Params fp, Collect(f, "rfilter"));
    FilterDesc& filter = cam.filter;
    if (type == "mitchell" || type == "catmullrom" || type == "lanczos") {
      // Filters with negative lobes: the film's importance-sampled placement and its per-pixel
      // error estimates need weights >= 0. The gaussian nearest the filter's kernel (least
      // squares, both normalised: stddev 0.448 for mitchell with B = C = 1/3, 0.403 for
      // catmullrom, 0.406 for lanczos with 3 lobes) instead, said once; the parameters are still
      // checked. No positive filter makes their ringing at sharp edges: against Mitsuba's own
      // image with the original filter, cornell-box (256 x 256) differs by relMSE 2.3e-3, 5.1e-3
      // and 1.5e-2 (docs/guide/film-filters.md).
      LOADER_RETURN_IF_ERROR(GetFloat(fp, "B", 1.0f / 3).status());
      LOADER_RETURN_IF_ERROR(GetFloat(fp, "C", 1.0f / 3).status());
      LOADER_RETURN_IF_ERROR(GetInt(fp, "lobes", 3).status());
      const float stddev = type == "mitchell" ? 0.45f : 0.40f;
      Warn(f, absl::StrCat("rfilter '", type, "' is rendered with a gaussian of stddev ", stddev,
                           ": irfarm has no filters with negative lobes (expect differences at "
                           "sharp edges against an image made with '",
                           type, "')"));
      filter = FilterDesc{FilterType::kGaussian, 4 * stddev, stddev};
    } else if (type == "box") {
      filter = FilterDesc{FilterType::kBox, 0.5f, 0.5f};
    } else if (type == "gaussian") {
      LOADER_ASSIGN_OR_RETURN(const float stddev, GetFloat(fp, "stddev", 0.5f));
      if (!(stddev > 0 && std::isfinite(4 * stddev)))
        return Error(NodeOf(fp, "stddev"), "stddev must be positive and finite");
      // Mitsuba cuts the gaussian off at 4 standard deviations (rfilters/gaussian.cpp).
      filter = FilterDesc{FilterType::kGaussian, 4 * stddev, stddev};
    } else {
      LOADER_ASSIGN_OR_RETURN(const float radius, GetFloat(fp, "radius", 1.0f));
      if (!(radius > 0 && std::isfinite(radius)))
        return Error(NodeOf(fp, "radius"), "radius must be positive and finite");
      filter = FilterDesc{FilterType::kTent, radius, 0.5f};
    }
    LOADER_RETURN_IF_ERROR(Finish(fp));
    LOADER_RETURN_IF_ERROR(RegisterId(f, "rfilter", -1));
  }
  return RegisterId(n, "film", -1);
}

absl::Status Parser::ParseSampler(pugi::xml_node n) {
  LOADER_ASSIGN_OR_RETURN(const std::string type,
                          PluginType(n, "sampler",
                                     {"independent", "stratified", "multijitter", "orthogonal",
                                      "ldsampler", "sobol", "halton", "hammersley"}));
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "sampler"));
  LOADER_ASSIGN_OR_RETURN(scene_.camera.spp, GetInt(p, "sample_count", 4));
  LOADER_RETURN_IF_ERROR(GetInt(p, "seed", 0).status());  // irfarm seeds per job and pixel
  if (type != "independent") {
    // Their tuning knobs only change the noise pattern; accepted and ignored like the type.
    LOADER_RETURN_IF_ERROR(GetBool(p, "jitter", true).status());
    LOADER_RETURN_IF_ERROR(GetFloat(p, "strength", 1).status());
    Warn(n, absl::StrCat("sampler '", type, "' treated as independent"));
  }
  LOADER_RETURN_IF_ERROR(Finish(p));
  if (scene_.camera.spp <= 0) {
    return Error(NodeOf(p, "sample_count"), "sample_count must be positive");
  }
  return RegisterId(n, "sampler", -1);
}

// The BsdfParams a BSDF plugin reads its parameters through (see render/bsdfs/registry.h):
// the Parser's getters on this element's Params, recording each value in the BsdfDesc.
class Parser::BsdfReader final : public BsdfParams {
 public:
  BsdfReader(Parser& parser, Params& params, BsdfDesc& desc)
      : parser_(parser), p_(params), d_(desc) {}

  absl::StatusOr<float> Float(absl::string_view name, float def) override {
    LOADER_ASSIGN_OR_RETURN(const float v, parser_.GetFloat(p_, name, def));
    d_.floats[std::string(name)] = v;
    return v;
  }
  absl::StatusOr<bool> Bool(absl::string_view name, bool def) override {
    LOADER_ASSIGN_OR_RETURN(const bool v, parser_.GetBool(p_, name, def));
    d_.floats[std::string(name)] = v ? 1.0f : 0.0f;
    return v;
  }
  absl::StatusOr<std::string> String(absl::string_view name, absl::string_view def) override {
    LOADER_ASSIGN_OR_RETURN(std::string v, parser_.GetString(p_, name, def));
    d_.strings[std::string(name)] = v;
    return v;
  }
  absl::StatusOr<Vec3> Rgb(absl::string_view name, Vec3 def) override {
    LOADER_ASSIGN_OR_RETURN(const Vec3 v, parser_.GetRgb(p_, name, def));
    d_.colors[std::string(name)].value = v;
    return v;
  }
  absl::StatusOr<ColorParam> Color(absl::string_view name, Vec3 def) override {
    LOADER_ASSIGN_OR_RETURN(const ColorParam v, parser_.GetColor(p_, name, def));
    d_.colors[std::string(name)] = v;
    return v;
  }
  absl::StatusOr<float> Ior(absl::string_view name, float def) override {
    LOADER_ASSIGN_OR_RETURN(const float v, parser_.GetIor(p_, name, def));
    d_.floats[std::string(name)] = v;
    return v;
  }
  bool Has(absl::string_view name) const override {
    for (const Entry& e : p_.entries)
      if (e.name == name) return true;
    return false;
  }
  absl::StatusOr<std::vector<int>> NestedBsdfs() override {
    std::vector<int> out;
    for (const Entry* e : parser_.TakeObjects(p_, "bsdf")) {
      if (e->ref >= 0) {
        out.push_back(e->ref);
        continue;
      }
      LOADER_ASSIGN_OR_RETURN(BsdfDesc b, parser_.ParseBsdf(e->node));
      LOADER_ASSIGN_OR_RETURN(const int index, parser_.AddBsdf(e->node, std::move(b)));
      out.push_back(index);
    }
    d_.nested = out;
    return out;
  }
  const BsdfDesc& Nested(int index) const override { return parser_.scene_.bsdfs[size_t(index)]; }
  absl::StatusOr<std::vector<ColorParam>> NestedTextures() override {
    std::vector<ColorParam> out;
    for (const Entry* e : parser_.TakeObjects(p_, "texture")) {
      ColorParam c;
      c.texture = e->ref;
      if (c.texture < 0) {
        LOADER_ASSIGN_OR_RETURN(c.texture, parser_.ParseTexture(e->node));
      }
      out.push_back(c);
    }
    return out;
  }
  absl::Status Error(absl::string_view name, absl::string_view what) const override {
    return parser_.ParamError(p_, name, what);
  }
  BsdfDesc& desc() override { return d_; }

 private:
  Parser& parser_;
  Params& p_;
  BsdfDesc& d_;
};

absl::StatusOr<BsdfDesc> Parser::ParseBsdf(pugi::xml_node n) {
  const DepthGuard depth(*this);
  LOADER_RETURN_IF_ERROR(depth.Check(n));
  LOADER_ASSIGN_OR_RETURN(const std::string type, RequiredAttr(n, "type"));
  const BsdfPlugin* plugin = FindBsdfPlugin(type);
  if (plugin == nullptr) {
    return Error(n, absl::StrCat("unknown bsdf type '", type,
                                 "' (supported: ", absl::StrJoin(BsdfPluginNames(), ", "), ")"));
  }
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "bsdf"));
  BsdfDesc b;
  b.type = type;
  BsdfReader reader(*this, p, b);
  LOADER_RETURN_IF_ERROR(plugin->parse(reader));
  LOADER_RETURN_IF_ERROR(Finish(p));
  LOADER_ASSIGN_OR_RETURN(b.id, Attr(n, "id"));
  b.loc = Loc(n);
  return b;
}

absl::StatusOr<int> Parser::AddBsdf(pugi::xml_node n, BsdfDesc bsdf) {
  const int index = int(scene_.bsdfs.size());
  LOADER_RETURN_IF_ERROR(RegisterId(n, "bsdf", index));
  scene_.bsdfs.push_back(std::move(bsdf));
  return index;
}

// A texture plugin's view of its element's parameters (render/textures/registry.h).
class Parser::TextureReader final : public TextureParams {
 public:
  TextureReader(Parser& parser, Params& params) : parser_(parser), p_(params) {}

  absl::StatusOr<bool> Bool(absl::string_view name, bool def) override {
    return parser_.GetBool(p_, name, def);
  }
  absl::StatusOr<std::string> String(absl::string_view name, absl::string_view def) override {
    return parser_.GetString(p_, name, def);
  }
  absl::StatusOr<Vec3> Rgb(absl::string_view name, Vec3 def) override {
    return parser_.GetRgb(p_, name, def);
  }
  absl::StatusOr<std::string> File(absl::string_view name) override {
    return parser_.GetFile(p_, name);
  }
  absl::Status Error(absl::string_view name, absl::string_view what) const override {
    return parser_.ParamError(p_, name, what);
  }

 private:
  Parser& parser_;
  Params& p_;
};

absl::StatusOr<int> Parser::ParseTexture(pugi::xml_node n) {
  const DepthGuard depth(*this);
  LOADER_RETURN_IF_ERROR(depth.Check(n));
  LOADER_ASSIGN_OR_RETURN(const std::string type, RequiredAttr(n, "type"));
  const TexturePlugin* plugin = FindTexturePlugin(type);
  if (plugin == nullptr) {
    return Error(n, absl::StrCat("unknown texture type '", type,
                                 "' (supported: ", absl::StrJoin(TexturePluginNames(), ", "), ")"));
  }
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "texture"));
  TextureDesc t;
  t.type = type;
  t.loc = Loc(n);
  TextureReader reader(*this, p);
  LOADER_RETURN_IF_ERROR(plugin->parse(reader, &t));
  // to_uv: Mitsuba keeps the upper-left 2 x 2 and the first two rows' translation.
  LOADER_ASSIGN_OR_RETURN(const std::optional<Mat4> to_uv, GetTransform(p, "to_uv"));
  if (to_uv) {
    const auto& m = to_uv->m;
    t.to_uv = {float(m[0][0]), float(m[0][1]), float(m[0][3]),
               float(m[1][0]), float(m[1][1]), float(m[1][3])};
  }
  LOADER_RETURN_IF_ERROR(Finish(p));
  const int index = int(scene_.textures.size());
  LOADER_RETURN_IF_ERROR(RegisterId(n, "texture", index));
  scene_.textures.push_back(std::move(t));
  return index;
}

absl::Status Parser::ParseShapeGroup(pugi::xml_node n) {
  if (shape_sink_) return Error(n, "a shapegroup cannot be nested in another");
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "shape"));
  const std::vector<const Entry*> shapes = TakeObjects(p, "shape");
  LOADER_RETURN_IF_ERROR(Finish(p));
  std::vector<ShapeDesc> group;
  const Mat4 recentre = recentre_;
  recentre_ = Mat4();  // the group's shapes stay in its own space; the instances place them
  shape_sink_ = &group;
  absl::Status status;
  for (const Entry* e : shapes) {
    status = ParseShape(e->node);
    if (!status.ok()) break;
  }
  shape_sink_ = nullptr;
  recentre_ = recentre;
  LOADER_RETURN_IF_ERROR(status);
  groups_.push_back(std::move(group));
  return RegisterId(n, "shapegroup", int(groups_.size()) - 1);
}

absl::Status Parser::ParseInstance(pugi::xml_node n) {
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "shape"));
  LOADER_ASSIGN_OR_RETURN(const std::optional<Mat4> to_world_opt, GetTransform(p, "to_world"));
  const std::vector<const Entry*> refs = TakeObjects(p, "shapegroup");
  LOADER_RETURN_IF_ERROR(Finish(p));
  if (refs.size() != 1 || refs[0]->ref < 0) {
    return Error(n, "an instance needs exactly one <ref> to a shapegroup");
  }
  const Mat4 to_world = World(to_world_opt);
  const double det = to_world.Determinant3();
  if (!(det != 0) || !std::isfinite(det)) {
    return Error(NodeOf(p, "to_world"), "the instance's to_world is singular");
  }
  // Instances are copies (Embree instancing is not used), so a short file could ask for any
  // number of triangles: their total is capped.
  constexpr size_t kMaxInstancedTriangles = size_t{1} << 25;
  for (const ShapeDesc& s : groups_[size_t(refs[0]->ref)]) {
    instanced_triangles_ += s.mesh.indices.size() / 3;
  }
  if (instanced_triangles_ > kMaxInstancedTriangles) {
    return Error(n, absl::StrCat("instances copy more than ", kMaxInstancedTriangles,
                                 " triangles in all (each instance is a copy of its group)"));
  }
  for (ShapeDesc s : groups_[size_t(refs[0]->ref)]) {
    s.loc = Loc(n);
    if (s.type == ShapeType::kSphere) {
      s.center = to_world.ApplyPoint(s.center);
      // Its own frame turns with the instance; its front does not (an instance moves normals with
      // its normal transform, which keeps a sphere's outside outside).
      s.frame = Compose(SphereFrame(to_world), s.frame);
      bool uniform = true;
      s.radius = float(s.radius * SphereScale(to_world, &uniform));
      if (!uniform)
        Warn(n,
             "a sphere's instance scales it unevenly: irfarm keeps it round (radius from the "
             "x scale, as Mitsuba 3 does)");
    } else {
      TransformMesh(to_world, &s.mesh);
      // Mitsuba moves an instance's normals with to_world's normal transform, so a mirrored
      // instance keeps its front: the winding turns with the mirror (the vertex normals already
      // do, in TransformMesh).
      if (det < 0) ReverseWinding(&s.mesh);
    }
    scene_.shapes.push_back(std::move(s));
  }
  return RegisterId(n, "shape", -1);
}

// A shape plugin's view of its element's parameters (render/shapes/registry.h).
class Parser::ShapeReader final : public ShapeParams {
 public:
  ShapeReader(Parser& parser, Params& params) : parser_(parser), p_(params) {}

  absl::StatusOr<float> Float(absl::string_view name, float def) override {
    return parser_.GetFloat(p_, name, def);
  }
  absl::StatusOr<int> Int(absl::string_view name, int def) override {
    return parser_.GetInt(p_, name, def);
  }
  absl::StatusOr<bool> Bool(absl::string_view name, bool def) override {
    return parser_.GetBool(p_, name, def);
  }
  absl::StatusOr<std::optional<std::array<double, 3>>> Point(absl::string_view name) override {
    return parser_.GetPoint(p_, name);
  }
  absl::StatusOr<std::string> File(absl::string_view name) override {
    return parser_.GetFile(p_, name);
  }
  absl::Status Error(absl::string_view name, absl::string_view what) const override {
    return parser_.ParamError(p_, name, what);
  }
  absl::Status ElementError(const absl::Status& s, absl::string_view what) const override {
    return absl::Status(s.code(), absl::StrCat(parser_.Where(p_.node), what, s.message()));
  }

 private:
  Parser& parser_;
  Params& p_;
};

absl::Status Parser::ParseShape(pugi::xml_node n) {
  const DepthGuard depth(*this);
  LOADER_RETURN_IF_ERROR(depth.Check(n));
  LOADER_ASSIGN_OR_RETURN(const std::string type, RequiredAttr(n, "type"));
  if (type == "shapegroup") return ParseShapeGroup(n);
  if (type == "instance") {
    if (shape_sink_) return Error(n, "an instance cannot be part of a shapegroup");
    return ParseInstance(n);
  }
  const ShapePlugin* plugin = FindShapePlugin(type);
  if (plugin == nullptr) {
    std::vector<std::string> names = ShapePluginNames();
    names.emplace_back("shapegroup");
    names.emplace_back("instance");
    return Error(n, absl::StrCat("unknown shape type '", type,
                                 "' (supported: ", absl::StrJoin(names, ", "), ")"));
  }
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "shape"));
  ShapeDesc s;
  LOADER_ASSIGN_OR_RETURN(s.id, Attr(n, "id"));
  s.loc = Loc(n);
  LOADER_ASSIGN_OR_RETURN(const std::optional<Mat4> to_world_opt, GetTransform(p, "to_world"));
  const Mat4 to_world = World(to_world_opt);
  LOADER_ASSIGN_OR_RETURN(s.flip_normals, GetBool(p, "flip_normals", false));
  ShapeReader reader(*this, p);
  LOADER_ASSIGN_OR_RETURN(ShapeGeometry g, plugin->parse(reader));

  const std::vector<const Entry*> emitters = TakeObjects(p, "emitter");
  // (An included emitter too, not only one written in the shape.)
  if (shape_sink_ != nullptr && !emitters.empty()) {
    return Error(emitters[0]->node,
                 "a shape in a shapegroup cannot emit (Mitsuba 3 does not instance emitters)");
  }
  const std::vector<const Entry*> bsdfs = TakeObjects(p, "bsdf");
  if (bsdfs.size() > 1) return Error(bsdfs[1]->node, "a shape has at most one bsdf");
  if (bsdfs.empty()) {
    // Mitsuba 3 gives a shape without a bsdf a diffuse one, reflectance 0.5, or 0 when the shape
    // emits (a lamp reflects nothing unless it says so).
    const bool emits = !emitters.empty();
    int& slot = emits ? default_emitter_bsdf_ : default_bsdf_;
    if (slot < 0) {
      slot = int(scene_.bsdfs.size());
      BsdfDesc b;
      b.type = "diffuse";
      b.colors["reflectance"].value = Vec3(emits ? 0.0f : 0.5f);
      b.loc = Loc(n);
      scene_.bsdfs.push_back(b);
    }
    s.bsdf = slot;
  } else if (bsdfs[0]->ref >= 0) {
    s.bsdf = bsdfs[0]->ref;
  } else {
    LOADER_ASSIGN_OR_RETURN(BsdfDesc b, ParseBsdf(bsdfs[0]->node));
    LOADER_ASSIGN_OR_RETURN(s.bsdf, AddBsdf(bsdfs[0]->node, std::move(b)));
  }
  if (emitters.size() > 1) return Error(emitters[1]->node, "a shape has at most one emitter");
  // An area emitter on a shape with a null bsdf (how Mitsuba's Blender exporter writes every area
  // light) is seen and lights the scene as on any other shape, and rays pass through it: a
  // sphere lamp shows its front's emission and what lies behind (Mitsuba 3.9.1 measured,
  // RenderPropertiesTest.NullBsdfLampsAreSeenAndPassedThrough).
  if (!emitters.empty()) {
    LOADER_ASSIGN_OR_RETURN(s.area_radiance, ParseAreaEmitter(emitters[0]->node));
  }
  LOADER_RETURN_IF_ERROR(Finish(p));

  if (g.sphere) {
    s.type = ShapeType::kSphere;
    const double det = to_world.Determinant3();
    if (det == 0 || !std::isfinite(det))
      return Error(NodeOf(p, "to_world"), "the sphere's to_world is singular or not finite");
    s.center =
        (to_world * Mat4::Translate(g.center[0], g.center[1], g.center[2])).ApplyPoint(Vec3(0.0f));
    bool uniform = true;
    s.radius = float(g.radius * SphereScale(to_world, &uniform));
    s.frame = SphereFrame(to_world);
    // Mitsuba's sphere flips its normals where to_world mirrors (sphere.cpp): it faces inward.
    if (det < 0) s.flip_normals = !s.flip_normals;
    if (!uniform)
      Warn(NodeOf(p, "to_world"),
           "the sphere's to_world scales it unevenly: irfarm keeps it "
           "round (radius from the x scale, as Mitsuba 3 does)");
  } else {
    const Mat4 mesh_to_world = to_world * g.placement;
    s.mesh = std::move(g.mesh);
    TransformMesh(mesh_to_world, &s.mesh);
    if (g.turns_with_mirror && mesh_to_world.Determinant3() < 0) ReverseWinding(&s.mesh);
    s.degenerate_dropped = DropDegenerateTriangles(&s.mesh);
    if (!g.face_normals && s.mesh.normals.empty()) ComputeSmoothNormals(&s.mesh);
    if (!emitters.empty() && g.slice_when_emitting) {
      SliceAlongPrincipalAxis(&s.mesh, std::max<size_t>(64 * (s.mesh.indices.size() / 3), 65536));
      DropDegenerateTriangles(&s.mesh);
    }
    if (s.flip_normals) FlipNormals(&s.mesh);
    if (g.face_normals) s.mesh.normals.clear();
    if (s.degenerate_dropped > 0) {
      Warn(n, absl::StrCat("shape '", s.id, "': dropped ", s.degenerate_dropped,
                           " degenerate triangle(s) (zero area, repeated or non-finite vertices)"));
    }
    if (s.mesh.indices.empty()) {
      Warn(n, absl::StrCat("shape '", s.id, "' has no triangles left and is skipped"));
      return RegisterId(n, "shape", -1);
    }
  }
  (shape_sink_ ? *shape_sink_ : scene_.shapes).push_back(std::move(s));
  return RegisterId(n, "shape", -1);
}

// An emitter plugin's view of its element's parameters (render/emitters/registry.h).
class Parser::EmitterReader final : public EmitterParams {
 public:
  EmitterReader(Parser& parser, Params& params) : parser_(parser), p_(params) {}

  absl::StatusOr<float> Float(absl::string_view name, float def) override {
    return parser_.GetFloat(p_, name, def);
  }
  absl::StatusOr<Vec3> Rgb(absl::string_view name, Vec3 def) override {
    return parser_.GetRgb(p_, name, def);
  }
  absl::StatusOr<std::optional<Vec3>> Vector(absl::string_view name) override {
    return parser_.GetVec3(p_, name);
  }
  absl::StatusOr<std::optional<std::array<double, 3>>> Point(absl::string_view name) override {
    return parser_.GetPoint(p_, name);
  }
  absl::StatusOr<std::optional<Mat4>> Transform(absl::string_view name) override {
    return parser_.GetTransform(p_, name);
  }
  absl::StatusOr<std::string> File(absl::string_view name) override {
    return parser_.GetFile(p_, name);
  }
  Mat4 World(const Mat4& m) const override { return parser_.World(m); }
  absl::Status Error(absl::string_view name, absl::string_view what) const override {
    return parser_.ParamError(p_, name, what);
  }

 private:
  Parser& parser_;
  Params& p_;
};

absl::StatusOr<const EmitterPlugin*> Parser::EmitterPluginOf(pugi::xml_node n) const {
  LOADER_ASSIGN_OR_RETURN(const std::string type, RequiredAttr(n, "type"));
  const EmitterPlugin* plugin = FindEmitterPlugin(type);
  if (plugin == nullptr) {
    return Error(n, absl::StrCat("unknown emitter type '", type,
                                 "' (supported: ", absl::StrJoin(EmitterPluginNames(), ", "), ")"));
  }
  return plugin;
}

absl::StatusOr<EmitterDesc> Parser::ParseEmitterDesc(pugi::xml_node n,
                                                     const EmitterPlugin& plugin) {
  LOADER_ASSIGN_OR_RETURN(Params p, Collect(n, "emitter"));
  EmitterDesc e;
  e.type = plugin.name;
  e.loc = Loc(n);
  EmitterReader reader(*this, p);
  LOADER_RETURN_IF_ERROR(plugin.parse(reader, &e));
  LOADER_RETURN_IF_ERROR(Finish(p));
  LOADER_RETURN_IF_ERROR(RegisterId(n, "emitter", -1));
  return e;
}

absl::StatusOr<Vec3> Parser::ParseAreaEmitter(pugi::xml_node n) {
  LOADER_ASSIGN_OR_RETURN(const EmitterPlugin* plugin, EmitterPluginOf(n));
  if (plugin->kind != EmitterPlugin::Kind::kArea) {
    return Error(n, absl::StrCat("emitter '", plugin->name,
                                 "' cannot be attached to a shape (only 'area' can)"));
  }
  LOADER_ASSIGN_OR_RETURN(const EmitterDesc e, ParseEmitterDesc(n, *plugin));
  return e.radiance;
}

absl::Status Parser::ParseEmitter(pugi::xml_node n) {
  LOADER_ASSIGN_OR_RETURN(const EmitterPlugin* plugin, EmitterPluginOf(n));
  if (plugin->kind == EmitterPlugin::Kind::kArea) {
    return Error(n, absl::StrCat("an ", plugin->name, " emitter must be nested in a <shape>"));
  }
  if (plugin->kind == EmitterPlugin::Kind::kEnvironment) {
    if (environment_) {
      return Error(n, absl::StrCat("a second environment emitter (the first is at ",
                                   LineOf(environment_), ")"));
    }
    environment_ = n;
  }
  LOADER_ASSIGN_OR_RETURN(EmitterDesc e, ParseEmitterDesc(n, *plugin));
  scene_.emitters.push_back(std::move(e));
  return absl::OkStatus();
}

// Mitsuba 0.5 / 0.6 files (<scene version="0.x.y">) are upgraded as Mitsuba 3 does on load
// (its xml.cpp, upgrade_tree): every parameter name (the `name` attribute of anything but
// <default>) goes from camelCase to snake_case (toWorld -> to_world, intIOR -> int_ior,
// sampleCount -> sample_count); <lookAt> becomes <lookat>; a diffuse BSDF's diffuse_reflectance
// becomes its reflectance; and a texture's uoffset, voffset, uscale and vscale become a to_uv
// transform (translate by the offsets, then scale), as Mitsuba 3 builds it.
std::string SnakeCase(absl::string_view s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (absl::ascii_isupper(c) && i > 0) {
      const char prev = s[i - 1];
      const bool next_lower = i + 1 < s.size() && absl::ascii_islower(s[i + 1]);
      if (absl::ascii_islower(prev) || absl::ascii_isdigit(prev) ||
          (absl::ascii_isupper(prev) && next_lower))
        out += '_';
    }
    out += absl::ascii_tolower(c);
  }
  return out;
}

absl::Status Parser::UpgradeOldSyntax(pugi::xml_node root) {
  const std::string version = root.attribute("version").value();
  if (version.empty()) return absl::OkStatus();
  int major = 0;
  const auto [end, ec] = std::from_chars(version.data(), version.data() + version.size(), major);
  if (ec != std::errc() || (end != version.data() + version.size() && *end != '.'))
    return Error(root, absl::StrCat("malformed scene version '", version, "'"));
  if (major >= 2) return absl::OkStatus();
  const_cast<SourceFile&>(FileOf(root)).upgraded = true;  // files_ holds them mutable
  Warn(root, absl::StrCat("scene version ", version,
                          ": upgraded to Mitsuba 3 syntax (camelCase names -> snake_case)"));
  std::vector<pugi::xml_node> stack = {root};
  while (!stack.empty()) {
    pugi::xml_node n = stack.back();
    stack.pop_back();
    for (pugi::xml_node c : n.children()) {
      if (c.type() != pugi::node_element) continue;
      if (absl::string_view(c.name()) == "lookAt") c.set_name("lookat");
      pugi::xml_attribute name = c.attribute("name");
      if (name && absl::string_view(c.name()) != "default") {
        name.set_value(SnakeCase(name.value()).c_str());
        if (absl::string_view(n.name()) == "bsdf" &&
            absl::string_view(n.attribute("type").value()) == "diffuse" &&
            absl::string_view(name.value()) == "diffuse_reflectance")
          name.set_value("reflectance");
      }
      stack.push_back(c);
    }
    // uoffset, voffset, uscale, vscale (snake case already: single words) -> to_uv.
    pugi::xml_node found[4];
    static constexpr const char* kUv[4] = {"uoffset", "voffset", "uscale", "vscale"};
    bool any = false;
    for (pugi::xml_node c : n.children("float"))
      for (int k = 0; k < 4; ++k)
        if (absl::string_view(c.attribute("name").value()) == kUv[k]) found[k] = c, any = true;
    if (!any) continue;
    // The numbers are read here, where a bad one still has its file:line.
    std::string values[4] = {"0", "0", "1", "1"};
    for (int k = 0; k < 4; ++k) {
      if (!found[k]) continue;
      LOADER_ASSIGN_OR_RETURN(const double v, Number(found[k], "value"));
      values[k] = absl::StrFormat("%.17g", v);
      n.remove_child(found[k]);
    }
    pugi::xml_node to_uv = n.append_child("transform");
    to_uv.append_attribute("name") = "to_uv";
    pugi::xml_node translate = to_uv.append_child("translate");
    translate.append_attribute("x") = values[0].c_str();
    translate.append_attribute("y") = values[1].c_str();
    pugi::xml_node scale = to_uv.append_child("scale");
    scale.append_attribute("x") = values[2].c_str();
    scale.append_attribute("y") = values[3].c_str();
  }
  return absl::OkStatus();
}

absl::Status Parser::ParseChildren(pugi::xml_node root) {
  for (const pugi::xml_node c : root.children()) {
    if (c.type() == pugi::node_pcdata) return Error(c, "unexpected text in <scene>");
    if (c.type() != pugi::node_element || absl::string_view(c.name()) == "default") continue;
    if (parsed_.count(c.internal_object()) != 0) continue;  // parsed early for a <ref>
    LOADER_RETURN_IF_ERROR(ParseTopLevel(c));
  }
  return absl::OkStatus();
}

absl::Status Parser::ParseTopLevel(pugi::xml_node c) {
  const DepthGuard depth(*this);
  LOADER_RETURN_IF_ERROR(depth.Check(c));
  const absl::string_view tag = c.name();
  if (tag == "integrator") return ParseIntegrator(c);
  if (tag == "sensor") return ParseSensor(c);
  if (tag == "bsdf") {
    LOADER_ASSIGN_OR_RETURN(BsdfDesc b, ParseBsdf(c));
    return AddBsdf(c, std::move(b)).status();
  }
  if (tag == "texture") return ParseTexture(c).status();
  if (tag == "shape") return ParseShape(c);
  if (tag == "emitter") return ParseEmitter(c);
  if (tag == "include") {
    LOADER_ASSIGN_OR_RETURN(const pugi::xml_node inc, LoadInclude(c));
    if (absl::string_view(inc.name()) != "scene") return ParseTopLevel(inc);
    // Its <default>s were read with it (IndexForward); its children are read here.
    return ParseChildren(inc);
  }
  if (tag == "spectrum") {
    return Error(c,
                 "a <spectrum> outside the object that uses it is not read: give it inside "
                 "that object, as <spectrum name=... value=...> or <rgb>");
  }
  return Error(c, absl::StrCat("unknown element <", tag,
                               "> in <scene> (supported: default, integrator, sensor, bsdf, "
                               "texture, shape, emitter, include)"));
}

absl::StatusOr<SceneDesc> Parser::Parse(const std::string& xml) {
  files_.push_back(std::make_unique<SourceFile>());
  SourceFile& main = *files_[0];
  main.path = path_;
  scene_.path = path_;
  LOADER_RETURN_IF_ERROR(main.Load(xml));
  const pugi::xml_node root = main.doc.document_element();
  if (!root) return absl::InvalidArgumentError(absl::StrCat(path_, ":1: no <scene> element"));
  if (absl::string_view(root.name()) != "scene") {
    return Error(root, absl::StrCat("the root element must be <scene>, not <", root.name(), ">"));
  }
  LOADER_RETURN_IF_ERROR(CheckAttributes(root, {"version"}));
  LOADER_RETURN_IF_ERROR(CheckNesting(root));
  LOADER_RETURN_IF_ERROR(UpgradeOldSyntax(root));

  // <default>s first, so that $name works anywhere; then the -D defines override them.
  std::map<std::string, int> default_lines;
  for (const pugi::xml_node d : root.children("default")) {
    LOADER_ASSIGN_OR_RETURN(const std::string name, DefaultName(d));
    if (const auto [it, inserted] = default_lines.try_emplace(name, Line(d)); !inserted) {
      return Error(d, absl::StrCat("duplicate <default name=\"", name, "\"> (first at line ",
                                   it->second, ")"));
    }
    vars_[name] = d.attribute("value").value();
  }
  for (const auto& [name, value] : options_.defines) vars_[name] = value;

  LOADER_RETURN_IF_ERROR(IndexForward(root));
  LOADER_RETURN_IF_ERROR(ParseChildren(root));
  if (!sensor_) return Error(root, "the scene has no <sensor>");
  return std::move(scene_);
}

// The point a scene is re-centred on (SceneDesc::world_origin), if it is further from the origin
// than kFarFactor times its own size: the centre of its shapes' bounds. Below that, float
// rounding of its coordinates and ray offsets (kOriginOffset times the coordinates' magnitude,
// scene.h) stay under 1.6e-4 of its size; a scene nearer the origin keeps its coordinates
// exactly (no rounding from a shift), so its images do not change.
std::optional<std::array<double, 3>> FarOrigin(const SceneDesc& desc) {
  const Bounds3 b = ShapeBounds(desc);
  if (b.Empty()) return std::nullopt;
  const Vec3 c = b.Center(), d = b.Diagonal();
  const double size = std::sqrt(double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z);
  const double far = std::max(std::abs(c.x), std::max(std::abs(c.y), std::abs(c.z)));
  constexpr double kFarFactor = 16;
  if (!(far > kFarFactor * size) || !std::isfinite(far)) return std::nullopt;
  return std::array<double, 3>{c.x, c.y, c.z};
}

}  // namespace

absl::StatusOr<SceneDesc> LoadSceneString(const std::string& xml, const std::string& path,
                                          const LoadOptions& options) {
  absl::StatusOr<SceneDesc> desc = Parser(path, options).Parse(xml);
  if (!desc.ok()) return desc;
  // Far from the origin: parsed again, re-centred (the first pass's float coordinates are only
  // good enough to choose the centre). Scenes near the origin are parsed once.
  const std::optional<std::array<double, 3>> origin = FarOrigin(*desc);
  if (!origin) return desc;
  Parser recentred(path, options);
  recentred.SetWorldOrigin(*origin);
  return recentred.Parse(xml);
}

absl::StatusOr<SceneDesc> LoadSceneFile(const std::string& path, const LoadOptions& options) {
  std::error_code ec;
  std::ifstream in(path, std::ios::binary);
  if (!fs::is_regular_file(path, ec) || !in) {
    return absl::NotFoundError(absl::StrCat(path, ":0: cannot open scene file"));
  }
  std::ostringstream text;
  text << in.rdbuf();
  return LoadSceneString(text.str(), path, options);
}

}  // namespace irfarm

#undef LOADER_RETURN_IF_ERROR
#undef LOADER_CONCAT_INNER
#undef LOADER_CONCAT
#undef LOADER_ASSIGN_OR_RETURN
#undef LOADER_ASSIGN_OR_RETURN_IMPL
