// The BSDF interface: how light scatters at a surface point, in the LOCAL shading frame (z = the
// shading normal as the geometry defines it, i.e. its front side; x, y span the tangent plane).
// Directions point away from the surface: wo towards the viewer, wi towards the light; either
// may have z < 0 (back side / transmission). Every BSDF is one file under render/bsdfs/ and one
// line in registry.cc (see registry.h for the parse -> describe -> build path).
//
// Conventions shared by all implementations:
//   - Eval returns f(wo, wi) * |cos(theta_i)| (the "cosine-weighted" BSDF, Mitsuba 3's eval).
//   - Pdf is the solid-angle density of Sample producing wi (0 for delta lobes, which Eval and
//     Pdf never see: a delta lobe is only reached through Sample).
//   - Sample returns weight = f * |cos| / pdf for the lobe it chose (already divided by the
//     probability of choosing it); a failed sample has IsBlack(weight).
//   - One-sided semantics (../shared/scenes/README.md "BSDFs"): a BSDF that neither transmits
//     nor is wrapped in `twosided` is black when wo.z <= 0; the integrator then stops the path
//     there, so the back side blocks light as well.
//   - `lobes` restricts Eval/Pdf/Sample to part of the BSDF: kAllLobes, or kDiffuseLobe /
//     kNonDiffuseLobes, used by the irradiance cache (the cache serves the Lambertian lobe, the
//     rest is path traced). Sample's weight and Pdf are then those of the restricted sampler.
// Hot path: nothing here allocates.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/math.h"
#include "render/texture.h"

namespace irfarm {

// Lobe kinds, as bits. A BSDF reports the union of its lobes in Flags().
enum BsdfLobe : uint32_t {
  kDiffuseReflection = 1u << 0,   // Lambertian (served by the irradiance cache)
  kGlossyReflection = 1u << 1,    // rough specular (microfacet) reflection
  kGlossyTransmission = 1u << 2,  // rough refraction
  kDeltaReflection = 1u << 3,     // mirror
  kDeltaTransmission = 1u << 4,   // smooth refraction
  kNullTransmission = 1u << 5,    // straight through (mask): the ray continues unchanged
  kTwoSidedFlag = 1u << 6,        // not a lobe: the BSDF is the same on both sides
  // Lambertian to the other side (principledthin). Not served by the irradiance cache, whose
  // records hold the light on one side only: integrators sample it with the non-diffuse lobes.
  kDiffuseTransmission = 1u << 7,
};

// Which lobes a call may use.
enum LobeMask : uint32_t {
  kDiffuseLobe = kDiffuseReflection,
  kNonDiffuseLobes = ~uint32_t(kDiffuseReflection),
  kAllLobes = ~0u,
};

constexpr uint32_t kDeltaLobes = kDeltaReflection | kDeltaTransmission | kNullTransmission;
constexpr uint32_t kTransmissionLobes =
    kGlossyTransmission | kDeltaTransmission | kNullTransmission | kDiffuseTransmission;
// The lobes besides kDiffuseReflection that Eval sees (next-event estimation helps them).
constexpr uint32_t kSmoothNonDiffuseLobes =
    kGlossyReflection | kGlossyTransmission | kDiffuseTransmission;
// Lobes Eval sees on the other side of the surface: a BSDF with one takes light from both sides.
constexpr uint32_t kSmoothTransmissionLobes = kGlossyTransmission | kDiffuseTransmission;

// The normal next-event estimation selects lights with at a vertex whose facing normal is `nf`
// (LightSampler::SampleForNee; the same normal goes into the MIS weight of the light the next
// bounce hits): `nf` for a BSDF that only reflects, none (every direction) for one that
// transmits with lobes Eval sees, so that lamps behind it (a point light in a frosted bulb, the
// sun behind rough glass) are sampled too; a delta light is found by nothing else.
inline Vec3 LightSelectionNormal(uint32_t flags, const Vec3& nf) {
  return (flags & kSmoothTransmissionLobes) != 0 ? Vec3() : nf;
}

// Where the BSDF is evaluated: texture coordinates for textured parameters and, for normal and
// bump mapping, the surface's tangents (world space, per unit of u and v) with the shading
// normal n the local frame was made from (ShadingFrame(n, dpdu)). n = 0: no tangents known
// (unit tests); then local x, y are taken as the u, v directions.
struct BsdfContext {
  float u = 0, v = 0;
  Vec3 n, dpdu, dpdv;
};

struct BsdfSample {
  Vec3 wi;            // local
  Vec3 weight;        // f * |cos(theta_i)| / pdf, including the lobe choice; black = failed
  float pdf = 0;      // solid-angle pdf; 0 for delta lobes
  uint32_t lobe = 0;  // the BsdfLobe sampled (one bit)
  float eta = 1;      // relative index crossed (transmitted over incident), 1 if no refraction
  // A delta lobe: the probability with which Sample chose it among the BSDF's lobes (Mitsuba's
  // bs.pdf for a delta lobe). blendbsdf weighs a delta lobe with it as Mitsuba's does.
  float delta_prob = 1;
  bool IsDelta() const { return (lobe & kDeltaLobes) != 0; }
};

// An rgb value that is a constant or a bitmap texture looked up at (u, v).
struct TexturedColor {
  Vec3 value{0.5f, 0.5f, 0.5f};
  const Texture* texture = nullptr;  // owned by the Scene
  Vec3 Eval(const BsdfContext& ctx) const { return texture ? texture->Eval(ctx.u, ctx.v) : value; }
  // A scalar parameter (roughness, opacity) from the same, as Mitsuba's eval_1: an rgb
  // constant's channel mean, a texture's Texture::EvalScalar (a bitmap's luminance).
  float EvalScalar(const BsdfContext& ctx) const {
    if (texture) return texture->EvalScalar(ctx.u, ctx.v);
    return (value.x + value.y + value.z) * (1.0f / 3.0f);
  }
};

class Bsdf {
 public:
  virtual ~Bsdf() = default;

