// Parameters shared by `dielectric`, `thindielectric` and `roughdielectric` (Mitsuba 3's
// defaults: int_ior bk7 1.5046, ext_ior air 1.000277, specular_reflectance and
// specular_transmittance 1).
#pragma once

#include "render/bsdfs/registry.h"

namespace irfarm {

// `rough`: roughdielectric, which (as Mitsuba's) refuses equal indices: its half vector between
// wo and a straight-through wi is undefined, and every refracted sample would fail.
inline absl::Status ParseDielectricParams(BsdfParams& p, bool rough = false) {
  absl::StatusOr<float> int_ior = p.Ior("int_ior", 1.5046f);
  if (!int_ior.ok()) return int_ior.status();
  absl::StatusOr<float> ext_ior = p.Ior("ext_ior", 1.000277f);
  if (!ext_ior.ok()) return ext_ior.status();
  if (rough && *int_ior == *ext_ior)
    return p.Error("int_ior", "int_ior and ext_ior must differ (the surface would not refract)");
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
