// Parameters shared by `plastic` and `roughplastic` (Mitsuba 3's defaults: int_ior
// polypropylene 1.49, ext_ior air, diffuse_reflectance 0.5, specular_reflectance 1, nonlinear
// false) and the sampling weight Mitsuba derives from the two reflectances' means.
#pragma once

#include "render/bsdfs/registry.h"

namespace irfarm {

inline absl::Status ParsePlasticParams(BsdfParams& p) {
  if (absl::Status s = p.Ior("int_ior", 1.49f).status(); !s.ok()) return s;
  if (absl::Status s = p.Ior("ext_ior", 1.000277f).status(); !s.ok()) return s;
  if (absl::Status s = p.Color("diffuse_reflectance", Vec3(0.5f)).status(); !s.ok()) return s;
  if (absl::Status s = p.Color("specular_reflectance", Vec3(1.0f)).status(); !s.ok()) return s;
  return p.Bool("nonlinear", false).status();
}

// Mean over the surface (texture average) and channels, as Mitsuba's Texture::mean.
inline float MeanOf(const TexturedColor& c) {
  const Vec3 v = c.texture ? c.texture->Average() : c.value;
  return (v.x + v.y + v.z) / 3;
}

struct PlasticParams {
  float eta;
  TexturedColor diffuse, specular;
  bool nonlinear;
  float specular_weight;  // probability weight of the specular lobe in sampling
  PlasticParams(const BsdfDesc& d, const BsdfBuildContext& ctx)
      : eta(d.Float("int_ior", 1.49f) / d.Float("ext_ior", 1.000277f)),
        diffuse(ctx.Color(d.Color("diffuse_reflectance", Vec3(0.5f)))),
        specular(ctx.Color(d.Color("specular_reflectance", Vec3(1.0f)))),
        nonlinear(d.Float("nonlinear", 0) != 0) {
    const float dm = MeanOf(diffuse), sm = MeanOf(specular);
    specular_weight = dm + sm > 0 ? sm / (dm + sm) : 0.5f;
  }
  // The diffuse base's reflectance after internal scattering under the coating, whose
  // hemispherical internal reflectance is `internal`: rho / (1 - rho internal) with
  // `nonlinear` (the colour shift of repeated bounces), else rho / (1 - internal).
  Vec3 Base(const BsdfContext& ctx, float internal) const {
    const Vec3 rho = diffuse.Eval(ctx);
    if (nonlinear)
      return Vec3(rho.x / (1 - rho.x * internal), rho.y / (1 - rho.y * internal),
                  rho.z / (1 - rho.z * internal));
    return rho / (1 - internal);
  }
};

}  // namespace irfarm