  // Union of BsdfLobe bits over all lobes (and kTwoSidedFlag).
  virtual uint32_t Flags() const = 0;
  virtual Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi,
                    uint32_t lobes = kAllLobes) const = 0;
  virtual float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi,
                    uint32_t lobes = kAllLobes) const = 0;
  // u1 picks a lobe, (u2, u3) the direction within it.
  virtual BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                            uint32_t lobes = kAllLobes) const = 0;

  // For the irradiance cache: the Lambertian lobe seen from wo is DiffuseAlbedo(wo) / pi times
  // the cosine-weighted incident radiance (the irradiance). Black when there is no such lobe on
  // wo's side. Exact for diffuse; for plastic it folds the angle-dependent Fresnel
  // transmission of the light's way in into its hemispherical average (see plastic.cc).
  virtual Vec3 DiffuseAlbedo(const BsdfContext& /*ctx*/, const Vec3& /*wo*/) const {
    return Vec3();
  }

  // The normal the BSDF shades with, in the local frame, seen from wo: (0, 0, 1) except under
  // normal and bump mapping (perturbed_frame.h). For integrators that approximate a lobe as
  // Lambertian about a normal (the irradiance cache's direct light): DiffuseAlbedo is the
  // albedo about this normal.
  virtual Vec3 ShadingNormal(const BsdfContext& /*ctx*/, const Vec3& /*wo*/) const {
    return Vec3(0, 0, 1);
  }

  // Probability that a shadow ray passes straight through (the kNullTransmission lobe: a mask, a
  // thin pane of glass) when it meets the surface at |cos theta| = cos_theta to its normal, on
  // its front side (against the geometric normal) or its back, on its way to a delta light
  // (point, spot, directional) or not; 0 for ordinary surfaces. Sample's null lobe is chosen
  // with the same probability and weight 1 (a grey weight may be folded in).
  virtual float PassThrough(const BsdfContext& /*ctx*/, float /*cos_theta*/, bool /*front*/,
                            bool /*delta_light*/) const {
    return 0;
  }

  bool HasDiffuse() const { return (Flags() & kDiffuseReflection) != 0; }
  bool HasNonDiffuse() const {
    return (Flags() & ~uint32_t(kDiffuseReflection | kTwoSidedFlag)) != 0;
  }
  bool HasSmooth() const {  // a lobe that Eval can see (so next-event estimation helps)
    return (Flags() & (kDiffuseReflection | kSmoothNonDiffuseLobes)) != 0;
  }
  bool Transmits() const { return (Flags() & kTransmissionLobes) != 0; }
  bool IsTwoSided() const { return (Flags() & kTwoSidedFlag) != 0; }

 protected:
  // The end of a Sample whose wi, lobe and eta are set: its pdf and weight over `lobes` (Eval /
  // Pdf, so that the weight agrees with what next-event estimation's MIS sees), or a failed
  // sample (lobe 0, weight black) where that pdf is not positive.
  BsdfSample Weighed(const BsdfContext& ctx, const Vec3& wo, BsdfSample s, uint32_t lobes) const {
    s.pdf = Pdf(ctx, wo, s.wi, lobes);
    if (!(s.pdf > 0)) {
      s.lobe = 0;
      return s;
    }
    s.weight = Eval(ctx, wo, s.wi, lobes) / s.pdf;
    return s;
  }
};

// The local shading frame of a hit: n = shading normal (front side); s along the surface's
// dp/du made orthogonal to n (as Mitsuba's sh_frame, so anisotropic roughness and normal maps
// follow the texture's u direction), t = n x s; any s from MakeFrame without a usable tangent.
struct ShadingFrame {
  Vec3 s, t, n;
  explicit ShadingFrame(const Vec3& normal) : n(normal) { MakeFrame(n, &s, &t); }
  ShadingFrame(const Vec3& normal, const Vec3& dpdu) : n(normal) {
    const Vec3 p = dpdu - n * Dot(n, dpdu);
    const float len2 = LengthSquared(p);
    if (len2 > 1e-12f * LengthSquared(dpdu) && len2 > 0) {
      s = p / std::sqrt(len2);
      t = Cross(n, s);
    } else {
      MakeFrame(n, &s, &t);
    }
  }
  Vec3 ToLocal(const Vec3& w) const { return Vec3(Dot(w, s), Dot(w, t), Dot(w, n)); }
  Vec3 ToWorld(const Vec3& w) const { return s * w.x + t * w.y + n * w.z; }
};

// A pair of world directions is usable at a surface only when the geometric normal ng agrees
// with the shading frame on whether it is a reflection or a transmission (otherwise the ray
// would leak through the surface, or a transmitted ray would be blocked by it).
inline bool SidesAgree(const Vec3& wo, const Vec3& wi, const Vec3& ng, float wo_z, float wi_z) {
  return (Dot(wo, ng) * Dot(wi, ng) > 0) == (wo_z * wi_z > 0);
}

// Local-frame helpers.
inline float CosTheta(const Vec3& w) { return w.z; }
inline float AbsCosTheta(const Vec3& w) { return std::abs(w.z); }
inline Vec3 ReflectZ(const Vec3& w) { return Vec3(-w.x, -w.y, w.z); }

}  // namespace irfarm
