// `thindielectric`: a thin pane of glass. Fresnel reflection including the interreflections
// inside the pane, R' = R + (1 - R)^2 R / (1 - R^2); the rest passes straight through.
//
// Passing straight through leaves a ray's direction unchanged, so a lamp or a sky behind the
// pane is reached by next-event estimation as well as by a path: the transmission is the null
// lobe (kNullTransmission, as a mask's), and shadow rays pass the pane with probability
// t (1 - R') (PassThrough; t the grey specular_transmittance). Integrators then leave the MIS
// state unchanged at the pane, a record ray that reaches a lamp through it finds direct light
// (DirectLight's, not the record's), and a photon through it is not a caustic. Without it, a
// lamp behind a diffuser pane or the sky behind a window lit the room only through the few paths
// that happened upon it. A coloured or textured transmittance cannot be one pass probability:
// such a pane keeps an ordinary delta transmission.
// Shadow rays towards a delta light (point, spot, directional) do not pass: no path can reach
// such a light, so Mitsuba 3's path tracer, whose shadow rays stop at every surface, has none of
// its light behind glass (its sun does not come through a glazed window), and irfarm keeps to
// the references, as the caustic map leaves out a delta light's first delta bounce.
#include <cmath>

#include "render/bsdfs/dielectric_params.h"
#include "render/bsdfs/fresnel.h"
#include "render/bsdfs/registry.h"

namespace irfarm {
namespace {

class ThinDielectricBsdf final : public Bsdf {
 public:
  ThinDielectricBsdf(float eta, const TexturedColor& reflect, const TexturedColor& transmit)
      : eta_(eta), reflect_(reflect), transmit_(transmit) {
    const Vec3 t = transmit.value;
    grey_ = transmit.texture == nullptr && t.x == t.y && t.y == t.z && t.x >= 0 && t.x <= 1;
  }

  uint32_t Flags() const override {
    return kDeltaReflection | (grey_ ? kNullTransmission : kDeltaTransmission);
  }
  Vec3 Eval(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override {
    return Vec3();
  }
  float Pdf(const BsdfContext&, const Vec3&, const Vec3&, uint32_t) const override { return 0; }

  BsdfSample Sample(const BsdfContext& ctx, const Vec3& wo, float u1, float, float,
                    uint32_t lobes) const override {
    BsdfSample s;
    const float r = Reflectance(std::abs(wo.z));
    const uint32_t t_lobe = grey_ ? kNullTransmission : kDeltaTransmission;
    const bool has_r = (lobes & kDeltaReflection) != 0, has_t = (lobes & t_lobe) != 0;
    if (!has_r && !has_t) return s;
    if (grey_) {
      // The null lobe is chosen with the pass probability t (1 - r), as shadow rays pass, and
      // weighs 1; reflection with r, or the rest when the null lobe is left out.
      const float pass = transmit_.value.x * (1 - r);
      if (has_t && (!has_r || u1 < pass)) {
        s.wi = -wo;
        s.weight = Vec3(has_r ? 1.0f : pass);
        s.lobe = kNullTransmission;
        s.delta_prob = has_r ? pass : 1.0f;
      } else if (has_r && (!has_t || u1 < pass + r)) {
        s.wi = ReflectZ(wo);
        s.weight = reflect_.Eval(ctx);
        s.lobe = kDeltaReflection;
        s.delta_prob = has_t ? r : 1.0f;
        if (!has_t) s.weight *= r;
      }
      return s;  // otherwise absorbed (t < 1)
    }
    if (has_r && (!has_t || u1 < r)) {
      s.wi = ReflectZ(wo);
      s.weight = reflect_.Eval(ctx) * (has_t ? 1.0f : r);
      s.lobe = kDeltaReflection;
      s.delta_prob = has_t ? r : 1.0f;
    } else {
      s.wi = -wo;
      s.weight = transmit_.Eval(ctx) * (has_r ? 1.0f : 1 - r);
      s.lobe = kDeltaTransmission;
      s.delta_prob = has_r ? 1 - r : 1.0f;
    }
    return s;
  }

  float PassThrough(const BsdfContext&, float cos_theta, bool, bool delta_light) const override {
    // Not towards a delta light (see the top).
    return grey_ && !delta_light ? transmit_.value.x * (1 - Reflectance(cos_theta)) : 0.0f;
  }

 private:
  // R' at |cos theta| = c. The pane has the same outside on both sides, so light enters it at
  // the relative index eta from either side, as Mitsuba's thindielectric has it (no total
  // internal reflection on the back).
  float Reflectance(float c) const {
    float cos_t;
    const float f = FresnelDielectric(c, eta_, &cos_t);
    return f < 1 ? f + (1 - f) * (1 - f) * f / (1 - f * f) : 1.0f;
  }

  float eta_;
  TexturedColor reflect_, transmit_;
  bool grey_ = false;  // transmittance one constant grey <= 1: the null lobe (see the top)
};

absl::Status Parse(BsdfParams& p) { return ParseDielectricParams(p); }

std::unique_ptr<Bsdf> Build(const BsdfDesc& d, const BsdfBuildContext& ctx) {
  const DielectricParams params(d, ctx);
  return std::make_unique<ThinDielectricBsdf>(params.eta, params.reflect, params.transmit);
}

}  // namespace

extern const BsdfPlugin kThinDielectricBsdf = {"thindielectric", Parse, Build};

}  // namespace irfarm
