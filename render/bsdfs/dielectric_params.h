// Parameters shared by `dielectric`, `thindielectric` and `roughdielectric` (Mitsuba 3's
// defaults: int_ior bk7 1.5046, ext_ior air 1.000277, specular_reflectance and
// specular_transmittance 1).
#pragma once

#include "render/bsdfs/registry.h"

namespace irfarm {

inline absl::Status ParseDielectricParams(BsdfParams& p) {
  if (absl::Status s = p.Ior("int_ior", 1.5046f).status(); !s.ok()) return s;
  if (absl::Status s = p.Ior("ext_ior", 1.000277f).status(); !s.ok()) return s;
  if (absl::Status s = p.Color("specular_reflectance", Vec3(1.0f)).status(); !s.ok()) return s;
  return p.Color("specular_transmittance", Vec3(1.0f)).status();
}

struct DielectricParams {
  float eta;  // int_ior / ext_ior
  TexturedColor reflect, transmit;
  DielectricParams(const BsdfDesc& d, const BsdfBuildContext& ctx)
      : eta(d.Float("int_ior", 1.5046f) / d.Float("ext_ior", 1.000277f)),
        reflect(ctx.Color(d.Color("specular_reflectance", Vec3(1.0f)))),
        transmit(ctx.Color(d.Color("specular_transmittance", Vec3(1.0f)))) {}
};

}  // namespace irfarm
