#include "render/scene.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "render/bsdfs/registry.h"
#include "render/emitters/registry.h"
#include "render/sampling.h"

namespace irfarm {
namespace {

// Occluded's occlusion query context: Embree's own first (filter functions get a pointer to
// it), then whether the shadow ray ends at a delta light (Bsdf::PassThrough).
struct ShadowContext {
  RTCIntersectContext embree;
  bool delta_light = false;
};

// |cos| of the angle between two directions of any length (1 where either is zero).
float AbsCos(const Vec3& a, const Vec3& b) {
  const float l = std::sqrt(Dot(a, a) * Dot(b, b));
  return l > 0 ? std::min(1.0f, std::abs(Dot(a, b)) / l) : 1.0f;
}

void EmbreeError(void* user, RTCError code, const char* str) {
  auto* msg = static_cast<std::string*>(user);
  if (msg->empty()) *msg = "embree error " + std::to_string(int(code)) + ": " + (str ? str : "");
}

float TriangleArea(const Vec3& a, const Vec3& b, const Vec3& c) {
  return 0.5f * Length(Cross(b - a, c - a));
}

// Mitsuba's sphere uv at the outward unit normal n (world space) of a sphere whose own directions
// `frame` takes to world ones: with l = frame^T n, u = phi / 2 pi with phi = atan2(l.y, l.x) in
// [0, 2 pi), v = theta / pi. The tangents (optional): d/du turns around its own z, d/dv runs from
// its own +z pole down, scaled to the radius and turned back to world space.
void SphereUv(const std::array<float, 9>& frame, const Vec3& n, float radius, float* u, float* v,
              Vec3* dpdu = nullptr, Vec3* dpdv = nullptr) {
  const auto& q = frame;
  const Vec3 l(q[0] * n.x + q[3] * n.y + q[6] * n.z, q[1] * n.x + q[4] * n.y + q[7] * n.z,
               q[2] * n.x + q[5] * n.y + q[8] * n.z);
  const float phi = std::atan2(l.y, l.x);
  *u = (phi < 0 ? phi + 2 * kPi : phi) * (0.5f * kInvPi);
  *v = std::acos(std::clamp(l.z, -1.0f, 1.0f)) * kInvPi;
  if (dpdu == nullptr) return;
  const auto to_world = [&q](const Vec3& a) {
    return Vec3(q[0] * a.x + q[1] * a.y + q[2] * a.z, q[3] * a.x + q[4] * a.y + q[5] * a.z,
                q[6] * a.x + q[7] * a.y + q[8] * a.z);
  };
  const float rxy = std::sqrt(l.x * l.x + l.y * l.y);
  *dpdu = to_world(Vec3(-l.y, l.x, 0) * (2 * kPi * radius));
  *dpdv = to_world(rxy > 0 ? Vec3(l.z * l.x / rxy, l.z * l.y / rxy, -rxy) * (kPi * radius)
                           : Vec3(kPi * radius, 0, 0));
}

// The per-vertex uvs of triangle `tri` interpolated at barycentrics (b0, b1, b2).
void TriangleUv(const std::vector<float>& uvs, const uint32_t* tri, float b0, float b1, float b2,
                float* u, float* v) {
  *u = uvs[2 * tri[0]] * b0 + uvs[2 * tri[1]] * b1 + uvs[2 * tri[2]] * b2;
  *v = uvs[2 * tri[0] + 1] * b0 + uvs[2 * tri[1] + 1] * b1 + uvs[2 * tri[2] + 1] * b2;
}

// What MakeAreaLight needs of a built mesh (Scene::Mesh is private to Scene).
struct MeshView {
  bool sphere = false, flip = false;
  Vec3 center;
  float radius = 0;
  const std::vector<Vec3>* positions = nullptr;
  const std::vector<Vec3>* normals = nullptr;
  const std::vector<uint32_t>* indices = nullptr;
  const std::vector<Vec3>* tri_ng = nullptr;
};

// An area light from the emitting shape: its triangles (kept for sampling by solid angle) and,
// for a shape that is one rectangle (two triangles spanning a parallelogram with a right angle,
// as Mitsuba's `rectangle` is), its corner and edges, or its sphere.
Light MakeAreaLight(const MeshView& m, const Vec3& radiance, unsigned geom) {
  Light l;
  l.type = LightType::kArea;
  l.radiance = radiance;
  l.geom = geom;
  if (m.sphere) {
    l.shape = AreaShape::kSphere;
    l.center = m.center;
    l.radius = m.radius;
    l.flip = m.flip;
    l.area = 4 * kPi * m.radius * m.radius;
    l.error_scale = MaxAbsComponent(m.center) + m.radius;
    return l;
  }
  l.shape = AreaShape::kMesh;
  const size_t nt = m.indices->size() / 3;
  float acc = 0;
  for (size_t t = 0; t < nt; ++t) {
    const uint32_t* tri = &(*m.indices)[3 * t];
    LightTriangle lt;
    lt.p0 = (*m.positions)[tri[0]];
    lt.p1 = (*m.positions)[tri[1]];
    lt.p2 = (*m.positions)[tri[2]];
    lt.ng = (*m.tri_ng)[t];
    if (!m.normals->empty()) {
      lt.n0 = (*m.normals)[tri[0]];
      lt.n1 = (*m.normals)[tri[1]];
      lt.n2 = (*m.normals)[tri[2]];
      // A lamp emits on its shading normals' side (Emitted); its samples, pdfs, tree and photons
      // face where lt.ng does: the same side, where the winding disagrees (a mesh mirrored by
      // its to_world keeps its triangles' order, its normals turn with the transform).
      if (Dot(lt.ng, lt.n0 + lt.n1 + lt.n2) < 0) lt.ng = -lt.ng;
    } else {
      lt.n0 = lt.n1 = lt.n2 = lt.ng;
    }
    lt.area = TriangleArea(lt.p0, lt.p1, lt.p2);
    lt.error_scale =
        std::max({MaxAbsComponent(lt.p0), MaxAbsComponent(lt.p1), MaxAbsComponent(lt.p2)});
    l.error_scale = std::max(l.error_scale, lt.error_scale);
    acc += lt.area;
    l.cdf.push_back(acc);
    l.triangles.push_back(lt);
  }
  l.area = acc;
  // One rectangle? Two triangles with 4 distinct vertices, flat, edges at a right angle.
  bool flat = true;
  for (const Vec3& n : *m.normals) flat &= nt > 0 && Dot(n, l.triangles[0].ng) > 1 - 1e-4f;
  if (nt == 2 && flat) {
    std::vector<Vec3> v;
    for (size_t k = 0; k < 6; ++k) {
      const Vec3& p = (*m.positions)[(*m.indices)[k]];
      bool seen = false;
      for (const Vec3& q : v) seen |= LengthSquared(q - p) == 0;
      if (!seen) v.push_back(p);
    }
    const Vec3 n0 = l.triangles[0].ng, n1 = l.triangles[1].ng;
    if (v.size() == 4 && Dot(n0, n1) > 1 - 1e-5f) {
      // Find the corner whose two neighbours (the other vertices but the opposite one) span it.
      for (int c = 0; c < 4; ++c) {
        for (int a = 0; a < 4; ++a) {
          for (int b = 0; b < 4; ++b) {
            if (a == c || b == c || a == b) continue;
            const int o = 6 - a - b - c;
            const Vec3 eu = v[a] - v[c], ev = v[b] - v[c];
            const float lu = Length(eu), lv = Length(ev);
            if (!(lu > 0 && lv > 0)) continue;
            const bool right = std::abs(Dot(eu, ev)) <= 1e-5f * lu * lv;
            const Vec3 far = v[c] + eu + ev;
            const bool closes = Length(far - v[o]) <= 1e-5f * (lu + lv);
            if (right && closes && Dot(Cross(eu, ev), n0) > 0) {
              l.shape = AreaShape::kRect;
              l.corner = v[c];
              l.edge_u = eu;
              l.edge_v = ev;
              l.normal = n0;
              return l;
            }
          }
        }
      }
    }
  }
  l.tree.Build(l.triangles, Luminance(l.radiance));
  return l;
}

}  // namespace

Scene::~Scene() {
  if (rtc_scene_) rtcReleaseScene(rtc_scene_);
  if (device_) rtcReleaseDevice(device_);
}

absl::StatusOr<std::unique_ptr<Scene>> Scene::Build(const SceneDesc& desc,
                                                    const SceneBuildOptions& options) {
  std::unique_ptr<Scene> s(new Scene());
  s->camera_ = Camera(desc.camera);
  std::string embree_error;
  // Under ThreadSanitizer (.ci/sanitizers thread) Embree builds on one thread: its builds hand
  // work to TBB's threads inside the uninstrumented libembree and libtbb, which TSan cannot see
  // (the same reason RenderThreads is 1 there, render/renderer.cc).
#if defined(__SANITIZE_THREAD__)
  s->device_ = rtcNewDevice("verbose=0,threads=1");
#else
  s->device_ = rtcNewDevice("verbose=0");
#endif
  if (!s->device_) return absl::InternalError("cannot create the Embree device");
  rtcSetDeviceErrorFunction(s->device_, EmbreeError, &embree_error);

  // Textures decode in parallel (veach-ajar's four JPEG/PNG files took most of its Scene::Build,
  // one after another); the first failing one in file order is reported, as a serial load would. On
  // one thread under ThreadSanitizer, as Embree's builds above.
  std::vector<absl::StatusOr<std::unique_ptr<Texture>>> loaded(desc.textures.size());
  const auto load = [&](size_t i) { loaded[i] = LoadTexture(desc.textures[i]); };
#if defined(__SANITIZE_THREAD__)
  for (size_t i = 0; i < loaded.size(); ++i) load(i);
#else
  tbb::parallel_for(size_t(0), loaded.size(), load);
#endif
  for (absl::StatusOr<std::unique_ptr<Texture>>& tex : loaded) {
    if (!tex.ok()) return tex.status();
    s->textures_.push_back(*std::move(tex));
  }
  BsdfBuildContext bsdf_ctx;
  bsdf_ctx.textures = &s->textures_;
  bsdf_ctx.bsdfs = &s->materials_;
  for (const BsdfDesc& b : desc.bsdfs) {
    const BsdfPlugin* plugin = FindBsdfPlugin(b.type);
    if (plugin == nullptr)
      return absl::InvalidArgumentError(b.loc.ToString() + ": unknown bsdf type '" + b.type + "'");
    for (const int i : b.nested)
      if (i < 0 || size_t(i) >= s->materials_.size())
        return absl::InternalError(b.loc.ToString() + ": nested bsdf index out of order");
    s->materials_.push_back(plugin->build(b, bsdf_ctx));
    if (s->materials_.back()->Flags() & kNullTransmission) s->has_pass_through_ = true;
  }
  if (s->materials_.empty()) {
    BsdfDesc def;
    def.colors["reflectance"].value = Vec3(0.5f);
    s->materials_.push_back(FindBsdfPlugin("diffuse")->build(def, bsdf_ctx));
  }

  s->rtc_scene_ = rtcNewScene(s->device_);
  // No RTC_SCENE_FLAG_ROBUST: it cost 12% of path-tracing time and changed no test image
  // (relMSE equal to 1e-7 on cornell-box and stress-degenerate); ray origins are offset anyway.
  rtcSetSceneFlags(s->rtc_scene_, RTC_SCENE_FLAG_NONE);
  rtcSetSceneBuildQuality(s->rtc_scene_, RTC_BUILD_QUALITY_HIGH);

  std::vector<Light> area_lights;
  for (const ShapeDesc& sh : desc.shapes) {
    Mesh mesh;
    mesh.material = sh.bsdf >= 0 ? sh.bsdf : 0;
    RTCGeometry g;
    if (sh.type == ShapeType::kSphere) {
      mesh.sphere = true;
      mesh.center = sh.center;
      mesh.radius = sh.radius;
      mesh.flip = sh.flip_normals;
      mesh.frame = sh.frame;
      g = rtcNewGeometry(s->device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
      float* v = static_cast<float*>(
          rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 16, 1));
      v[0] = sh.center.x;
      v[1] = sh.center.y;
      v[2] = sh.center.z;
      v[3] = sh.radius;
      s->bounds_.Extend(sh.center - Vec3(sh.radius));
      s->bounds_.Extend(sh.center + Vec3(sh.radius));
      ++s->counts_.spheres;
    } else {
      const TriangleMesh& tm = sh.mesh;
      if (tm.indices.empty()) continue;
      mesh.positions = tm.positions;
      mesh.normals = tm.normals;
      mesh.uvs = tm.uvs;
      mesh.indices = tm.indices;
      const size_t nv = tm.positions.size(), nt = tm.indices.size() / 3;
      g = rtcNewGeometry(s->device_, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto* v = static_cast<Vec3*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0,
                                                           RTC_FORMAT_FLOAT3, sizeof(Vec3), nv));
      std::memcpy(static_cast<void*>(v), tm.positions.data(), nv * sizeof(Vec3));
      auto* idx = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), nt));
      std::memcpy(idx, tm.indices.data(), nt * 3 * sizeof(uint32_t));
      for (const Vec3& p : tm.positions) s->bounds_.Extend(p);
      mesh.tri_info.resize(nt);
      for (size_t t = 0; t < nt; ++t) {
        const Vec3& p0 = tm.positions[tm.indices[3 * t]];
        const Vec3& p1 = tm.positions[tm.indices[3 * t + 1]];
        const Vec3& p2 = tm.positions[tm.indices[3 * t + 2]];
        const Vec3 cross = Cross(p1 - p0, p2 - p0);
        const float len = Length(cross);
        const float longest = std::sqrt(std::max(
            LengthSquared(p1 - p0), std::max(LengthSquared(p2 - p1), LengthSquared(p0 - p2))));
        const float height = len / std::max(longest, 1e-30f);
        Mesh::TriInfo& info = mesh.tri_info[t];
        info.ng = len > 0 ? cross / len : Vec3(0, 0, 1);
        info.error_scale =
            std::max(MaxAbsComponent(p0), std::max(MaxAbsComponent(p1), MaxAbsComponent(p2)));
        info.inset =
            std::min(0.1f, 4 * kOriginOffset * info.error_scale / std::max(height, 1e-30f));
      }
      s->counts_.triangles += long(nt);
    }
    s->counts_.degenerate_dropped += sh.degenerate_dropped;
    rtcCommitGeometry(g);
    const unsigned id = rtcAttachGeometry(s->rtc_scene_, g);
    rtcReleaseGeometry(g);
    if (id != s->meshes_.size()) return absl::InternalError("unexpected Embree geometry id");

    if (sh.area_radiance && !IsBlack(*sh.area_radiance)) {
      std::vector<Vec3> tri_ng;
      for (const Mesh::TriInfo& t : mesh.tri_info) tri_ng.push_back(t.ng);
      MeshView view;
      view.sphere = mesh.sphere;
      view.flip = mesh.flip;
      view.center = mesh.center;
      view.radius = mesh.radius;
      view.positions = &mesh.positions;
      view.normals = &mesh.normals;
      view.indices = &mesh.indices;
      view.tri_ng = &tri_ng;
      Light l = MakeAreaLight(view, *sh.area_radiance, id);
      if (l.area > 0) {
        mesh.light = int(area_lights.size());
        area_lights.push_back(std::move(l));
      }
    }
    s->meshes_.push_back(std::move(mesh));
  }
  if (s->has_pass_through_ &&
      rtcGetDeviceProperty(s->device_, RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED) != 0) {
    s->pass_through_filter_ = true;
    for (size_t id = 0; id < s->meshes_.size(); ++id) {
      if (!(s->materials_[size_t(s->meshes_[id].material)]->Flags() & kNullTransmission)) continue;
      RTCGeometry g = rtcGetGeometry(s->rtc_scene_, unsigned(id));
      rtcSetGeometryUserData(g, s.get());
      rtcSetGeometryOccludedFilterFunction(g, &Scene::PassThroughFilter);
      rtcCommitGeometry(g);
    }
  }
  rtcCommitScene(s->rtc_scene_);
  if (!embree_error.empty()) return absl::InternalError(embree_error);
  rtcSetDeviceErrorFunction(s->device_, nullptr, nullptr);  // embree_error goes out of scope

  // Lights: local ones first, environment ones last.
  std::vector<Light> local = std::move(area_lights);
  std::vector<Light> env;
  for (const EmitterDesc& e : desc.emitters) {
    const EmitterPlugin* plugin = FindEmitterPlugin(e.type);
    if (plugin == nullptr || plugin->build == nullptr) {
      return absl::InvalidArgumentError(
          absl::StrCat(e.loc.file, ":", e.loc.line, ": no light for emitter type '", e.type, "'"));
    }
    absl::StatusOr<Light> l = plugin->build(e, &s->textures_);
    if (!l.ok()) return l.status();
    (l->IsEnvironment() ? env : local).push_back(*std::move(l));
  }
  const int num_local = int(local.size());
  for (Light& l : env) local.push_back(l);
  s->lights_.Build(std::move(local), num_local);
  bool has_envmap = false;
  for (const Light& l : s->lights_.lights()) has_envmap |= l.type == LightType::kEnvmap;
  s->sun_ = EnvironmentSun::Find([&s](const Vec3& d) { return s->lights_.EvalEnvironment(d); },
                                 has_envmap);
  if (options.environment_guide) {
    s->env_guide_ = EnvironmentGuide::Learn(*s);
    if (!s->env_guide_.empty()) s->lights_.set_guide(&s->env_guide_);
  }
  return s;
}

