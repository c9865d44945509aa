// OBJ and PLY readers, built-in shape generators and mesh clean-up for the scene loader
// (see mesh_loader.h). The OBJ reader is hand-written rather than tinyobjloader so that every
// malformed number and every out-of-range index is an error naming its line, never a crash.

#include "render/mesh_loader.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "render/parse_number.h"

namespace irfarm {

absl::StatusOr<std::string> ReadWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open file"));
  std::ostringstream data;
  data << in.rdbuf();
  return data.str();
}

namespace {

absl::Status LineError(const std::string& path, int line, absl::string_view what) {
  return absl::InvalidArgumentError(absl::StrCat(path, ":", line, ": ", what));
}

// One OBJ face corner: 0-based indices into v / vt / vn, -1 = not given.
struct ObjCorner {
  int v = -1, t = -1, n = -1;
  bool operator==(const ObjCorner& o) const { return v == o.v && t == o.t && n == o.n; }
};
struct ObjCornerHash {
  size_t operator()(const ObjCorner& c) const {
    return std::hash<uint64_t>()((uint64_t(uint32_t(c.v)) << 32) ^ (uint64_t(uint32_t(c.t)) << 16) ^
                                 uint64_t(uint32_t(c.n)));
  }
};

// Resolves one OBJ index token (1-based, or negative relative to `count` so far) to 0-based.
// A positive index is checked against the final count later (it may name a later vertex).
std::string ResolveObjIndex(absl::string_view token, int count, int* out) {
  int value = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (token.empty() || ec != std::errc() || end != token.data() + token.size()) {
    return absl::StrCat("malformed index '", token, "'");
  }
  if (value == 0) return "index 0 is invalid (OBJ indices start at 1)";
  if (value < 0 && count + value < 0) {
    return absl::StrCat("relative index ", value, " out of range (", count, " defined so far)");
  }
  *out = value > 0 ? value - 1 : count + value;
  return "";
}

}  // namespace

absl::StatusOr<TriangleMesh> ParseObjMesh(const std::string& text, const std::string& path,
                                          bool flip_v) {
  std::vector<Vec3> v, vn;
  std::vector<std::array<float, 2>> vt;
  std::vector<ObjCorner> corners;  // 3 per triangle
  std::vector<int> triangle_lines;
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_number;
    if (const size_t hash = line.find('#'); hash != absl::string_view::npos) {
      line = line.substr(0, hash);
    }
    std::vector<absl::string_view> tokens =
        absl::StrSplit(line, absl::ByAnyChar(" \t\r\f\v"), absl::SkipEmpty());
    if (tokens.empty()) continue;
    const absl::string_view key = tokens[0];
    if (key == "v" || key == "vn" || key == "vt") {
      const size_t needed = key == "vt" ? 1 : 3;
      if (tokens.size() < needed + 1) {
        return LineError(path, line_number, absl::StrCat("'", key, "' needs ", needed, " numbers"));
      }
      double x[3] = {0, 0, 0};
      for (size_t i = 0; i < 3 && i + 1 < tokens.size(); ++i) {
        if (std::string why = ParseFinite(tokens[i + 1], &x[i]); !why.empty()) {
          return LineError(path, line_number, why);
        }
        // As PLY and .serialized: a value a float cannot hold is refused, not made infinite.
        if (!FitsFloat(x[i])) {
          return LineError(
              path, line_number,
              absl::StrCat("value '", tokens[i + 1], "' is beyond the range of a float"));
        }
      }
      if (key == "v") v.emplace_back(float(x[0]), float(x[1]), float(x[2]));
      if (key == "vn") vn.emplace_back(float(x[0]), float(x[1]), float(x[2]));
      if (key == "vt") vt.push_back({float(x[0]), float(flip_v ? 1 - x[1] : x[1])});
    } else if (key == "f") {
      if (tokens.size() < 4) return LineError(path, line_number, "a face needs 3 or more corners");
      std::vector<ObjCorner> face;
      for (size_t i = 1; i < tokens.size(); ++i) {
        std::vector<absl::string_view> parts = absl::StrSplit(tokens[i], '/');
        if (parts.size() > 3 || parts[0].empty()) {
          return LineError(path, line_number,
                           absl::StrCat("malformed face corner '", tokens[i],
                                        "' (expected a, a/b, a//c or a/b/c)"));
        }
        ObjCorner c;
        const int counts[3] = {int(v.size()), int(vt.size()), int(vn.size())};
        int* fields[3] = {&c.v, &c.t, &c.n};
        for (size_t k = 0; k < parts.size(); ++k) {
          if (k > 0 && parts[k].empty()) continue;
          if (std::string why = ResolveObjIndex(parts[k], counts[k], fields[k]); !why.empty()) {
            return LineError(path, line_number, why);
          }
        }
        face.push_back(c);
      }
      for (size_t i = 1; i + 1 < face.size(); ++i) {
        corners.insert(corners.end(), {face[0], face[i], face[i + 1]});
        triangle_lines.push_back(line_number);
      }
    }
    // Anything else (o, g, s, usemtl, mtllib, l, p, ...) does not change the geometry.
  }

  bool all_uvs = !corners.empty(), all_normals = !corners.empty();
  for (size_t i = 0; i < corners.size(); ++i) {
    const ObjCorner& c = corners[i];
    const char* kinds[3] = {"vertex", "texture coordinate", "normal"};
    const char* plurals[3] = {"vertices", "texture coordinates", "normals"};
    const int values[3] = {c.v, c.t, c.n};
    const size_t counts[3] = {v.size(), vt.size(), vn.size()};
    for (int k = 0; k < 3; ++k) {
      if (values[k] >= int(counts[k])) {
        return LineError(
            path, triangle_lines[i / 3],
            absl::StrCat(kinds[k], " index ", values[k] + 1, " out of range (the file has ",
                         counts[k], " ", plurals[k], ")"));
      }
    }
    all_uvs = all_uvs && c.t >= 0;
    all_normals = all_normals && c.n >= 0;
  }

  TriangleMesh mesh;
  std::unordered_map<ObjCorner, uint32_t, ObjCornerHash> vertex_of;
  mesh.indices.reserve(corners.size());
  for (ObjCorner c : corners) {
    if (!all_uvs) c.t = -1;
    if (!all_normals) c.n = -1;
    auto [it, inserted] = vertex_of.try_emplace(c, uint32_t(mesh.positions.size()));
    if (inserted) {
      mesh.positions.push_back(v[c.v]);
      if (all_normals) mesh.normals.push_back(vn[c.n]);
      if (all_uvs) mesh.uvs.insert(mesh.uvs.end(), {vt[c.t][0], vt[c.t][1]});
    }
    mesh.indices.push_back(it->second);
  }
  return mesh;
}

