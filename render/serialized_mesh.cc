#include "render/serialized_mesh.h"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "absl/strings/str_cat.h"
#include "render/mesh_loader.h"
#include "render/parse_number.h"

namespace irfarm {
namespace {

constexpr uint16_t kMagic = 0x041C;
// The face-normals flag (0x10) is not read: Mitsuba 3 ignores it too (only the shape's
// face_normals parameter counts), and its images are the reference.
constexpr uint32_t kHasNormals = 0x0001, kHasUvs = 0x0002, kHasColors = 0x0008, kSingle = 0x1000,
                   kDouble = 0x2000;
// A mesh's name in version 4 is NUL-terminated; one longer than this is taken for damage.
constexpr size_t kMaxNameLength = 1 << 16;
// Values read per block: the arrays grow block by block as the stream delivers them.
constexpr size_t kBlockValues = 1 << 16;

// The little-endian unsigned integer at p (the format's byte order, whatever the machine's).
template <typename T>
T LittleEndian(const unsigned char* p) {
  T v = 0;
  for (size_t i = 0; i < sizeof(T); ++i) v |= T(p[i]) << (8 * i);
  return v;
}
template <typename T>
T LittleEndian(const std::string& bytes, size_t at) {
  return LittleEndian<T>(reinterpret_cast<const unsigned char*>(bytes.data()) + at);
}

// Exactly-sized reads from one zlib stream that starts at a given byte of the file.
class Inflater {
 public:
  Inflater(const std::string& bytes, size_t start) {
    zs_.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data() + start));
    zs_.avail_in = uInt(std::min<size_t>(bytes.size() - start, std::numeric_limits<uInt>::max()));
    ready_ = inflateInit(&zs_) == Z_OK;
  }
  ~Inflater() {
    if (ready_) inflateEnd(&zs_);
  }
  Inflater(const Inflater&) = delete;
  Inflater& operator=(const Inflater&) = delete;

  // Reads n bytes into dst; on failure returns false and `error()` says why.
  bool Read(void* dst, size_t n) {
    if (!ready_) {
      error_ = "cannot start zlib";
      return false;
    }
    auto* out = static_cast<Bytef*>(dst);
    while (n > 0) {
      if (ended_) {
        error_ = "the compressed data ends early";
        return false;
      }
      const uInt chunk = uInt(std::min<size_t>(n, 1u << 30));
      zs_.next_out = out;
      zs_.avail_out = chunk;
      const int r = inflate(&zs_, Z_NO_FLUSH);
      const size_t got = chunk - zs_.avail_out;
      out += got;
      n -= got;
      if (r == Z_STREAM_END) {
        ended_ = true;
      } else if (r != Z_OK) {
        error_ =
            r == Z_BUF_ERROR
                ? "the file ends inside the compressed data"
                : absl::StrCat("corrupt compressed data (zlib: ", zs_.msg ? zs_.msg : "error", ")");
        return false;
      } else if (got == 0 && zs_.avail_in == 0) {
        error_ = "the file ends inside the compressed data";
        return false;
      }
    }
    return true;
  }
  template <typename T>
  bool Read(T* v) {
    unsigned char b[sizeof(T)];
    if (!Read(b, sizeof(T))) return false;
    *v = LittleEndian<T>(b);
    return true;
  }
  // Reads on to the stream's end, which checks its Adler-32 checksum: a damaged stream can
  // inflate to wrong values without an error before it.
  bool Finish() {
    unsigned char scratch[4096];
    while (!ended_) {
      zs_.next_out = scratch;
      zs_.avail_out = sizeof scratch;
      const int r = inflate(&zs_, Z_NO_FLUSH);
      if (r == Z_STREAM_END) {
        ended_ = true;
      } else if (r != Z_OK || (zs_.avail_out == sizeof scratch && zs_.avail_in == 0)) {
        error_ =
            r == Z_DATA_ERROR
                ? absl::StrCat("corrupt compressed data (zlib: ", zs_.msg ? zs_.msg : "error", ")")
                : "the file ends inside the compressed data";
        return false;
      }
    }
    return true;
  }
  const std::string& error() const { return error_; }

 private:
  z_stream zs_{};
  bool ready_ = false, ended_ = false;
  std::string error_;
};

}  // namespace

