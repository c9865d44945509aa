// Cache snapshot files: serialisation, validation, atomic writes (see snapshot.h).
#include "cache/snapshot.h"

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace irfarm {
namespace {

constexpr char kMagic[8] = {'I', 'R', 'F', 'S', 'N', 'A', 'P', '\0'};
constexpr uint32_t kRecordBytesV1 = 44;  // version 1: no occluder
constexpr uint32_t kRecordBytes = 56;
constexpr size_t kHeaderBytes = 32;

template <typename T>
void Put(std::string* out, const T& v) {  // the project targets little-endian x86-64 / arm64
  out->append(reinterpret_cast<const char*>(&v), sizeof(T));
}

template <typename T>
T Get(const std::string& in, size_t offset) {
  T v;
  std::memcpy(&v, in.data() + offset, sizeof(T));
  return v;
}

std::string Hex(uint64_t v) {
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

}  // namespace

uint64_t SnapshotChecksum(const char* data, size_t n) {
  uint64_t h = 1469598103934665603ull;  // FNV-1a 64 offset basis and prime
  for (size_t i = 0; i < n; ++i) h = (h ^ static_cast<unsigned char>(data[i])) * 1099511628211ull;
  return h;
}

std::string SerializeSnapshot(const Snapshot& snapshot) {
  std::string out;
  out.reserve(kHeaderBytes + snapshot.records.size() * kRecordBytes + 8);
  out.append(kMagic, sizeof kMagic);
  Put(&out, kSnapshotVersion);
  Put(&out, kRecordBytes);
  Put(&out, snapshot.scene_hash);
  Put(&out, uint64_t(snapshot.records.size()));
  for (const IrradianceRecord& r : snapshot.records) {
    const float v[10] = {r.position.x, r.position.y,   r.position.z,   r.normal.x,     r.normal.y,
                         r.normal.z,   r.irradiance.x, r.irradiance.y, r.irradiance.z, r.radius};
    for (float f : v) Put(&out, f);
    Put(&out, r.origin);
    Put(&out, r.occluder.x);
    Put(&out, r.occluder.y);
    Put(&out, r.occluder.z);
  }
  Put(&out, SnapshotChecksum(out.data(), out.size()));
  return out;
}

absl::StatusOr<Snapshot> ParseSnapshot(const std::string& in, const std::string& name) {
  const auto bad = [&](const std::string& why) {
    return absl::InvalidArgumentError(name + ": not a valid irfarm cache snapshot: " + why);
  };
  if (in.size() < kHeaderBytes + 8) return bad("too short");
  if (std::memcmp(in.data(), kMagic, sizeof kMagic) != 0) return bad("bad magic");
  const uint32_t version = Get<uint32_t>(in, 8);
  if (version != 1 && version != kSnapshotVersion)
    return bad("version " + std::to_string(version) + ", this build reads versions 1 to " +
               std::to_string(kSnapshotVersion));
  const uint32_t record_bytes = version == 1 ? kRecordBytesV1 : kRecordBytes;
  if (Get<uint32_t>(in, 12) != record_bytes) return bad("unexpected record size");
  Snapshot s;
  s.scene_hash = Get<uint64_t>(in, 16);
  const uint64_t count = Get<uint64_t>(in, 24);
  if (count > (in.size() - kHeaderBytes - 8) / record_bytes ||
      in.size() != kHeaderBytes + count * record_bytes + 8)
    return bad("size does not match the record count " + std::to_string(count));
  const size_t body = in.size() - 8;
  if (SnapshotChecksum(in.data(), body) != Get<uint64_t>(in, body)) return bad("checksum mismatch");
  s.records.reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    const size_t o = kHeaderBytes + i * record_bytes;
    float v[10];
    std::memcpy(v, in.data() + o, sizeof v);
    IrradianceRecord r;
    r.position = Vec3(v[0], v[1], v[2]);
    r.normal = Vec3(v[3], v[4], v[5]);
    r.irradiance = Vec3(v[6], v[7], v[8]);
    r.radius = v[9];
    r.origin = Get<uint32_t>(in, o + 40);
    if (version >= 2)
      r.occluder = Vec3(Get<float>(in, o + 44), Get<float>(in, o + 48), Get<float>(in, o + 52));
    if (!IsValidRecord(r)) return bad("record " + std::to_string(i) + " is invalid");
    s.records.push_back(r);
  }
  return s;
}

absl::Status WriteSnapshotFile(const Snapshot& snapshot, const std::string& path) {
  const std::string tmp = path + ".tmp." + std::to_string(getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    const std::string bytes = SerializeSnapshot(snapshot);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    out.flush();
    if (!out) {
      std::remove(tmp.c_str());
      return absl::InternalError(path + ": cannot write snapshot");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    return absl::InternalError(path + ": cannot rename snapshot into place");
  }
  return absl::OkStatus();
}

absl::StatusOr<Snapshot> ReadSnapshotFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(path + ": cannot open snapshot");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ParseSnapshot(ss.str(), path);
}

absl::Status CheckSnapshotScene(const Snapshot& snapshot, uint64_t scene_hash,
                                const std::string& name) {
  if (snapshot.scene_hash == scene_hash) return absl::OkStatus();
  return absl::FailedPreconditionError(
      name + ": snapshot is of another scene, or of other record settings (caustics, direct sun) " +
      "(scene hash " + Hex(snapshot.scene_hash) + ", this render " + Hex(scene_hash) +
      "); refusing to warm-start from it");
}

}  // namespace irfarm
