// SceneHash: FNV-1a over the record-relevant parts of a SceneDesc (see scene_hash.h).
#include "service/scene_hash.h"

#include <cstring>
#include <fstream>
#include <string>

namespace irfarm {
namespace {

class Hasher {
 public:
  void Bytes(const void* data, size_t n) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) h_ = (h_ ^ p[i]) * 1099511628211ull;
  }
  template <typename T>
  void Pod(const T& v) {
    Bytes(&v, sizeof(T));
  }
  void Str(const std::string& s) {
    Pod(s.size());
    Bytes(s.data(), s.size());
  }
  void V(const Vec3& v) {
    Pod(v.x);
    Pod(v.y);
    Pod(v.z);
  }
  // A file a parameter names (a texture's or an environment map's image): its name without the
  // folder (a scene is hashed the same in the folder a bundle is unpacked to) and its bytes (an
  // image replaced under the same name is another scene). A file that cannot be read adds its
  // name only: the scene does not load then anyway.
  void File(const std::string& path) {
    if (path.empty()) return;
    Str(path.substr(path.find_last_of('/') + 1));
    std::ifstream in(path, std::ios::binary);
    char buf[1 << 16];
    uint64_t n = 0;
    while (in) {
      in.read(buf, sizeof(buf));
      const std::streamsize got = in.gcount();
      if (got <= 0) break;
      Bytes(buf, size_t(got));
      n += uint64_t(got);
    }
    Pod(n);
  }
  uint64_t value() const { return h_; }

 private:
  uint64_t h_ = 1469598103934665603ull;
};

}  // namespace

uint64_t SceneHash(const SceneDesc& desc) {
  Hasher h;
  h.Pod(desc.integrator.max_depth);
  h.Pod(desc.integrator.rr_depth);
  for (const TextureDesc& t : desc.textures) {
    h.Str(t.type);
    h.File(t.filename);
    h.Pod(t.raw);
    h.Str(t.filter_type);
    h.Str(t.wrap_mode);
    h.V(t.color0);
    h.V(t.color1);
    h.Pod(t.to_uv);
  }
  for (const BsdfDesc& b : desc.bsdfs) {  // every parameter, in name order (std::map)
    h.Str(b.type);
    for (const auto& [name, v] : b.floats) {
      h.Str(name);
      h.Pod(v);
    }
    for (const auto& [name, v] : b.strings) {
      h.Str(name);
      h.Str(v);
    }
    for (const auto& [name, c] : b.colors) {
      h.Str(name);
      h.V(c.value);
      h.Pod(c.texture);
    }
    h.Pod(b.nested.size());
    for (const int i : b.nested) h.Pod(i);
  }
  for (const ShapeDesc& s : desc.shapes) {
    h.Pod(int(s.type));
    h.Pod(s.mesh.positions.size());
    for (const Vec3& p : s.mesh.positions) h.V(p);
    for (const Vec3& n : s.mesh.normals) h.V(n);
    h.Pod(s.mesh.indices.size());
    if (!s.mesh.indices.empty())
      h.Bytes(s.mesh.indices.data(), s.mesh.indices.size() * sizeof(uint32_t));
    // Texture coordinates: the textures records see are where they put them.
    h.Pod(s.mesh.uvs.size());
    if (!s.mesh.uvs.empty()) h.Bytes(s.mesh.uvs.data(), s.mesh.uvs.size() * sizeof(float));
    h.V(s.center);
    h.Pod(s.radius);
    h.Pod(s.frame);
    h.Pod(s.flip_normals);
    h.Pod(s.bsdf);
    h.Pod(s.area_radiance.has_value());
    if (s.area_radiance) h.V(*s.area_radiance);
  }
  for (const EmitterDesc& e : desc.emitters) {
    h.Str(e.type);
    h.V(e.position);
    h.V(e.direction);
    h.V(e.intensity);
    h.V(e.irradiance);
    h.V(e.radiance);
    h.Pod(e.cutoff_angle_deg);
    h.Pod(e.beam_width_deg);
    h.File(e.filename);
    h.Pod(e.scale);
    h.Pod(e.to_world);  // an environment map's rotation (where its sun is)
  }
  return h.value();
}

uint64_t CacheHash(uint64_t scene_hash, bool caustics, bool direct_sun) {
  if (caustics && direct_sun) return scene_hash;
  Hasher h;
  h.Pod(scene_hash);
  h.Pod(caustics);
  h.Pod(direct_sun);
  return h.value();
}

}  // namespace irfarm