absl::StatusOr<TriangleMesh> ParseSerializedMesh(const std::string& bytes, const std::string& path,
                                                 int shape_index) {
  const std::string where = absl::StrCat(path, ": mesh ", shape_index, ": ");
  const auto bad = [&](absl::string_view what) {
    return absl::InvalidArgumentError(absl::StrCat(where, what));
  };
  if (bytes.size() < 4 || LittleEndian<uint16_t>(bytes, 0) != kMagic) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": not a Mitsuba serialized mesh (no 0x041C header)"));
  }
  const uint16_t version = LittleEndian<uint16_t>(bytes, 2);
  if (version != 3 && version != 4) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": serialized mesh version ", version, " (3 and 4 are read)"));
  }
  if (shape_index < 0) return bad("shape_index must not be negative");
  size_t start = 0;
  if (shape_index > 0) {
    // The end-of-file dictionary: offsets of every mesh, then their count.
    if (bytes.size() < 8) return bad("the file is too short for its table of meshes");
    const uint32_t count = LittleEndian<uint32_t>(bytes, bytes.size() - 4);
    if (uint32_t(shape_index) >= count) {
      return bad(absl::StrCat("out of range: the file's table lists ", count, " mesh(es)"));
    }
    const size_t entry = version == 4 ? 8 : 4;
    const uint64_t back = uint64_t(count - uint32_t(shape_index)) * entry + 4;
    if (back > bytes.size()) return bad("the file is too short for its table of meshes");
    const size_t at = bytes.size() - size_t(back);
    const uint64_t offset =
        version == 4 ? LittleEndian<uint64_t>(bytes, at) : LittleEndian<uint32_t>(bytes, at);
    if (offset > bytes.size() - 4 || LittleEndian<uint16_t>(bytes, size_t(offset)) != kMagic) {
      return bad(absl::StrCat("the table's offset ", offset, " is not the start of a mesh"));
    }
    start = size_t(offset);
  }
  Inflater in(bytes, start + 4);
  const auto broken = [&] { return bad(in.error()); };
  uint32_t flags = 0;
  if (!in.Read(&flags)) return broken();
  if ((flags & kSingle) && (flags & kDouble)) return bad("flags say both single and double");
  const bool dp = (flags & kDouble) != 0;
  if (version == 4) {
    size_t length = 0;
    for (char c = 1; c != 0; ++length) {
      if (length > kMaxNameLength) return bad("the mesh's name does not end");
      if (!in.Read(&c, 1)) return broken();
    }
  }
  uint64_t vertices = 0, triangles = 0;
  if (!in.Read(&vertices) || !in.Read(&triangles)) return broken();
  // Indices are uint32 (Mitsuba 3 reads no other), so there are fewer than 2^32 vertices.
  if (vertices > std::numeric_limits<uint32_t>::max() ||
      triangles > std::numeric_limits<uint32_t>::max() / 3) {
    return bad(absl::StrCat(vertices, " vertices and ", triangles,
                            " triangles: more than 32-bit indices can hold"));
  }

  // `n` values of the file's precision, converted to float; each must be finite as a float.
  // Read a block at a time (one inflate call per value would dominate a large mesh's load).
  std::vector<unsigned char> block;
  const auto read_values = [&](uint64_t n, const char* what, std::vector<float>* out) {
    const size_t size = dp ? 8 : 4;
    out->reserve(size_t(std::min<uint64_t>(n, kBlockValues)));
    for (uint64_t done = 0; done < n;) {
      const size_t m = size_t(std::min<uint64_t>(n - done, kBlockValues));
      block.resize(m * size);
      if (!in.Read(block.data(), block.size())) return broken();
      for (size_t i = 0; i < m; ++i) {
        double v = 0;
        if (dp) {
          const uint64_t u = LittleEndian<uint64_t>(&block[8 * i]);
          std::memcpy(&v, &u, sizeof v);
        } else {
          const uint32_t u = LittleEndian<uint32_t>(&block[4 * i]);
          float f = 0;
          std::memcpy(&f, &u, sizeof f);
          v = f;
        }
        if (!FitsFloat(v)) {
          return bad(
              absl::StrCat(what, " value ", done + i, " is ", v, ": not a finite 32-bit float"));
        }
        out->push_back(float(v));
      }
      done += m;
    }
    return absl::OkStatus();
  };
  const auto to_vec3 = [](const std::vector<float>& v, std::vector<Vec3>* out) {
    out->resize(v.size() / 3);
    for (size_t i = 0; i < out->size(); ++i) (*out)[i] = Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
  };

  TriangleMesh mesh;
  std::vector<float> values;
  if (absl::Status st = read_values(3 * vertices, "position", &values); !st.ok()) return st;
  to_vec3(values, &mesh.positions);
  values.clear();
  if (flags & kHasNormals) {
    if (absl::Status st = read_values(3 * vertices, "normal", &values); !st.ok()) return st;
    to_vec3(values, &mesh.normals);
    values.clear();
  }
  if (flags & kHasUvs) {
    if (absl::Status st = read_values(2 * vertices, "uv", &mesh.uvs); !st.ok()) return st;
  }
  if (flags & kHasColors) {  // skipped, as Mitsuba 3 does
    if (absl::Status st = read_values(3 * vertices, "colour", &values); !st.ok()) return st;
    values.clear();
  }
  mesh.indices.reserve(size_t(std::min<uint64_t>(3 * triangles, kBlockValues)));
  for (uint64_t done = 0; done < 3 * triangles;) {
    const size_t m = size_t(std::min<uint64_t>(3 * triangles - done, kBlockValues));
    block.resize(4 * m);
    if (!in.Read(block.data(), block.size())) return broken();
    for (size_t i = 0; i < m; ++i) {
      const uint32_t index = LittleEndian<uint32_t>(&block[4 * i]);
      if (index >= vertices) {
        return bad(absl::StrCat("triangle ", (done + i) / 3, ": vertex index ", index,
                                " out of range (the mesh has ", vertices, " vertices)"));
      }
      mesh.indices.push_back(index);
    }
    done += m;
  }
  if (!in.Finish()) return broken();
  return mesh;
}

absl::StatusOr<TriangleMesh> LoadSerializedMesh(const std::string& path, int shape_index) {
  absl::StatusOr<std::string> bytes = ReadWholeFile(path);
  if (!bytes.ok()) return bytes.status();
  return ParseSerializedMesh(*bytes, path, shape_index);
}

}  // namespace irfarm