absl::StatusOr<TriangleMesh> LoadObjMesh(const std::string& path, bool flip_v) {
  absl::StatusOr<std::string> text = ReadWholeFile(path);
  if (!text.ok()) return text.status();
  return ParseObjMesh(*text, path, flip_v);
}

namespace {

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64, kNone };

// The longest list (a face's vertex count) a PLY file may hold.
constexpr int64_t kMaxPlyListLength = int64_t{1} << 31;

PlyType PlyTypeFromName(absl::string_view name) {
  static constexpr std::pair<const char*, PlyType> kNames[] = {
      {"char", PlyType::kInt8},      {"int8", PlyType::kInt8},       {"uchar", PlyType::kUint8},
      {"uint8", PlyType::kUint8},    {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUint16},  {"uint16", PlyType::kUint16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},    {"uint", PlyType::kUint32},     {"uint32", PlyType::kUint32},
      {"float", PlyType::kFloat32},  {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  for (const auto& [n, t] : kNames) {
    if (name == n) return t;
  }
  return PlyType::kNone;
}

int PlyTypeSize(PlyType t) {
  switch (t) {
    case PlyType::kInt8:
    case PlyType::kUint8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUint16:
      return 2;
    case PlyType::kFloat64:
      return 8;
    default:
      return 4;
  }
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kNone;
  PlyType count_type = PlyType::kNone;  // != kNone: a list
};

struct PlyElement {
  std::string name;
  size_t count = 0;
  std::vector<PlyProperty> properties;
};

// Reads scalars from the PLY body, binary (either byte order) or ascii.
class PlyReader {
 public:
  PlyReader(absl::string_view data, bool ascii, bool big_endian)
      : data_(data), ascii_(ascii), big_endian_(big_endian) {}

  bool Read(PlyType type, double* out) {
    if (ascii_) {
      while (pos_ < data_.size() && absl::ascii_isspace(data_[pos_])) ++pos_;
      size_t end = pos_;
      while (end < data_.size() && !absl::ascii_isspace(data_[end])) ++end;
      const absl::string_view token = data_.substr(pos_, end - pos_);
      pos_ = end;
      return !token.empty() && ParseFinite(token, out).empty();
    }
    const int size = PlyTypeSize(type);
    if (data_.size() - pos_ < size_t(size)) return false;
    uint64_t bits = 0;
    for (int i = 0; i < size; ++i) {
      const uint64_t byte = uint8_t(data_[pos_ + (big_endian_ ? i : size - 1 - i)]);
      bits = (bits << 8) | byte;
    }
    pos_ += size;
    switch (type) {
      case PlyType::kInt8:
        *out = int8_t(bits);
        break;
      case PlyType::kUint8:
        *out = uint8_t(bits);
        break;
      case PlyType::kInt16:
        *out = int16_t(bits);
        break;
      case PlyType::kUint16:
        *out = uint16_t(bits);
        break;
      case PlyType::kInt32:
        *out = int32_t(bits);
        break;
      case PlyType::kUint32:
        *out = uint32_t(bits);
        break;
      case PlyType::kFloat32: {
        const uint32_t b32 = uint32_t(bits);
        float f;
        std::memcpy(&f, &b32, 4);
        *out = f;
        break;
      }
      default: {
        double d;
        std::memcpy(&d, &bits, 8);
        *out = d;
        break;
      }
    }
    return true;
  }
  size_t remaining() const { return data_.size() - pos_; }

 private:
  absl::string_view data_;
  bool ascii_, big_endian_;
  size_t pos_ = 0;
};

bool IsIntegerType(PlyType t) { return t != PlyType::kFloat32 && t != PlyType::kFloat64; }

}  // namespace

absl::StatusOr<TriangleMesh> LoadPlyMesh(const std::string& path) {
  absl::StatusOr<std::string> file = ReadWholeFile(path);
  if (!file.ok()) return file.status();
  const absl::string_view text = *file;

  // Header: one statement per line up to end_header.
  std::vector<PlyElement> elements;
  bool ascii = false, big_endian = false, have_format = false;
  size_t pos = 0;
  int line_number = 0;
  for (;;) {
    const size_t eol = text.find('\n', pos);
    if (eol == absl::string_view::npos) return LineError(path, line_number + 1, "no end_header");
    const absl::string_view line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_number;
    std::vector<absl::string_view> tok =
        absl::StrSplit(line, absl::ByAnyChar(" \t\r"), absl::SkipEmpty());
    if (line_number == 1) {
      if (tok.size() != 1 || tok[0] != "ply") return LineError(path, 1, "not a PLY file");
      continue;
    }
    if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info") continue;
    if (tok[0] == "end_header") break;
    if (tok[0] == "format" && tok.size() == 3) {
      ascii = tok[1] == "ascii";
      big_endian = tok[1] == "binary_big_endian";
      if (!ascii && !big_endian && tok[1] != "binary_little_endian") {
        return LineError(path, line_number, absl::StrCat("unknown PLY format '", tok[1], "'"));
      }
      have_format = true;
    } else if (tok[0] == "element" && tok.size() == 3) {
      PlyElement e;
      e.name = std::string(tok[1]);
      const auto [end, ec] = std::from_chars(tok[2].data(), tok[2].data() + tok[2].size(), e.count);
      if (end != tok[2].data() + tok[2].size() || ec != std::errc()) {
        return LineError(path, line_number,
                         absl::StrCat("malformed or out-of-range element count '", tok[2], "'"));
      }
      elements.push_back(e);
    } else if (tok[0] == "property" && !elements.empty() &&
               (tok.size() == 3 || (tok.size() == 5 && tok[1] == "list"))) {
      PlyProperty p;
      const bool list = tok.size() == 5;
      p.name = std::string(tok.back());
      p.type = PlyTypeFromName(tok[list ? 3 : 1]);
      if (list) p.count_type = PlyTypeFromName(tok[2]);
      if (p.type == PlyType::kNone || (list && !IsIntegerType(p.count_type))) {
        return LineError(path, line_number, absl::StrCat("unsupported property '", line, "'"));
      }
      elements.back().properties.push_back(p);
    } else {
      return LineError(path, line_number, absl::StrCat("malformed PLY header line '", line, "'"));
    }
  }
  if (!have_format) return LineError(path, line_number, "PLY header has no format line");

  TriangleMesh mesh;
  PlyReader reader(text.substr(pos), ascii, big_endian);
  const auto truncated = [&](const std::string& what) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": ", what, ": file is truncated or malformed"));
  };
  bool have_vertices = false;
  for (const PlyElement& e : elements) {
    // An element without properties has nothing to read (a count of 1e19 of them looped for ever).
    // Every item of one with properties takes at least a byte, binary or ASCII: a cheap guard
    // against absurd counts before reserving memory.
    if (e.properties.empty()) continue;
    if (e.count > reader.remaining()) return truncated(absl::StrCat("element ", e.name));
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    int slot[8];  // x y z nx ny nz u v -> property index, or -1
    std::fill(std::begin(slot), std::end(slot), -1);
    int face_list = -1;
    for (size_t i = 0; i < e.properties.size(); ++i) {
      const std::string& n = e.properties[i].name;
      static constexpr std::pair<const char*, int> kSlots[] = {
          {"x", 0},         {"y", 1},         {"z", 2},         {"nx", 3},       {"ny", 4},
          {"nz", 5},        {"u", 6},         {"v", 7},         {"s", 6},        {"t", 7},
          {"texture_u", 6}, {"texture_v", 7}, {"texture_s", 6}, {"texture_t", 7}};
      if (is_vertex && e.properties[i].count_type == PlyType::kNone) {
        for (const auto& [name, s] : kSlots) {
          if (n == name) slot[s] = int(i);
        }
      }
      if (is_face && e.properties[i].count_type != PlyType::kNone &&
          (n == "vertex_indices" || n == "vertex_index")) {
        if (!IsIntegerType(e.properties[i].type)) {
          return absl::InvalidArgumentError(absl::StrCat(path, ": ", n, " must be integers"));
        }
        face_list = int(i);
      }
    }
    if (is_vertex && (slot[0] < 0 || slot[1] < 0 || slot[2] < 0)) {
      return absl::InvalidArgumentError(absl::StrCat(path, ": vertex element lacks x, y, z"));
    }
    if (is_face && face_list < 0) {
      return absl::InvalidArgumentError(absl::StrCat(path, ": face element lacks vertex_indices"));
    }
    const bool normals = is_vertex && slot[3] >= 0 && slot[4] >= 0 && slot[5] >= 0;
    const bool uvs = is_vertex && slot[6] >= 0 && slot[7] >= 0;
    std::vector<double> values(e.properties.size());
    std::vector<uint32_t> polygon;
    for (size_t item = 0; item < e.count; ++item) {
      for (size_t i = 0; i < e.properties.size(); ++i) {
        const PlyProperty& p = e.properties[i];
        if (p.count_type == PlyType::kNone) {
          if (!reader.Read(p.type, &values[i])) {
            return truncated(absl::StrCat(e.name, " ", item));
          }
          continue;
        }
        double count = 0;
        if (!reader.Read(p.count_type, &count)) return truncated(absl::StrCat(e.name, " ", item));
        // An ASCII file can write any number where the header says integer; a binary uint32 count
        // can be 4e9. Both are checked before the count becomes a loop bound.
        if (count < 0 || count != std::floor(count) || count > double(kMaxPlyListLength)) {
          return absl::InvalidArgumentError(absl::StrCat(path, ": ", e.name, " ", item,
                                                         ": list of ", count, " entries (0 to ",
                                                         kMaxPlyListLength, " allowed)"));
        }
        polygon.clear();
        for (int64_t k = 0; k < int64_t(count); ++k) {
          double index = 0;
          if (!reader.Read(p.type, &index)) return truncated(absl::StrCat(e.name, " ", item));
          if (int(i) != face_list) continue;
          if (index != std::floor(index)) {  // an ASCII "1.7" is no vertex index
            return absl::InvalidArgumentError(absl::StrCat(path, ": face ", item, ": vertex index ",
                                                           index, " is not a whole number"));
          }
          if (index < 0 || index >= double(mesh.positions.size()) || !have_vertices) {
            return absl::InvalidArgumentError(absl::StrCat(path, ": face ", item, ": vertex index ",
                                                           index, " out of range (the file has ",
                                                           mesh.positions.size(), " vertices)"));
          }
          polygon.push_back(uint32_t(index));
        }
        if (int(i) == face_list) {
          if (polygon.size() < 3) {
            return absl::InvalidArgumentError(
                absl::StrCat(path, ": face ", item, " has ", polygon.size(), " vertices"));
          }
          for (size_t k = 1; k + 1 < polygon.size(); ++k) {
            mesh.indices.insert(mesh.indices.end(), {polygon[0], polygon[k], polygon[k + 1]});
          }
        }
      }
      if (is_vertex) {
        for (const int s : slot) {
          if (s >= 0 && !FitsFloat(values[s])) {
            return absl::InvalidArgumentError(absl::StrCat(path, ": vertex ", item, ": ",
                                                           e.properties[s].name, " = ", values[s],
                                                           " is not a finite 32-bit float"));
          }
        }
        const auto at = [&](int s) { return float(values[slot[s]]); };
        mesh.positions.emplace_back(at(0), at(1), at(2));
        if (normals) mesh.normals.emplace_back(at(3), at(4), at(5));
        if (uvs) mesh.uvs.insert(mesh.uvs.end(), {at(6), at(7)});
      }
    }
    have_vertices = have_vertices || is_vertex;
  }
  return mesh;
}