RTCRayHit Scene::ToRtcRayHit(const Ray& ray) {
  RTCRayHit rh;
  rh.ray.org_x = ray.origin.x;
  rh.ray.org_y = ray.origin.y;
  rh.ray.org_z = ray.origin.z;
  rh.ray.dir_x = ray.dir.x;
  rh.ray.dir_y = ray.dir.y;
  rh.ray.dir_z = ray.dir.z;
  rh.ray.tnear = ray.tnear;
  rh.ray.tfar = ray.tmax;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.ray.time = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

RTCRay Scene::ToRtcRay(const Ray& ray) {
  RTCRay r;
  r.org_x = ray.origin.x;
  r.org_y = ray.origin.y;
  r.org_z = ray.origin.z;
  r.dir_x = ray.dir.x;
  r.dir_y = ray.dir.y;
  r.dir_z = ray.dir.z;
  r.tnear = ray.tnear;
  r.tfar = ray.tmax;
  r.mask = 0xFFFFFFFFu;
  r.flags = 0;
  r.time = 0;
  return r;
}

bool Scene::Intersect(const Ray& ray, SurfaceHit* hit) const {
  if (ray_log_ != nullptr) ray_log_->push_back(TracedRay{ray, false});
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh = Scene::ToRtcRayHit(ray);
  rtcIntersect1(rtc_scene_, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  const Mesh& m = meshes_[rh.hit.geomID];
  hit->t = rh.ray.tfar;
  hit->geom = rh.hit.geomID;
  hit->prim = rh.hit.primID;
  hit->material = m.material;
  hit->light = m.light;
  if (m.sphere) {
    const Vec3 d = ray.origin + ray.dir * rh.ray.tfar - m.center;
    const Vec3 n = Normalize(d);
    hit->p = m.center + n * m.radius;
    hit->ng = m.flip ? -n : n;
    hit->ns = hit->ng;
    SphereUv(m.frame, n, m.radius, &hit->u, &hit->v, &hit->dpdu, &hit->dpdv);
    hit->error_scale = MaxAbsComponent(m.center) + m.radius;
    return true;
  }
  const uint32_t* tri = &m.indices[3 * size_t(rh.hit.primID)];
  const Vec3& p0 = m.positions[tri[0]];
  const Vec3& p1 = m.positions[tri[1]];
  const Vec3& p2 = m.positions[tri[2]];
  float b1 = rh.hit.u, b2 = rh.hit.v, b0 = 1 - b1 - b2;
  const Mesh::TriInfo& info = m.tri_info[rh.hit.primID];
  hit->error_scale = info.error_scale;
  // A hit on (or rounded onto) an edge lies on every surface meeting there, e.g. the line where a
  // ceiling meets a wall; a ray leaving it, offset only along this triangle's normal, would start
  // on the wall's plane and could pass behind it. So the point is moved into the triangle's
  // interior by a few ray offsets (relative to the triangle's height, so scale-free).
  const float inset = info.inset;
  if (b0 < inset || b1 < inset || b2 < inset) {
    b0 = std::max(b0, inset);
    b1 = std::max(b1, inset);
    b2 = std::max(b2, inset);
    const float inv = 1 / (b0 + b1 + b2);
    b0 *= inv;
    b1 *= inv;
    b2 *= inv;
  }
  hit->p = p0 * b0 + p1 * b1 + p2 * b2;
  hit->ng = info.ng;
  if (!m.normals.empty()) {
    const Vec3 n = m.normals[tri[0]] * b0 + m.normals[tri[1]] * b1 + m.normals[tri[2]] * b2;
    const float len = Length(n);
    hit->ns = len > 0 ? n / len : hit->ng;
  } else {
    hit->ns = hit->ng;
  }
  // Tangents from the triangle's edges and their uv differences (without uvs, u = b1, v = b2).
  const Vec3 e1 = p1 - p0, e2 = p2 - p0;
  hit->dpdu = e1;
  hit->dpdv = e2;
  if (!m.uvs.empty()) {
    TriangleUv(m.uvs, tri, b0, b1, b2, &hit->u, &hit->v);
    const float du1 = m.uvs[2 * tri[1]] - m.uvs[2 * tri[0]];
    const float dv1 = m.uvs[2 * tri[1] + 1] - m.uvs[2 * tri[0] + 1];
    const float du2 = m.uvs[2 * tri[2]] - m.uvs[2 * tri[0]];
    const float dv2 = m.uvs[2 * tri[2] + 1] - m.uvs[2 * tri[0] + 1];
    const float det = du1 * dv2 - dv1 * du2;
    if (det != 0 && std::isfinite(1 / det)) {
      const float inv = 1 / det;
      hit->dpdu = (e1 * dv2 - e2 * dv1) * inv;
      hit->dpdv = (e2 * du1 - e1 * du2) * inv;
    }
  } else {
    hit->u = b1;
    hit->v = b2;
  }
  return true;
}

bool Scene::Occluded(const Ray& ray, bool delta_light) const {
  if (has_pass_through_ && !pass_through_filter_) return OccludedPassThrough(ray, delta_light);
  if (ray_log_ != nullptr) ray_log_->push_back(TracedRay{ray, true});
  ShadowContext ctx;
  rtcInitIntersectContext(&ctx.embree);
  ctx.delta_light = delta_light;
  RTCRay r = ToRtcRay(ray);
  rtcOccluded1(rtc_scene_, &ctx.embree, &r);
  return r.tfar < 0;
}

uint64_t Scene::PassThroughHash(const Vec3& origin, const Vec3& dir) {
  const auto bits = [](float f) {
    uint32_t u;
    std::memcpy(&u, &f, sizeof(u));
    return uint64_t(u);
  };
  return HashCombine((bits(origin.x) << 32) | bits(origin.y),
                     (bits(origin.z) << 32) | bits(dir.x + 3 * dir.y + 7 * dir.z));
}

float Scene::PassProbability(unsigned geom, unsigned prim, float bu, float bv, const Vec3& p,
                             const Vec3& d, float cos_theta, bool delta_light) const {
  const Mesh& m = meshes_[geom];
  float u = bu, v = bv;  // without uvs, as Intersect: u = b1, v = b2
  Vec3 ng;               // the front side's normal, as Intersect gives it (SurfaceHit::ng)
  if (m.sphere) {
    const Vec3 n = Normalize(p - m.center);
    SphereUv(m.frame, n, m.radius, &u, &v);
    ng = m.flip ? -n : n;
  } else {
    const uint32_t* tri = &m.indices[3 * size_t(prim)];
    if (!m.uvs.empty()) TriangleUv(m.uvs, tri, 1 - bu - bv, bu, bv, &u, &v);
    ng = m.tri_info[prim].ng;
    // Against the shading normal where the mesh has one, as the BSDF's Sample sees the surface
    // (a pane with smoothed normals passed shadow rays by its geometric cosine, paths by the
    // shading one: the two halves of MIS disagreed).
    if (!m.normals.empty()) {
      const Vec3 n =
          m.normals[tri[0]] * (1 - bu - bv) + m.normals[tri[1]] * bu + m.normals[tri[2]] * bv;
      const float len = Length(n) * Length(d);
      if (len > 0) cos_theta = std::min(1.0f, std::abs(Dot(d, n)) / len);
    }
  }
  return materials_[size_t(m.material)]->PassThrough(BsdfContext{u, v}, cos_theta, Dot(d, ng) < 0,
                                                     delta_light);
}

void Scene::PassThroughFilter(const RTCFilterFunctionNArguments* args) {
  const Scene* s = static_cast<const Scene*>(args->geometryUserPtr);
  // Occluded's context: Embree's, first, and what the query is for.
  const bool delta_light = reinterpret_cast<const ShadowContext*>(args->context)->delta_light;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const Vec3 o(RTCRayN_org_x(args->ray, args->N, i), RTCRayN_org_y(args->ray, args->N, i),
                 RTCRayN_org_z(args->ray, args->N, i));
    const Vec3 d(RTCRayN_dir_x(args->ray, args->N, i), RTCRayN_dir_y(args->ray, args->N, i),
                 RTCRayN_dir_z(args->ray, args->N, i));
    const unsigned geom = RTCHitN_geomID(args->hit, args->N, i);
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    // The ray's tfar is the candidate hit's distance while the filter runs.
    const Vec3 p = o + d * RTCRayN_tfar(args->ray, args->N, i);
    const Vec3 ng(RTCHitN_Ng_x(args->hit, args->N, i), RTCHitN_Ng_y(args->hit, args->N, i),
                  RTCHitN_Ng_z(args->hit, args->N, i));
    const float pass =
        s->PassProbability(geom, prim, RTCHitN_u(args->hit, args->N, i),
                           RTCHitN_v(args->hit, args->N, i), p, d, AbsCos(d, ng), delta_light);
    if (!(pass > 0)) continue;  // blocks: the hit stands and the query ends
    // A sphere is hit twice by a ray through it: the way out is a surface of its own.
    const Scene::Mesh& m = s->meshes_[geom];
    const uint64_t out = m.sphere && Dot(d, p - m.center) > 0 ? 1 : 0;
    const uint64_t h =
        HashCombine(HashCombine(PassThroughHash(o, d), (uint64_t(geom) << 32) | prim), out);
    if (Rng::ToUnitFloat(uint32_t(h >> 32)) < pass) args->valid[i] = 0;  // passes: ignored
  }
}

// With masks, where Embree has no filter functions: walk the hits along the segment; each
// pass-through surface lets the ray on with its pass probability, decided by a hash of the ray and
// the hit (deterministic, so renders repeat; uncorrelated between rays). The expected visibility is
// the product of the pass probabilities, as for camera and bounce rays that sample the mask's null
// lobe.
bool Scene::OccludedPassThrough(Ray ray, bool delta_light) const {
  uint64_t h = PassThroughHash(ray.origin, ray.dir);
  for (int i = 0; i < 64; ++i) {
    SurfaceHit hit;
    if (!Intersect(ray, &hit)) return false;
    const float pass = materials_[size_t(hit.material)]->PassThrough(
        BsdfContext{hit.u, hit.v}, AbsCos(ray.dir, hit.ns), Dot(ray.dir, hit.ng) < 0, delta_light);
    if (!(pass > 0)) return true;
    h = HashCombine(h, (uint64_t(hit.geom) << 32) | hit.prim);
    if (Rng::ToUnitFloat(uint32_t(h >> 32)) >= pass) return true;
    const Ray next = SpawnRay(hit.p, hit.ng, hit.error_scale, ray.dir);
    const float used = Length(next.origin - ray.origin);
    if (!(ray.tmax - used > 0)) return false;
    ray.tmax = std::isfinite(ray.tmax) ? ray.tmax - used : INFINITY;
    ray.origin = next.origin;
  }
  return true;
}

Ray Scene::SpawnRay(const Vec3& p, const Vec3& ng, float s, const Vec3& dir) {
  const float side = Dot(dir, ng) >= 0 ? 1.0f : -1.0f;
  const float off = kOriginOffset * std::max(s, MaxAbsComponent(p));
  return Ray{p + ng * (side * off), dir, INFINITY};
}

Ray Scene::SpawnShadowRay(const SurfaceHit& hit, const LightSample& ls) {
  Ray r = SpawnRay(hit.p, hit.ng, hit.error_scale, ls.wi);
  if (std::isfinite(ls.distance)) {
    // Stop short of the light's surface. Embree's (non-robust) triangle test places a hit up to
    // ~4 ray offsets off the true surface, measured along its normal; along the ray that is
    // that much over |cos| at the light. Measured on a plane under a lamp: a margin of 1 offset
    // let 71% of unoccluded shadow rays hit the lamp itself, 2 offsets 25%, 4 none; 8 are used.
    // The ray is aimed from its offset origin at the light point (the origin offset, up to
    // 1e-5 of the coordinates' magnitude, would otherwise shift the whole segment).
    const float scale = std::max(ls.light_error_scale, MaxAbsComponent(ls.light_point));
    const Vec3 d = ls.light_point - r.origin;
    const float dist = Length(d);
    if (dist > 0) r.dir = d / dist;
    const float cos_l = std::abs(Dot(r.dir, ls.light_normal));
    const float margin = 8 * kOriginOffset * scale / std::max(cos_l, 1e-3f);
    r.tmax = std::max(0.0f, dist - margin);
  }
  return r;
}

Bounds3 Scene::BoundsOfLobes(uint32_t lobes) const {
  Bounds3 b;
  for (const Mesh& m : meshes_) {
    if ((material(m.material).Flags() & lobes) == 0) continue;
    if (m.sphere) {
      b.Extend(m.center - Vec3(m.radius));
      b.Extend(m.center + Vec3(m.radius));
    } else {
      for (const uint32_t i : m.indices) b.Extend(m.positions[i]);
    }
  }
  return b;
}

Vec3 Scene::Emitted(const SurfaceHit& hit, const Vec3& wo) const {
  if (hit.light < 0) return Vec3();
  return Dot(wo, hit.ns) > 0 ? lights()[hit.light].radiance : Vec3();
}

}  // namespace irfarm
