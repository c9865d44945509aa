// The lights of a built scene, each self-contained (its own copy of the emitting geometry), so
// that the light sampler needs nothing of the Embree scene. Local lights (area, point, spot,
// directional) are sampled explicitly; environment lights (constant, envmap) act as one.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/math.h"
#include "render/light_tree.h"
#include "render/light_triangle.h"
#include "render/textures/bitmap.h"

namespace irfarm {

enum class LightType { kArea, kPoint, kSpot, kDirectional, kConstant, kEnvmap };

// The shape of an area light.
enum class AreaShape { kRect, kSphere, kMesh };

struct Light {
  LightType type = LightType::kArea;
  Vec3 radiance;   // area, constant: emitted radiance
  Vec3 intensity;  // point, spot (W/sr); directional: irradiance (W/m^2)
  Vec3 position;   // point, spot
  Vec3 direction;  // directional, spot: direction the light travels
  float cos_cutoff = 0, cos_beam = 0, cutoff = 0, inv_transition = 0;  // spot
  // Area lights.
  AreaShape shape = AreaShape::kMesh;
  unsigned geom = 0;  // Embree geometry id of the emitting shape
  // kRect: corner + two orthogonal edges; emits towards normal (= the triangles' ng).
  Vec3 corner, edge_u, edge_v, normal;
  // kSphere: emits outwards (inwards when flipped).
  Vec3 center;
  float radius = 0;
  bool flip = false;
  // kMesh (and kRect, whose two triangles are kept for the fallback): triangles and their
  // cumulative areas, to pick one by area (photon emission); kMesh: the tree that picks one by
  // its estimated contribution at a shading point (next-event estimation).
  std::vector<LightTriangle> triangles;
  std::vector<float> cdf;
  LightTree tree;
  float area = 0;
  float error_scale = 0;
  // Envmap
  const BitmapTexture* envmap = nullptr;
  Mat4 world_to_env;
  float scale = 1;
  Vec3 average_radiance;  // environment: mean radiance over the sphere (selection weights)

  // The triangle u in [0, 1) picks by area (kMesh; cdf not empty).
  const LightTriangle& PickTriangle(float u) const {
    const size_t i = size_t(std::upper_bound(cdf.begin(), cdf.end(), u * area) - cdf.begin());
    return triangles[std::min(i, cdf.size() - 1)];
  }

  bool IsDelta() const {
    return type == LightType::kPoint || type == LightType::kSpot || type == LightType::kDirectional;
  }
  bool IsEnvironment() const { return type == LightType::kConstant || type == LightType::kEnvmap; }
};

// A spot light's falloff (Mitsuba's spot: 1 inside beam_width, linear in angle to 0 at
// cutoff_angle) towards a point that sees it in direction wi (from the point to the light).
inline float SpotFalloff(const Light& l, const Vec3& wi) {
  const float c = Dot(l.direction, -wi);
  if (c <= l.cos_cutoff) return 0;
  if (c >= l.cos_beam) return 1;
  return (l.cutoff - std::acos(std::min(c, 1.0f))) * l.inv_transition;
}

// An envmap's parameterisation (Mitsuba's latitude-longitude map): unit direction e in the map's
// frame -> (u, v) in [0, 1)^2 with u = phi / 2 pi (phi = atan2(e.x, -e.z)) and v = theta / pi
// (theta from +y). LightSampler::EvalEnvironment reads the map with it; EnvironmentMapSampler
// places its density with it and its inverse.
inline void EnvmapUv(const Vec3& e, float* u, float* v) {
  const float a = std::atan2(e.x, -e.z) * (0.5f * kInvPi);
  *u = a - std::floor(a);
  *v = std::acos(std::clamp(e.y, -1.0f, 1.0f)) * kInvPi;
}
inline Vec3 EnvmapDirection(float u, float v) {
  const float phi = u * 2 * kPi, theta = v * kPi;
  const float st = std::sin(theta);
  return Vec3(st * std::sin(phi), std::cos(theta), -st * std::cos(phi));
}

struct LightSample {
  Vec3 wi;                    // unit direction from the shading point to the light
  float distance = INFINITY;  // to the light point (INFINITY for directional / environment)
  Vec3 value;                 // Le * G / pdf, for delta lights I / d^2 (or E) / pselect
  float pdf = 0;              // solid-angle pdf including light selection; 0 for delta lights
  Vec3 light_point, light_normal;
  float light_error_scale = 0;
  int light = -1;  // which light
  // An environment sample's value is 1 / pdf until the direction is known to be unblocked: the
  // radiance lookup (a texture fetch far from cache) is left to Scene::LightValue, called after
  // the shadow ray, since in interiors most shadow rays towards the sky are blocked.
  bool environment = false;
};

}  // namespace irfarm