TriangleMesh MakeRectangleMesh() {
  TriangleMesh mesh;
  mesh.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  mesh.normals.assign(4, Vec3(0, 0, 1));
  mesh.uvs = {0, 0, 1, 0, 1, 1, 0, 1};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  return mesh;
}

TriangleMesh MakeCubeMesh() {
  // Each face: normal n and tangents s, t with cross(s, t) = n, so corners -s-t, s-t, s+t, -s+t
  // run counter-clockwise seen from outside.
  const Vec3 x(1, 0, 0), y(0, 1, 0), z(0, 0, 1);
  const Vec3 faces[6][3] = {{x, y, z}, {-x, z, y}, {y, z, x}, {-y, x, z}, {z, x, y}, {-z, y, x}};
  // Each face's (u, v) as Mitsuba's cube lays them out (cube.cpp's texcoords): the directions in
  // which u and v grow, from 0 to 1 across the face.
  const Vec3 uv_axes[6][2] = {{y, -z}, {y, z}, {-x, -z}, {z, x}, {y, x}, {-y, x}};
  TriangleMesh mesh;
  for (int f = 0; f < 6; ++f) {
    const auto& [n, s, t] = faces[f];
    const auto base = uint32_t(mesh.positions.size());
    const float corner[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (const auto& [a, b] : corner) {
      const Vec3 p = n + s * a + t * b;
      mesh.positions.push_back(p);
      mesh.normals.push_back(n);
      mesh.uvs.insert(mesh.uvs.end(),
                      {(Dot(p - n, uv_axes[f][0]) + 1) / 2, (Dot(p - n, uv_axes[f][1]) + 1) / 2});
    }
    mesh.indices.insert(mesh.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  }
  return mesh;
}

TriangleMesh MakeDiskMesh(int segments) {
  // One centre vertex per segment so the polar uv (r, angle / 2pi) has no seam.
  TriangleMesh mesh;
  for (int i = 0; i <= segments; ++i) {
    const double a = 2 * 3.14159265358979323846 * i / segments;
    mesh.positions.emplace_back(float(std::cos(a)), float(std::sin(a)), 0.0f);
    mesh.uvs.insert(mesh.uvs.end(), {1.0f, float(i) / segments});
  }
  for (int i = 0; i < segments; ++i) {
    const auto center = uint32_t(mesh.positions.size());
    mesh.positions.emplace_back(0.0f, 0.0f, 0.0f);
    mesh.uvs.insert(mesh.uvs.end(), {0.0f, (i + 0.5f) / segments});
    mesh.indices.insert(mesh.indices.end(), {center, uint32_t(i), uint32_t(i + 1)});
  }
  mesh.normals.assign(mesh.positions.size(), Vec3(0, 0, 1));
  return mesh;
}

int SliceAlongPrincipalAxis(TriangleMesh* mesh, size_t max_triangles) {
  TriangleMesh& m = *mesh;
  const std::vector<Vec3>& v = m.positions;
  if (v.empty() || m.indices.empty()) return 0;
  // Connected parts (by shared vertices), each with its own axis: a fixture's two tubes in one
  // file are two parts.
  std::vector<uint32_t> root(v.size());
  for (size_t i = 0; i < root.size(); ++i) root[i] = uint32_t(i);
  const auto find = [&](uint32_t x) {
    while (root[x] != x) x = root[x] = root[root[x]];
    return x;
  };
  for (size_t i = 0; i + 2 < m.indices.size(); i += 3) {
    const uint32_t a = find(m.indices[i]);
    for (int k = 1; k < 3; ++k) root[find(m.indices[i + size_t(k)])] = a;
  }
  std::vector<int> part(v.size(), -1);
  std::unordered_map<uint32_t, int> part_of_root;
  for (size_t i = 0; i < v.size(); ++i)
    part[i] = part_of_root.emplace(find(uint32_t(i)), int(part_of_root.size())).first->second;
  struct Part {
    double c[3] = {0, 0, 0}, total = 0, cov[3][3] = {}, axis[3] = {1, 0, 0}, far = 0;
    double widest = 0, lo = INFINITY, hi = -INFINITY, spacing = 0;
  };
  std::vector<Part> parts(part_of_root.size());
  // Centroid and covariance of each part's surface (triangle centroids by area), not of its
  // vertices: a seam's repeated vertices would pull them aside.
  const auto for_triangles = [&](const auto& f) {
    for (size_t i = 0; i + 2 < m.indices.size(); i += 3) {
      const Vec3 &a = v[m.indices[i]], &b = v[m.indices[i + 1]], &e = v[m.indices[i + 2]];
      f(parts[size_t(part[m.indices[i]])], (a + b + e) / 3.0f,
        0.5 * double(Length(Cross(b - a, e - a))));
    }
  };
  for_triangles([](Part& q, const Vec3& p, double w) {
    for (int k = 0; k < 3; ++k) q.c[k] += w * p[k];
    q.total += w;
  });
  for (Part& q : parts)
    for (double& x : q.c) x = q.total > 0 ? x / q.total : 0.0;
  for_triangles([](Part& q, const Vec3& p, double w) {
    const double d[3] = {p.x - q.c[0], p.y - q.c[1], p.z - q.c[2]};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) q.cov[i][j] += w * d[i] * d[j];
  });
  // Each part's leading eigenvector by power iteration, from the direction of its farthest vertex.
  for (size_t i = 0; i < v.size(); ++i) {
    Part& q = parts[size_t(part[i])];
    const double d[3] = {v[i].x - q.c[0], v[i].y - q.c[1], v[i].z - q.c[2]};
    const double d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if (d2 > q.far) {
      q.far = d2;
      for (int k = 0; k < 3; ++k) q.axis[k] = d[k];
    }
  }
  for (Part& q : parts) {
    for (int it = 0; it < 64; ++it) {
      double next[3] = {0, 0, 0};
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) next[i] += q.cov[i][j] * q.axis[j];
      const double len = std::sqrt(next[0] * next[0] + next[1] * next[1] + next[2] * next[2]);
      if (!(len > 0)) break;
      for (int k = 0; k < 3; ++k) q.axis[k] = next[k] / len;
    }
    const double len =
        std::sqrt(q.axis[0] * q.axis[0] + q.axis[1] * q.axis[1] + q.axis[2] * q.axis[2]);
    for (double& x : q.axis) x = len > 0 ? x / len : 0.0;
  }
  std::vector<double> t(v.size());  // each vertex's coordinate along its part's axis
  for (size_t i = 0; i < v.size(); ++i) {
    Part& q = parts[size_t(part[i])];
    const double d[3] = {v[i].x - q.c[0], v[i].y - q.c[1], v[i].z - q.c[2]};
    t[i] = d[0] * q.axis[0] + d[1] * q.axis[1] + d[2] * q.axis[2];
    q.widest = std::max(q.widest, d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - t[i] * t[i]);
    q.lo = std::min(q.lo, t[i]);
    q.hi = std::max(q.hi, t[i]);
  }
  bool any = false;
  for (Part& q : parts) {
    const double spacing = kCylinderRingRadii * std::sqrt(q.widest);
    q.spacing = q.total > 0 && spacing > 0 && q.hi - q.lo > spacing ? spacing : 0.0;
    any = any || q.spacing > 0;
  }
  if (!any) return 0;
  // Planes at t = j spacing. A triangle's slabs run from floor(min t / s) to floor(max t / s).
  // Counted in double: a part a few float ulps wide (a degenerate strip in a scene file) gives
  // slab counts past any integer type, and the cap must refuse it before a slab index is formed.
  double estimate = 0;
  for (size_t i = 0; i + 2 < m.indices.size(); i += 3) {
    const double spacing = parts[size_t(part[m.indices[i]])].spacing;
    if (!(spacing > 0)) {
      estimate += 1;
      continue;
    }
    const double a = t[m.indices[i]], b = t[m.indices[i + 1]], e = t[m.indices[i + 2]];
    estimate += 3 * (std::floor(std::max({a, b, e}) / spacing) -
                     std::floor(std::min({a, b, e}) / spacing) + 1);
  }
  if (!(estimate <= double(max_triangles))) return 0;
  const bool normals = !m.normals.empty(), uvs = !m.uvs.empty();
  std::map<std::tuple<uint32_t, uint32_t, int64_t>, uint32_t> cuts;  // (edge, plane) -> vertex
  const auto cut = [&](uint32_t a, uint32_t b, int64_t plane, double spacing) {
    const auto key = std::make_tuple(std::min(a, b), std::max(a, b), plane);
    const auto found = cuts.find(key);
    if (found != cuts.end()) return found->second;
    // From the lower-numbered vertex, so both triangles compute the same point.
    const uint32_t p = std::min(a, b), q = std::max(a, b);
    const float f = float((double(plane) * spacing - t[p]) / (t[q] - t[p]));
    const auto id = uint32_t(m.positions.size());
    m.positions.push_back(m.positions[p] + (m.positions[q] - m.positions[p]) * f);
    if (normals) m.normals.push_back(m.normals[p] + (m.normals[q] - m.normals[p]) * f);
    if (uvs) {
      const float u = m.uvs[2 * p] + (m.uvs[2 * q] - m.uvs[2 * p]) * f;
      const float w = m.uvs[2 * p + 1] + (m.uvs[2 * q + 1] - m.uvs[2 * p + 1]) * f;
      m.uvs.insert(m.uvs.end(), {u, w});
    }
    cuts.emplace(key, id);
    return id;
  };
  const size_t before = m.indices.size() / 3;
  std::vector<uint32_t> out;
  struct Point {
    uint32_t vertex;
    int64_t first, last;  // the slabs it bounds
  };
  std::vector<Point> ring;
  std::vector<uint32_t> piece;
  const std::vector<uint32_t> in = m.indices;
  for (size_t i = 0; i + 2 < in.size(); i += 3) {
    const double spacing = parts[size_t(part[in[i]])].spacing;
    ring.clear();
    int64_t kmin = INT64_MAX, kmax = INT64_MIN;
    for (int e = 0; e < 3 && spacing > 0; ++e) {
      const uint32_t a = in[i + size_t(e)], b = in[i + size_t((e + 1) % 3)];
      const double ta = t[a], tb = t[b];
      // The vertex: on plane j it bounds slabs j - 1 and j.
      const double qa = ta / spacing;
      const auto below = int64_t(std::floor(qa));
      ring.push_back({a, qa == double(below) ? below - 1 : below, below});
      kmin = std::min(kmin, below);
      kmax = std::max(kmax, below);
      // The planes strictly between a and b, in order from a.
      if (tb > ta) {
        for (int64_t j = below + 1; double(j) * spacing < tb; ++j)
          ring.push_back({cut(a, b, j, spacing), j - 1, j});
      } else if (tb < ta) {
        for (int64_t j = int64_t(std::ceil(qa)) - 1; double(j) * spacing > tb; --j)
          ring.push_back({cut(a, b, j, spacing), j - 1, j});
      }
    }
    if (!(spacing > 0) || kmin == kmax) {  // not sliced, or within one slab: unchanged
      out.insert(out.end(), {in[i], in[i + 1], in[i + 2]});
      continue;
    }
    for (int64_t k = kmin - 1; k <= kmax; ++k) {
      piece.clear();
      for (const Point& p : ring)
        if (p.first <= k && k <= p.last) piece.push_back(p.vertex);
      for (size_t j = 1; j + 1 < piece.size(); ++j)
        out.insert(out.end(), {piece[0], piece[j], piece[j + 1]});
    }
  }
  m.indices = std::move(out);
  return int(m.indices.size() / 3 - before);
}

