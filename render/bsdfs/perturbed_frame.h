// What `normalmap` and `bumpmap` share: a nested BSDF evaluated in a perturbed shading frame,
// as Mitsuba 3 does it. The wrapper works in the hit's local frame (z = the interpolated shading
// normal) and asks its subclass for the perturbed frame there; directions are carried into that
// frame for the nested BSDF. As in Mitsuba:
//   - a light direction on different sides of the two frames is black (Eval, Pdf 0; a sample
//     that lands there fails);
//   - with use_shadowing_function (default true) values are multiplied by Chiang et al.'s
//     (2019) shadow-terminator term 2 / (1 + sqrt(1 + a^2 tan^2 theta_l)), a^2 = min(1, tan^2
//     of the perturbed normal / 8), which is 1 for an unperturbed normal;
//   - flip_invalid_normals (default true): a perturbed normal that faces away from the viewer
//     has its tangential part mirrored (the subclass applies it with FlipInvalid).
// For the irradiance cache, DiffuseAlbedo is the nested one seen from the perturbed frame: the
// cache's irradiance is taken about the unperturbed normal, so normal detail reaches the
// diffuse lobe through path-traced light only.
#pragma once

#include <algorithm>
#include <cmath>

#include "render/bsdfs/registry.h"

namespace irfarm {

// An orthonormal frame given in the hit's local coordinates.
struct LocalFrame {
  Vec3 s, t, n;
  Vec3 ToFrame(const Vec3& w) const { return Vec3(Dot(w, s), Dot(w, t), Dot(w, n)); }
  Vec3 FromFrame(const Vec3& w) const { return s * w.x + t * w.y + n * w.z; }
};

// The hit's tangents in its local frame (z = ctx.n); without tangents (ctx.n = 0) the local
// x and y axes.
inline void LocalTangents(const BsdfContext& ctx, Vec3* dpdu, Vec3* dpdv) {
  if (!(LengthSquared(ctx.n) > 0)) {
    *dpdu = Vec3(1, 0, 0);
    *dpdv = Vec3(0, 1, 0);
    return;
  }
  const ShadingFrame f(ctx.n, ctx.dpdu);
  *dpdu = f.ToLocal(ctx.dpdu);
  *dpdv = f.ToLocal(ctx.dpdv);
}

// Mitsuba's flip_invalid_normals: if the viewer wo sees the back of n, mirror n's tangential
// part (local coordinates).
inline Vec3 FlipInvalid(const Vec3& n, const Vec3& wo) {
  return wo.z * Dot(wo, n) <= 0 ? Vec3(-n.x, -n.y, n.z) : n;
}

// The frame with normal n (unit, local) whose s is the projection of `tangent` (Gram-Schmidt);
// any tangent when that projection vanishes.
inline LocalFrame FrameAround(const Vec3& n, const Vec3& tangent) {
  LocalFrame f;
  f.n = n;
  const Vec3 s = tangent - n * Dot(n, tangent);
  if (LengthSquared(s) > 1e-20f) {
    f.s = Normalize(s);
    f.t = Cross(n, f.s);
  } else {
    MakeFrame(n, &f.s, &f.t);
  }
  return f;
}

class PerturbedFrameBsdf : public Bsdf {
 public:
  PerturbedFrameBsdf(const Bsdf* nested, bool shadowing) : nested_(nested), shadowing_(shadowing) {}

  uint32_t Flags() const override { return nested_->Flags(); }

  Vec3 Eval(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    const LocalFrame f = Frame(ctx, wo);
    const Vec3 wi_p = f.ToFrame(wi);
    if (wi.z * wi_p.z <= 0) return Vec3();
    return nested_->Eval(ctx, f.ToFrame(wo), wi_p, lobes) * Terminator(f.n, wi);
  }

  float Pdf(const BsdfContext& ctx, const Vec3& wo, const Vec3& wi, uint32_t lobes) const override {
    const LocalFrame f = Frame(ctx, wo);
    const Vec3 wi_p = f.ToFrame(wi);
    if (wi.z * wi_p.z <= 0) return 0;
    return nested_->Pdf(ctx, f.ToFrame(wo), wi_p, lobes);
  }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float u2, float u3,
                    uint32_t lobes) const override {
    const LocalFrame f = Frame(ctx, wo);
    BsdfSample s = nested_->Sample(ctx, f.ToFrame(wo), u1, u2, u3, lobes);
    if (IsBlack(s.weight)) return s;
    const Vec3 wi = f.FromFrame(s.wi);
    if (s.wi.z * wi.z <= 0 && s.lobe != kNullTransmission) return BsdfSample();
    s.wi = wi;
    if (s.lobe != kNullTransmission) s.weight *= Terminator(f.n, wi);
    return s;
  }

  Vec3 DiffuseAlbedo(const BsdfContext& ctx, const Vec3& wo) const override {
    return nested_->DiffuseAlbedo(ctx, Frame(ctx, wo).ToFrame(wo));
  }

  float PassThrough(const BsdfContext& ctx, float cos_theta, bool front,
                    bool delta_light) const override {
    return nested_->PassThrough(ctx, cos_theta, front, delta_light);
  }

  Vec3 ShadingNormal(const BsdfContext& ctx, const Vec3& wo) const override {
    return Frame(ctx, wo).n;
  }

 protected:
  // The perturbed frame at ctx, in the hit's local coordinates, for the viewer wo.
  virtual LocalFrame Frame(const BsdfContext& ctx, const Vec3& wo) const = 0;

 private:
  float Terminator(const Vec3& n, const Vec3& w) const {
    if (!shadowing_) return 1;
    const float tan2_n = n.z != 0 ? (1 - n.z * n.z) / (n.z * n.z) : INFINITY;
    const float a2 = std::min(0.125f * tan2_n, 1.0f);
    const float tan2_w = w.z != 0 ? (1 - w.z * w.z) / (w.z * w.z) : INFINITY;
    return 2 / (1 + std::sqrt(1 + a2 * tan2_w));
  }

  const Bsdf* nested_;
  bool shadowing_;
};

// Parameters both wrappers take (Mitsuba's defaults), and their one nested bsdf.
inline absl::Status ParsePerturbedFrameParams(BsdfParams& p, const char* what) {
  if (absl::Status s = p.Bool("flip_invalid_normals", true).status(); !s.ok()) return s;
  if (absl::Status s = p.Bool("use_shadowing_function", true).status(); !s.ok()) return s;
  absl::StatusOr<std::vector<int>> nested = p.NestedBsdfs();
  if (!nested.ok()) return nested.status();
  if (nested->size() != 1) return p.Error("", std::string(what) + " needs exactly one nested bsdf");
  return absl::OkStatus();
}

}  // namespace irfarm
