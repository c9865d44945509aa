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
#include "core/ray.h"
#include "render/bsdfs/bsdf.h"
#include "render/camera.h"
#include "render/environment_sun.h"
#include "render/light_sampler.h"
#include "render/scene_desc.h"
#include "render/texture.h"

namespace irfarm {

constexpr float kOriginOffset = 1e-5f;

struct SurfaceHit {
  Vec3 p;              // position, recomputed from barycentrics (triangles) or projected (spheres)
  Vec3 ng;             // unit geometric normal (front side)
  Vec3 ns;             // unit shading normal (front side)
  float u = 0, v = 0;  // texture coordinates
  Vec3 dpdu, dpdv;     // tangents: world-space change of p per unit u and v (Mitsuba's dp_du)
  float t = 0;
  float error_scale = 1;  // magnitude of coordinates around the hit, for ray offsets
  int material = 0;
  int light = -1;  // index into Scene::lights() when the surface emits
  unsigned geom = 0, prim = 0;
  // The BSDF's local frame at the hit, and what the BSDF needs of the hit.
  ShadingFrame Frame() const { return ShadingFrame(ns, dpdu); }
  BsdfContext Context() const { return BsdfContext{u, v, ns, dpdu, dpdv}; }
};

// One ray a Scene traced, for benchmarks that replay a renderer's own rays as bare Embree calls
// (bench_record): Intersect's closest-hit rays and Occluded's shadow rays.
struct TracedRay {
  Ray ray;
  bool shadow = false;
};

struct SceneStatsCounts {
  long triangles = 0, spheres = 0, degenerate_dropped = 0;
};

// What Scene::Build precomputes beyond the geometry and the lights.
struct SceneBuildOptions {
  // Learn where the environment is seen from (EnvironmentGuide), so that environment samples
  // aim at the windows; off: every environment sample comes from the unguided mixture.
  bool environment_guide = true;
};

class Scene {
 public:
  static absl::StatusOr<std::unique_ptr<Scene>> Build(const SceneDesc& desc,
                                                      const SceneBuildOptions& options = {});
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  bool Intersect(const Ray& ray, SurfaceHit* hit) const;
  // Whether the segment is blocked. Masks and panes let it through with their pass probability
  // (Bsdf::PassThrough); `delta_light`: the segment ends at a delta light, which panes block.
  bool Occluded(const Ray& ray, bool delta_light = false) const;
  // The shadow ray from `hit` to the light sample (SpawnShadowRay), blocked or not; towards a
  // point, spot or directional light (Light::IsDelta) panes block it.
  bool ShadowOccluded(const SurfaceHit& hit, const LightSample& ls) const {
    const bool delta = ls.light >= 0 && lights()[size_t(ls.light)].IsDelta();
    return Occluded(SpawnShadowRay(hit, ls), delta);
  }

  // A ray leaving hit point `p` (geometric normal ng, error scale s) in direction dir.
  static Ray SpawnRay(const Vec3& p, const Vec3& ng, float s, const Vec3& dir);
  // A shadow ray from the hit to a sampled light; the far end is offset as well.
  static Ray SpawnShadowRay(const SurfaceHit& hit, const LightSample& ls);

  // Picks a light by its expected contribution at (p, n) and samples it (LightSampler::Sample).
  // With include_env false only local lights (area, point, spot, directional) are chosen: the
  // irradiance cache integrates environment light itself. False when the sample carries
  // nothing. *skipped counts the lights that cannot reach p (no shadow ray is spent on them).
  bool SampleLight(const Vec3& p, const Vec3& n, float u1, float u2, float u3, bool include_env,
                   LightSample* s, int* skipped = nullptr) const {
    return lights_.Sample(p, n, u1, u2, u3, include_env, s, skipped);
  }
  // Solid-angle pdf (incl. selection) of SampleLight(p, n, ..., true) having produced the
  // direction wi from p that hits the area light of `hit`, or that escapes (environment).
  float PdfAreaLight(const Vec3& p, const Vec3& n, const SurfaceHit& hit, const Vec3& wi) const {
    return lights_.PdfArea(p, n, hit.light, hit.p, hit.ns, hit.prim, wi);
  }
  float PdfEnvironment(const Vec3& p, const Vec3& n, const Vec3& wi) const {
    return lights_.PdfEnvironment(p, n, wi);
  }
  int num_local_lights() const { return lights_.num_local(); }
  // Radiance from the environment lights (constant + envmap) along direction d.
  Vec3 EvalEnvironment(const Vec3& d) const { return lights_.EvalEnvironment(d); }
  // Le G / pdf of a light sample from SampleLight (its environment radiance looked up now).
  Vec3 LightValue(const LightSample& s) const {
    return s.environment ? s.value * lights_.EvalEnvironment(s.wi) : s.value;
  }
  // Emitted radiance of the surface towards wo (front side only).
  Vec3 Emitted(const SurfaceHit& hit, const Vec3& wo) const;