int CylinderRings(float length, float radius) {
  const float rings = std::ceil(length / (kCylinderRingRadii * radius));
  return rings >= 1 ? int(std::min(rings, float(kMaxCylinderRings))) : 1;
}

TriangleMesh MakeCylinderMesh(int segments, int rings) {
  TriangleMesh mesh;
  const int columns = rings + 1;
  for (int i = 0; i <= segments; ++i) {
    const double a = 2 * 3.14159265358979323846 * i / segments;
    const float c = float(std::cos(a)), s = float(std::sin(a)), u = float(i) / float(segments);
    for (int r = 0; r <= rings; ++r) {
      const float z = float(r) / float(rings);
      mesh.positions.push_back(Vec3(c, s, z));
      mesh.normals.push_back(Vec3(c, s, 0.0f));
      mesh.uvs.insert(mesh.uvs.end(), {u, z});
    }
  }
  for (int i = 0; i < segments; ++i)
    for (int r = 0; r < rings; ++r) {
      const auto b0 = uint32_t(columns * i + r), t0 = b0 + 1, b1 = b0 + uint32_t(columns),
                 t1 = b1 + 1;
      mesh.indices.insert(mesh.indices.end(), {b0, b1, t1, b0, t1, t0});
    }
  return mesh;
}

void TransformMesh(const Mat4& to_world, TriangleMesh* mesh) {
  for (Vec3& p : mesh->positions) p = to_world.ApplyPoint(p);
  if (mesh->normals.empty()) return;
  double c[3][3];  // once, not per normal
  NormalMatrix(to_world, c);
  for (Vec3& n : mesh->normals) n = ApplyNormalMatrix(c, n);
}

