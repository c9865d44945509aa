#include "render/light_sampler.h"

#include <algorithm>
#include <cmath>

#include "render/sampling.h"
#include "render/solid_angle.h"

namespace irfarm {
namespace {

// Meshes with at most this many triangles get their weight from the exact per-triangle
// projected solid angles; larger ones from an estimate by area and distance.
constexpr int kExactMeshTriangles = 8;

bool HasNormal(const Vec3& n) { return !IsBlack(n); }

// Cosine of the direction w against n, or 1 when there is no normal.
float HorizonCos(const Vec3& n, const Vec3& w) { return HasNormal(n) ? Dot(n, w) : 1.0f; }

void RectCorners(const Light& l, Vec3 c[4]) {
  c[0] = l.corner;
  c[1] = l.corner + l.edge_u;
  c[2] = l.corner + l.edge_u + l.edge_v;
  c[3] = l.corner + l.edge_v;
}

// Area pdf converted to solid angle: d^2 / (|cos_l| A).
float AreaToSolidAngle(float dist2, float cos_l, float area) {
  return cos_l > 0 && area > 0 ? dist2 / (cos_l * area) : 0;
}

}  // namespace

void LightSampler::Build(std::vector<Light> lights, int num_local) {
  lights_ = std::move(lights);
  num_local_ = num_local;
  env_map_ = EnvironmentMapSampler();
  // The first envmap's frame parameterises the density (every environment light's radiance goes
  // into it).
  for (size_t i = size_t(num_local_); i < lights_.size(); ++i) {
    if (lights_[i].type != LightType::kEnvmap) continue;
    env_map_.Build([this](const Vec3& d) { return EvalEnvironment(d); }, lights_[i].world_to_env);
    break;
  }
}

float LightSampler::Weight(int i, const Vec3& p, const Vec3& n) const {
  const Light& l = lights_[i];
  switch (l.type) {
    case LightType::kArea: {
      const float lum = Luminance(l.radiance);
      if (l.shape == AreaShape::kRect) {
        // Cheap: L A cos_l cos_p / d^2 at the centre, softened near the lamp; zero behind the
        // emitting side or when all four corners are below p's horizon.
        if (Dot(p - l.corner, l.normal) <= 0) return 0;  // behind its emitting side
        const Vec3 d = l.corner + (l.edge_u + l.edge_v) * 0.5f - p;
        const float d2 = LengthSquared(d), inv_d = 1 / std::sqrt(d2);
        float cos_p = 1;
        if (HasNormal(n)) {
          const Vec3 c0 = l.corner - p;
          const float a = Dot(n, c0), bu = Dot(n, l.edge_u), bv = Dot(n, l.edge_v);
          if (std::max({a, a + bu, a + bv, a + bu + bv}) <= 0) return 0;  // below the horizon
          cos_p = std::max(0.05f, Dot(n, d) * inv_d);
        }
        const float cos_l = std::max(0.01f, -Dot(d, l.normal) * inv_d);
        return lum * l.area * cos_l * cos_p / (d2 + l.area * kInvPi);
      }
      if (l.shape == AreaShape::kSphere) {
        const Vec3 d = l.center - p;
        const float d2 = LengthSquared(d), r2 = l.radius * l.radius;
        if (d2 <= r2) return l.flip ? lum * kPi : 0;  // inside: sees the inner side only
        if (l.flip) return 0;
        const float dist = std::sqrt(d2), sin_max = l.radius / dist;
        const float c = HorizonCos(n, d / dist);
        if (c <= -sin_max) return 0;  // the whole sphere is below the horizon
        const float cos_factor = std::min(1.0f, (c + sin_max) / (1 + sin_max));
        return lum * kPi * (r2 / d2) * cos_factor;
      }
      // Mesh.
      if (int(l.triangles.size()) <= kExactMeshTriangles) {
        float w = 0;
        for (const LightTriangle& t : l.triangles) {
          if (t.area <= 0 || Dot(p - t.p0, t.ng) <= 0) continue;
          if (HasNormal(n)) {
            const Vec3 v[3] = {t.p0, t.p1, t.p2};
            w += float(PolygonProjectedSolidAngle(p, n, v, 3));
          } else {
            w += float(TriangleSolidAngle(p, t.p0, t.p1, t.p2));
          }
        }
        return lum * w;
      }
      // Larger meshes: the root of their light tree (0 exactly when no triangle can reach p).
      return l.tree.Importance(p, n);
    }
    case LightType::kPoint:
    case LightType::kSpot: {
      const Vec3 d = l.position - p;
      const float d2 = LengthSquared(d);
      if (!(d2 > 0)) return 0;
      const Vec3 wi = d / std::sqrt(d2);
      const float c = HorizonCos(n, wi);
      if (c <= 0) return 0;
      const float falloff = l.type == LightType::kSpot ? SpotFalloff(l, wi) : 1.0f;
      return Luminance(l.intensity) * falloff * c / d2;
    }
    case LightType::kDirectional: {
      const float c = HorizonCos(n, -l.direction);
      return c > 0 ? Luminance(l.intensity) * c : 0;
    }
    case LightType::kConstant:
    case LightType::kEnvmap:
      return 0;
  }
  return 0;
}

Vec3 LightSampler::AnalyticIrradiance(int i, const Vec3& p, const Vec3& n) const {
  const Light& l = lights_[i];
  if (l.type != LightType::kArea || l.shape != AreaShape::kRect) return Vec3(-1);
  if (Dot(p - l.corner, l.normal) <= 0) return Vec3();
  Vec3 c[4];
  RectCorners(l, c);
  return l.radiance * float(PolygonProjectedSolidAngle(p, n, c, 4));
}

namespace {
// Rect lights whose diagonal is under kSphericalRectSize times the distance to their centre are
// sampled by area: their area pdf is then within a few times of proportional to solid angle
// across the light, and spherical-rectangle sampling's four acos and a sincos per sample cost
// more than the variance they save. Measured (path 16 spp, two seeds; CPU the fastest of three
// runs), threshold 0.5 -> 1.0: thin-panels relMSE 3.23e-2 -> 3.26e-2 in 2.86 -> 2.09 s CPU
// (1.4: 3.33e-2, 1.99 s; area sampling everywhere: 4.09e-2, 1.96 s); specular 8.11e-2 -> 8.22e-2
// in 1.92 -> 1.60 s; cornell-box 1.86e-2 -> 1.91e-2 in 1.44 -> 1.33 s; room-d 1.29e-2 ->
// 1.33e-2 at equal time; irrcache's defaults unchanged within noise (thin-panels, cornell-box,
// room-c). Points closer to a lamp than its diagonal, where area sampling's variance grows
// without bound, are still sampled by solid angle.
constexpr float kSphericalRectSize = 1.0f;

bool RectBySolidAngle(const Light& l, const Vec3& p) {
  const Vec3 c = l.corner + (l.edge_u + l.edge_v) * 0.5f;
  return LengthSquared(l.edge_u) + LengthSquared(l.edge_v) >=
         kSphericalRectSize * kSphericalRectSize * LengthSquared(c - p);
}

// The same rule for a mesh's triangles, by their longest edge: spherical-triangle sampling (three
// acos and two normalisations in double to set up) only where the triangle is large as seen from
// p. Measured on make_room 905 (a tube and a disk lamp, 1206 triangles): it was 14% of a default
// render's CPU.
bool TriangleBySolidAngle(const LightTriangle& t, const Vec3& p) {
  const float longest = std::max(
      {LengthSquared(t.p1 - t.p0), LengthSquared(t.p2 - t.p1), LengthSquared(t.p0 - t.p2)});
  const Vec3 c = (t.p0 + t.p1 + t.p2) * (1.0f / 3.0f);
  return longest >= kSphericalRectSize * kSphericalRectSize * LengthSquared(c - p);
}
}  // namespace

bool LightSampler::SampleOne(int i, const Vec3& p, const Vec3& n, float u2, float u3,
                             LightSample* s, bool coarse) const {
  const Light& l = lights_[i];
  s->light = i;
  switch (l.type) {
    case LightType::kArea: {
      Vec3 q, nl;
      float pdf = 0;
      float scale = l.error_scale;
      if (l.shape == AreaShape::kRect) {
        if (Dot(p - l.corner, l.normal) <= 0) return false;
        SphericalRect sr;
        if (RectBySolidAngle(l, p) && sr.Init(p, l.corner, l.edge_u, l.edge_v)) {
          q = sr.Sample(u2, u3);
          pdf = float(1 / sr.solid_angle());
        } else {
          q = l.corner + l.edge_u * u2 + l.edge_v * u3;
          pdf = -1;  // area pdf, converted below
        }
        nl = l.normal;
      } else if (l.shape == AreaShape::kSphere) {
        const Vec3 d = l.center - p;
        const float d2 = LengthSquared(d), r2 = l.radius * l.radius;
        if (d2 > r2) {
          if (l.flip) return false;
          // Cone of directions towards the sphere; 1 - cos_max = sin^2 / (1 + cos) stays exact
          // for a small far sphere.
          const float dist = std::sqrt(d2);
          const float sin2_max = r2 / d2;
          const float cos_max = std::sqrt(std::max(0.0f, 1 - sin2_max));
          const float one_minus = sin2_max / (1 + cos_max);
          const float x = u2 * one_minus;  // 1 - cos(theta), uniform in solid angle
          const float sin_t = std::sqrt(std::max(0.0f, x * (2 - x)));
          const float cos_t = 1 - x;
          const float phi = 2 * kPi * u3;
          const Vec3 w = d / dist;
          Vec3 a, b;
          MakeFrame(w, &a, &b);
          const Vec3 dir =
              Normalize(a * (sin_t * std::cos(phi)) + b * (sin_t * std::sin(phi)) + w * cos_t);
          // Nearest intersection with the sphere (grazing rays clamp to the tangent point).
          const float bq = Dot(dir, d);
          const float disc = std::max(0.0f, bq * bq - (d2 - r2));
          const float t = bq - std::sqrt(disc);
          q = p + dir * t;
          nl = Normalize(q - l.center);
          pdf = 1 / (2 * kPi * one_minus);
        } else {
          if (!l.flip) return false;
          const Vec3 d2v = UniformSphere(u2, u3);
          q = l.center + d2v * l.radius;
          nl = -d2v;
          pdf = -1;
        }
      } else {
        float pick = 0;
        // The tree's pick takes u2 and leaves what remains of it as the triangle's first
        // coordinate: a pixel's stratified (u2, u3) then spread over the lamp's triangles as well
        // as within them. Measured (irrcache defaults, seeds 7-9, against the pick taking u1):
        // tests/data mesh-lamps relMSE 4.04e-3 -> 2.78e-3 for 8% more CPU, make_room 905
        // 2.09e-3 -> 1.82e-3 (+2% CPU), 910 4.03e-3 -> 3.98e-3 in 21% less CPU.
        const int k = l.tree.Sample(p, n, u2, &pick, coarse, &u2);
        if (k < 0) return false;
        const LightTriangle& t = l.triangles[size_t(k)];
        if (t.area <= 0 || Dot(p - t.p0, t.ng) <= 0) return false;
        SphericalTriangle st;
        float b1, b2;
        if (TriangleBySolidAngle(t, p) && st.Init(p, t.p0, t.p1, t.p2)) {
          const Vec3 dir = st.Sample(u2, u3);
          const float dn = Dot(dir, t.ng);
          if (!(dn < 0)) return false;
          const float tt = Dot(t.p0 - p, t.ng) / dn;
          q = p + dir * tt;
          // Barycentrics of q for the shading normal.
          const Vec3 e1 = t.p1 - t.p0, e2 = t.p2 - t.p0, dq = q - t.p0;
          const Vec3 c = Cross(e1, e2);
          const float inv = 1 / LengthSquared(c);
          b1 = std::clamp(Dot(Cross(dq, e2), c) * inv, 0.0f, 1.0f);
          b2 = std::clamp(Dot(Cross(e1, dq), c) * inv, 0.0f, 1.0f);
          pdf = pick * float(1 / st.solid_angle());
        } else {
          float b0;
          UniformTriangle(u2, u3, &b0, &b1);
          b2 = 1 - b0 - b1;
          q = t.p0 * b0 + t.p1 * b1 + t.p2 * b2;
          pdf = -pick * l.area / t.area;  // negative: area pdf 1/area_t, converted below
        }
        const Vec3 ns = t.n0 * (1 - b1 - b2) + t.n1 * b1 + t.n2 * b2;
        nl = LengthSquared(ns) > 0 ? Normalize(ns) : t.ng;
        scale = t.error_scale;
      }
      const Vec3 d = q - p;
      const float dist2 = LengthSquared(d);
      if (!(dist2 > 0)) return false;
      const float dist = std::sqrt(dist2);
      s->wi = d / dist;
      const float cos_l = -Dot(s->wi, nl);
      if (cos_l <= 0) return false;  // back side emits nothing
      if (pdf < 0) pdf = -pdf * AreaToSolidAngle(dist2, cos_l, l.area);
      if (!(pdf > 0) || !std::isfinite(pdf)) return false;
      s->distance = dist;
      s->pdf = pdf;
      s->value = l.radiance / pdf;
      s->light_point = q;
      s->light_normal = nl;
      s->light_error_scale = scale;
      return true;
    }
    case LightType::kPoint:
    case LightType::kSpot: {
      const Vec3 d = l.position - p;
      const float dist2 = LengthSquared(d);
      if (!(dist2 > 0)) return false;
      const float dist = std::sqrt(dist2);
      s->wi = d / dist;
      s->distance = dist;
      s->pdf = 0;
      const float falloff = l.type == LightType::kSpot ? SpotFalloff(l, s->wi) : 1.0f;
      if (falloff <= 0) return false;
      s->value = l.intensity * (falloff / dist2);
      s->light_point = l.position;
      s->light_normal = -s->wi;
      s->light_error_scale = 0;
      return true;
    }
    case LightType::kDirectional:
      s->wi = -l.direction;
      s->distance = INFINITY;
      s->pdf = 0;
      s->value = l.intensity;
      return true;
    case LightType::kConstant:
    case LightType::kEnvmap:
      return false;
  }
  return false;
}

float LightSampler::PdfOne(int i, const Vec3& p, const Vec3& n, const Vec3& q, const Vec3& nq,
                           unsigned prim, const Vec3& wi, bool coarse) const {
  const Light& l = lights_[i];
  if (l.type != LightType::kArea) return 0;
  const float cos_l = -Dot(wi, nq);
  if (cos_l <= 0) return 0;
  const float dist2 = LengthSquared(q - p);
  if (l.shape == AreaShape::kRect) {
    if (Dot(p - l.corner, l.normal) <= 0) return 0;
    SphericalRect sr;
    if (RectBySolidAngle(l, p) && sr.Init(p, l.corner, l.edge_u, l.edge_v))
      return float(1 / sr.solid_angle());
    return AreaToSolidAngle(dist2, cos_l, l.area);
  }
  if (l.shape == AreaShape::kSphere) {
    const Vec3 d = l.center - p;
    const float d2 = LengthSquared(d), r2 = l.radius * l.radius;
    if (d2 > r2) {
      if (l.flip) return 0;
      const float sin2_max = r2 / d2;
      const float cos_max = std::sqrt(std::max(0.0f, 1 - sin2_max));
      return 1 / (2 * kPi * (sin2_max / (1 + cos_max)));
    }
    return l.flip ? AreaToSolidAngle(dist2, cos_l, l.area) : 0;
  }
  if (prim >= l.triangles.size()) return 0;
  const LightTriangle& t = l.triangles[prim];
  if (t.area <= 0 || Dot(p - t.p0, t.ng) <= 0) return 0;
  const float pick = l.tree.Pmf(p, n, prim, coarse);
  if (!(pick > 0)) return 0;
  SphericalTriangle st;
  if (TriangleBySolidAngle(t, p) && st.Init(p, t.p0, t.p1, t.p2))
    return pick * float(1 / st.solid_angle());
  return pick * AreaToSolidAngle(dist2, cos_l, t.area);
}

float LightSampler::EnvironmentWeight(const Vec3& n) const {
  if (!has_environment()) return 0;
  Vec3 avg;
  for (size_t i = size_t(num_local_); i < lights_.size(); ++i) avg += lights_[i].average_radiance;
  // Irradiance of a uniform sky on a surface (pi L); a point with no normal sees the sphere.
  return Luminance(avg) * (HasNormal(n) ? kPi : 4 * kPi) + 1e-30f;
}

float LightSampler::SelectPdf(const Vec3& p, const Vec3& n, int index) const {
  const int nl = num_local_;
  const bool env = has_environment();
  if (nl > kMaxSpatialLights) {  // uniform among local lights and the environment
    return 1.0f / float(nl + (env ? 1 : 0));
  }
  float total = 0, mine = 0;
  for (int i = 0; i < nl; ++i) {
    const float w = Weight(i, p, n);
    total += w;
    if (i == index) mine = w;
  }
  if (env) {
    const float w = EnvironmentWeight(n);
    total += w;
    if (index == nl) mine = w;
  }
  return total > 0 ? mine / total : 0;
}

bool LightSampler::Sample(const Vec3& p, const Vec3& n, float u1, float u2, float u3,
                          bool include_env, LightSample* s, int* skipped,
                          bool env_importance) const {
  const int nl = num_local_;
  const bool env = include_env && has_environment();
  const int count = nl + (env ? 1 : 0);
  if (count == 0) return false;
  int chosen = -1;
  float psel = 0;
  if (nl > kMaxSpatialLights) {
    chosen = std::min(count - 1, int(u1 * float(count)));
    psel = 1.0f / float(count);
  } else {
    float w[kMaxSpatialLights + 1];
    float total = 0;
    int zero = 0;
    for (int i = 0; i < nl; ++i) {
      w[i] = Weight(i, p, n);
      zero += w[i] <= 0;
      total += w[i];
    }
    if (env) {
      w[nl] = EnvironmentWeight(n);
      total += w[nl];
    }
    if (skipped) *skipped += zero;
    if (!(total > 0)) return false;
    const float target = u1 * total;
    float acc = 0;
    for (int i = 0; i < count; ++i) {
      if (w[i] <= 0) continue;
      chosen = i;
      if (target < acc + w[i]) break;
      acc += w[i];
    }
    psel = w[chosen] / total;
  }
  if (chosen == nl) {  // the environment
    if (!SampleEnvironment(p, n, u2, u3, s, env_importance)) return false;
    s->pdf *= psel;
    s->value = Vec3(1.0f / s->pdf);  // times EvalEnvironment(wi): Scene::LightValue
    return true;
  }
  if (!SampleOne(chosen, p, n, u2, u3, s)) return false;
  s->pdf *= psel;
  s->value = s->value / psel;
  return true;
}

bool LightSampler::SampleEnvironment(const Vec3& p, const Vec3& n, float u2, float u3,
                                     LightSample* s, bool importance) const {
  return SampleEnvironment(guide_, p, n, u2, u3, s, importance);
}

bool LightSampler::SampleEnvironment(const EnvironmentGuide* guide, const Vec3& p, const Vec3& n,
                                     float u2, float u3, LightSample* s, bool importance) const {
  const int cell = guide != nullptr ? guide->CellOf(p, n) : -1;
  bool by_guide = false;
  if (cell >= 0) {
    by_guide = u2 < kGuideShare;
    u2 = by_guide ? u2 / kGuideShare : (u2 - kGuideShare) / (1 - kGuideShare);
    u2 = std::min(u2, 0x1.fffffep-1f);
  }
  if (by_guide) {
    float guide_pdf = 0;
    if (!guide->Sample(cell, u2, u3, &s->wi, &guide_pdf)) return false;
    const float base = UnguidedPdf(n, s->wi, importance);
    if (!(base > 0)) return false;  // below the horizon
    s->pdf = kGuideShare * guide_pdf + (1 - kGuideShare) * base;
  } else {
    bool by_cosine = true;
    if (importance && !env_map_.empty()) {
      // u2 picks the part of the mixture and is then stretched back to [0, 1).
      by_cosine = u2 < kEnvCosineShare;
      u2 = by_cosine ? u2 / kEnvCosineShare : (u2 - kEnvCosineShare) / (1 - kEnvCosineShare);
      u2 = std::min(u2, 0x1.fffffep-1f);
    }
    if (!by_cosine) {
      float grid_pdf = 0;
      if (!env_map_.Sample(u2, u3, &s->wi, &grid_pdf)) return false;
      // Below the horizon nothing arrives: no shadow ray (and no density there,
      // PdfEnvironmentAlone).
      const float c = HasNormal(n) ? Dot(s->wi, n) : 1.0f;
      if (!(c > 0)) return false;
      const float cosine = HasNormal(n) ? c * kInvPi : 0.25f * kInvPi;
      // The mixture's pdf, with the cell's density as the sampler drew it.
      s->pdf = kEnvCosineShare * cosine + (1 - kEnvCosineShare) * grid_pdf;
    } else {
      if (HasNormal(n)) {
        Vec3 a, b;
        MakeFrame(n, &a, &b);
        const Vec3 local = CosineHemisphere(u2, u3);
        s->wi = a * local.x + b * local.y + n * local.z;
      } else {
        s->wi = UniformSphere(u2, u3);
      }
      s->pdf = UnguidedPdf(n, s->wi, importance);
    }
    if (cell >= 0 && s->pdf > 0)
      s->pdf = kGuideShare * guide->Pdf(cell, s->wi) + (1 - kGuideShare) * s->pdf;
  }
  if (!(s->pdf > 0)) return false;
  s->distance = INFINITY;
  s->value = Vec3(1.0f / s->pdf);  // times EvalEnvironment(wi): Scene::LightValue
  s->environment = true;
  s->light = -1;
  return true;
}

float LightSampler::UnguidedPdf(const Vec3& n, const Vec3& wi, bool importance) const {
  // With a normal, SampleEnvironment gives only directions above the horizon (it refuses the
  // envmap's others): the density is 0 below, for MIS with a BSDF that transmits.
  const float c = HasNormal(n) ? Dot(wi, n) : 1.0f;
  if (!(c > 0)) return 0;
  const float cosine = HasNormal(n) ? c * kInvPi : 0.25f * kInvPi;
  if (!importance || env_map_.empty()) return cosine;
  return kEnvCosineShare * cosine + (1 - kEnvCosineShare) * env_map_.Pdf(wi);
}

float LightSampler::PdfEnvironmentAlone(const Vec3& p, const Vec3& n, const Vec3& wi,
                                        bool importance) const {
  const float base = UnguidedPdf(n, wi, importance);
  if (!(base > 0)) return 0;
  const int cell = guide_ != nullptr ? guide_->CellOf(p, n) : -1;
  return cell < 0 ? base : kGuideShare * guide_->Pdf(cell, wi) + (1 - kGuideShare) * base;
}

float LightSampler::PdfArea(const Vec3& p, const Vec3& n, int light, const Vec3& q, const Vec3& nq,
                            unsigned prim, const Vec3& wi) const {
  if (light < 0 || light >= num_local_) return 0;
  const float one = PdfOne(light, p, n, q, nq, prim, wi);
  return one > 0 ? one * SelectPdf(p, n, light) : 0;
}

float LightSampler::NeePdfArea(bool all, const Vec3& p, const Vec3& n, int light, const Vec3& q,
                               const Vec3& nq, unsigned prim, const Vec3& wi, bool coarse) const {
  if (!SamplesEveryLight(all)) return PdfArea(p, n, light, q, nq, prim, wi);
  // A light that got weight 0 at p (e.g. behind the horizon of a transmitter) was not sampled:
  // what reaches it through the BSDF counts in full.
  if (light < 0 || light >= num_local_ || Weight(light, p, n) <= 0) return 0;
  return PdfOne(light, p, n, q, nq, prim, wi, coarse);
}

float LightSampler::NeePdfEnvironment(bool all, const Vec3& p, const Vec3& n, const Vec3& wi,
                                      bool env_importance) const {
  if (!SamplesEveryLight(all)) return PdfEnvironment(p, n, wi, env_importance);
  return has_environment() ? PdfEnvironmentAlone(p, n, wi, env_importance) : 0;
}

float LightSampler::PdfEnvironment(const Vec3& p, const Vec3& n, const Vec3& wi,
                                   bool importance) const {
  if (!has_environment()) return 0;
  const float dir = PdfEnvironmentAlone(p, n, wi, importance);
  return dir > 0 ? dir * SelectPdf(p, n, num_local_) : 0;
}

Vec3 LightSampler::EvalEnvironment(const Vec3& d) const {
  Vec3 L;
  for (size_t i = size_t(num_local_); i < lights_.size(); ++i) {
    const Light& l = lights_[i];
    if (l.type == LightType::kConstant) {
      L += l.radiance;
    } else {
      float u, v;
      EnvmapUv(Normalize(l.world_to_env.ApplyVector(d)), &u, &v);
      L += l.envmap->EvalLatLong(u, v) * l.scale;
    }
  }
  return L;
}

}  // namespace irfarm