  const Camera& camera() const { return camera_; }
  const Bsdf& material(int i) const { return *materials_[size_t(i)]; }
  int num_materials() const { return int(materials_.size()); }
  const std::vector<Light>& lights() const { return lights_.lights(); }
  const LightSampler& light_sampler() const { return lights_; }
  bool has_environment() const { return lights_.has_environment(); }
  // The environment map's sun (render/environment_sun.h), found once here; empty: none.
  const EnvironmentSun& environment_sun() const { return sun_; }
  const EnvironmentGuide& environment_guide() const { return env_guide_; }
  const Bounds3& bounds() const { return bounds_; }
  // The bounds of the shapes whose material has any of `lobes` (BSDF lobe bits); empty: none.
  Bounds3 BoundsOfLobes(uint32_t lobes) const;
  const SceneStatsCounts& counts() const { return counts_; }
  // The committed Embree scene, for benchmarks that compare with bare Embree calls.
  RTCScene embree_scene() const { return rtc_scene_; }
  // `ray` as Embree's ray-hit query (no hit yet): what Intersect passes to rtcIntersect1.
  static RTCRayHit ToRtcRayHit(const Ray& ray);
  // `ray` as Embree's occlusion query: what Occluded passes to rtcOccluded1.
  static RTCRay ToRtcRay(const Ray& ray);
  // Benchmarks only: while `log` is set, Intersect and Occluded append every ray they trace to
  // it (one thread; nullptr stops). The renderer never sets it: one predictable branch per ray.
  void set_ray_log(std::vector<TracedRay>* log) { ray_log_ = log; }

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
    std::array<float, 9> frame{1, 0, 0, 0, 1, 0, 0, 0, 1};  // kSphere: ShapeDesc::frame
    int material = 0;
    int light = -1;
  };
  // Shadow rays through pass-through surfaces (masks, null): an Embree occlusion filter on the
  // geometries whose material lets rays through rejects a hit with the surface's pass
  // probability, decided by a hash of the ray and the primitive (deterministic, uncorrelated
  // between rays), so rtcOccluded1 stays one traversal that stops at the first blocking hit.
  // Where Embree lacks filter functions, OccludedPassThrough walks the hits with Intersect.
  static void PassThroughFilter(const RTCFilterFunctionNArguments* args);
  // The chance that a shadow ray passes the surface of geometry `geom` at the hit (primitive
  // prim, Embree's barycentrics bu, bv, point p), meeting it at |cos| = cos_theta to its
  // geometric normal; a mesh with vertex normals is met at the cosine to its shading normal
  // instead, as the BSDF's Sample sees it.
  // `d`: the ray's direction (which side of the surface it meets: Bsdf::PassThrough's front).
  float PassProbability(unsigned geom, unsigned prim, float bu, float bv, const Vec3& p,
                        const Vec3& d, float cos_theta, bool delta_light) const;
  static uint64_t PassThroughHash(const Vec3& origin, const Vec3& dir);
  bool OccludedPassThrough(Ray ray, bool delta_light) const;

  RTCDevice device_ = nullptr;
  RTCScene rtc_scene_ = nullptr;
  std::vector<Mesh> meshes_;  // indexed by Embree geometry id
  std::vector<std::unique_ptr<Texture>> textures_;
  std::vector<std::unique_ptr<Bsdf>> materials_;  // SceneDesc::bsdfs, built
  LightSampler lights_;                           // local lights first, then environment lights
  EnvironmentSun sun_;
  EnvironmentGuide env_guide_;        // the light sampler points at it
  bool has_pass_through_ = false;     // some material lets rays through (mask): see Occluded
  bool pass_through_filter_ = false;  // ... and Embree's occlusion filter handles it
  Camera camera_;
  Bounds3 bounds_;
  SceneStatsCounts counts_;
  std::vector<TracedRay>* ray_log_ = nullptr;  // see set_ray_log
};

}  // namespace irfarm