void ReverseWinding(TriangleMesh* mesh) {
  for (size_t i = 0; i + 2 < mesh->indices.size(); i += 3) {
    std::swap(mesh->indices[i + 1], mesh->indices[i + 2]);
  }
}

void FlipNormals(TriangleMesh* mesh) {
  ReverseWinding(mesh);
  for (Vec3& n : mesh->normals) n = -n;
}

int DropDegenerateTriangles(TriangleMesh* mesh) {
  // sin^2 of the angle at the first vertex; 1e-12 is an angle of 1e-6 rad, far below any real
  // triangle and about where float rounding of exactly collinear points ends up.
  constexpr double kMinSin2 = 1e-12;
  std::vector<uint32_t>& idx = mesh->indices;
  size_t kept = 0;
  int dropped = 0;
  for (size_t i = 0; i + 2 < idx.size(); i += 3) {
    const uint32_t a = idx[i], b = idx[i + 1], c = idx[i + 2];
    bool bad = a == b || b == c || a == c;
    if (!bad) {
      const Vec3 &p0 = mesh->positions[a], &p1 = mesh->positions[b], &p2 = mesh->positions[c];
      const double e1[3] = {double(p1.x) - p0.x, double(p1.y) - p0.y, double(p1.z) - p0.z};
      const double e2[3] = {double(p2.x) - p0.x, double(p2.y) - p0.y, double(p2.z) - p0.z};
      const double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                   cz = e1[0] * e2[1] - e1[1] * e2[0];
      const double l1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
      const double l2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
      // Written so that NaN or infinity also counts as degenerate.
      bad = !(IsFinite(p0) && IsFinite(p1) && IsFinite(p2)) ||
            !(cx * cx + cy * cy + cz * cz > kMinSin2 * l1 * l2);
    }
    if (bad) {
      ++dropped;
    } else {
      idx[kept++] = a;
      idx[kept++] = b;
      idx[kept++] = c;
    }
  }
  idx.resize(kept);
  return dropped;
}

