// The built scene: Embree geometry (one device, one committed scene), materials, textures,
// lights and the camera, made from a SceneDesc. Answers the renderer's two questions: what does
// this ray hit first (Intersect), and is this segment blocked (Occluded).
//
// Self-intersection: new rays start at the hit point offset along the geometric normal, to the
// side the ray leaves towards, by kOriginOffset times the magnitude of the hit primitive's
// coordinates (the size of float rounding there). No absolute epsilon: a scene scaled by 1e-3
// or 1e4 gets the same relative offsets and so the same image.
#pragma once

#include <embree3/rtcore.h>

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "render/bsdfs/bsdf.h"
#include "render/camera.h"
#include "render/scene_desc.h"
#include "render/texture.h"

namespace irfarm {

constexpr float kOriginOffset = 1e-5f;

struct Ray {
  Vec3 origin, dir;
  float tmax = INFINITY;
};

struct SurfaceHit {
  Vec3 p;              // position, recomputed from barycentrics (triangles) or projected (spheres)
  Vec3 ng;             // unit geometric normal (front side)
  Vec3 ns;             // unit shading normal (front side)
  float u = 0, v = 0;  // texture coordinates
  float t = 0;
  float error_scale = 1;  // magnitude of coordinates around the hit, for ray offsets
  int material = 0;
  int light = -1;  // index into Scene::lights() when the surface emits
  unsigned geom = 0, prim = 0;
};

enum class LightType { kArea, kPoint, kSpot, kDirectional, kConstant, kEnvmap };

struct Light {
  LightType type = LightType::kArea;
  Vec3 radiance;   // area, constant: emitted radiance
  Vec3 intensity;  // point, spot (W/sr); directional: irradiance (W/m^2)
  Vec3 position;   // point, spot
  Vec3 direction;  // directional, spot: direction the light travels
  float cos_cutoff = 0, cos_beam = 0, cutoff = 0, inv_transition = 0;  // spot
  // Area: the emitting geometry and its triangles' cumulative areas (sampling by area).
  unsigned geom = 0;
  bool sphere = false;
  Vec3 center;
  float radius = 0;
  std::vector<float> cdf;
  float area = 0;
  // Envmap
  const Texture* envmap = nullptr;
  Mat4 world_to_env;
  float scale = 1;
  bool IsDelta() const {
    return type == LightType::kPoint || type == LightType::kSpot || type == LightType::kDirectional;
  }
  bool IsEnvironment() const { return type == LightType::kConstant || type == LightType::kEnvmap; }
};

struct LightSample {
  Vec3 wi;                    // unit direction from the shading point to the light
  float distance = INFINITY;  // to the light point (INFINITY for directional / environment)
  Vec3 value;                 // Le * G / pdf, for delta lights I / d^2 (or E) / pselect
  float pdf = 0;              // solid-angle pdf including light selection; 0 for delta lights
  Vec3 light_point, light_normal;
  float light_error_scale = 0;
};

struct SceneStatsCounts {
  long triangles = 0, spheres = 0, degenerate_dropped = 0;
};

class Scene {
 public:
  static absl::StatusOr<std::unique_ptr<Scene>> Build(const SceneDesc& desc);
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  bool Intersect(const Ray& ray, SurfaceHit* hit) const;
  bool Occluded(const Ray& ray) const;

  // A ray leaving hit point `p` (geometric normal ng, error scale s) in direction dir.
  static Ray SpawnRay(const Vec3& p, const Vec3& ng, float s, const Vec3& dir);
  // A shadow ray from the hit to a sampled light; the far end is offset as well.
  static Ray SpawnShadowRay(const SurfaceHit& hit, const LightSample& ls);

  // Samples one light, chosen uniformly, as seen from shading point p; u1 picks the light.
  // With include_env false only local lights (area, point, spot, directional) are chosen: the
  // irradiance cache integrates environment light itself. False when the sample carries nothing.
  bool SampleLight(const Vec3& p, float u1, float u2, float u3, bool include_env,
                   LightSample* s) const;
  // Solid-angle pdf (incl. selection among all lights) of SampleLight having produced the
  // direction wi from p that hits the area light of `hit`, or that escapes (environment).
  float PdfAreaLight(const Vec3& p, const SurfaceHit& hit, const Vec3& wi) const;
  float PdfEnvironment() const;
  int num_local_lights() const { return num_local_; }
  // Radiance from the environment lights (constant + envmap) along direction d.
  Vec3 EvalEnvironment(const Vec3& d) const;
  // Emitted radiance of the surface towards wo (front side only).
  Vec3 Emitted(const SurfaceHit& hit, const Vec3& wo) const;

  const Camera& camera() const { return camera_; }
  const Bsdf& material(int i) const { return *materials_[size_t(i)]; }
  const std::vector<Light>& lights() const { return lights_; }
  bool has_environment() const { return has_env_; }
  const Bounds3& bounds() const { return bounds_; }
  const SceneStatsCounts& counts() const { return counts_; }

 private:
  Scene() = default;
  struct Mesh {
    std::vector<Vec3> positions;  // one padding element at the end (Embree reads 16 bytes)
    std::vector<Vec3> normals;
    std::vector<float> uvs;
    std::vector<uint32_t> indices;
    // Per triangle, precomputed at build: unit geometric normal, the magnitude of its vertices'
    // coordinates (ray-offset scale) and the barycentric inset that keeps hit points a few ray
    // offsets away from its edges (see Intersect).
    struct TriInfo {
      Vec3 ng;
      float error_scale;
      float inset;
    };
    std::vector<TriInfo> tri_info;
    bool sphere = false;
    Vec3 center;
    float radius = 0;
    bool flip = false;
    int material = 0;
    int light = -1;
  };
  bool OccludedPassThrough(Ray ray) const;
  void SampleAreaLight(const Light& l, float u1, float u2, float u3, Vec3* q, Vec3* n,
                       float* scale) const;

  RTCDevice device_ = nullptr;
  RTCScene rtc_scene_ = nullptr;
  std::vector<Mesh> meshes_;  // indexed by Embree geometry id
  std::vector<std::unique_ptr<Texture>> textures_;
  std::vector<std::unique_ptr<Bsdf>> materials_;  // SceneDesc::bsdfs, built
  std::vector<Light> lights_;
  int num_local_ = 0;  // lights_[0, num_local_) are local; the rest are environment lights
  bool has_env_ = false;
  bool has_pass_through_ = false;  // some material lets rays through (mask): see Occluded
  Camera camera_;
  Bounds3 bounds_;
  SceneStatsCounts counts_;
};

}  // namespace irfarm