void ComputeSmoothNormals(TriangleMesh* mesh) {
  std::vector<Vec3> sum(mesh->positions.size(), Vec3(0.0f));
  const std::vector<uint32_t>& idx = mesh->indices;
  for (size_t i = 0; i + 2 < idx.size(); i += 3) {
    const Vec3 p[3] = {mesh->positions[idx[i]], mesh->positions[idx[i + 1]],
                       mesh->positions[idx[i + 2]]};
    const Vec3 n = Cross(p[1] - p[0], p[2] - p[0]);
    const float length = Length(n);
    if (!(length > 0)) continue;
    for (int j = 0; j < 3; ++j) {
      const Vec3 d0 = Normalize(p[(j + 1) % 3] - p[j]), d1 = Normalize(p[(j + 2) % 3] - p[j]);
      const float angle = std::acos(std::clamp(Dot(d0, d1), -1.0f, 1.0f));
      if (std::isfinite(angle)) sum[idx[i + j]] += n * (angle / length);
    }
  }
  mesh->normals.resize(sum.size());
  for (size_t v = 0; v < sum.size(); ++v) {
    const float length = Length(sum[v]);
    mesh->normals[v] = length > 0 ? sum[v] / length : Vec3(1, 0, 0);
  }
}

}  // namespace irfarm
