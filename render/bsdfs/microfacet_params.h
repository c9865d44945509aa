// Reading a microfacet distribution's parameters as Mitsuba 3 does (distribution "beckmann" or
// "ggx", default beckmann; alpha, or alpha_u and alpha_v for anisotropy; each a number or a
// bitmap texture; sample_visible accepted), shared by the rough BSDFs.
#pragma once

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "render/bsdfs/microfacet.h"
#include "render/bsdfs/registry.h"

namespace irfarm {

// The distribution's name, in any case as Mitsuba reads it ("GGX" is ggx); stored lower-case.
inline absl::Status ParseMicrofacetDistribution(BsdfParams& p) {
  absl::StatusOr<std::string> dist = p.String("distribution", "beckmann");
  if (!dist.ok()) return dist.status();
  const std::string lower = absl::AsciiStrToLower(*dist);
  if (lower != "beckmann" && lower != "ggx")
    return p.Error("distribution", absl::StrCat("unknown microfacet distribution '", *dist,
                                                "' (supported: beckmann, ggx)"));
  if (p.Has("distribution")) p.desc().strings["distribution"] = lower;
  return absl::OkStatus();
}

inline absl::Status ParseMicrofacetParams(BsdfParams& p) {
  if (absl::Status s = ParseMicrofacetDistribution(p); !s.ok()) return s;
  if (p.Has("alpha") && (p.Has("alpha_u") || p.Has("alpha_v")))
    return p.Error("alpha", "give either alpha or alpha_u/alpha_v, not both");
  if (p.Has("alpha_u") != p.Has("alpha_v"))
    return p.Error(p.Has("alpha_u") ? "alpha_u" : "alpha_v", "give both alpha_u and alpha_v");
  if (p.Has("alpha_u")) {
    if (absl::Status s = p.Color("alpha_u", Vec3(0.1f)).status(); !s.ok()) return s;
    if (absl::Status s = p.Color("alpha_v", Vec3(0.1f)).status(); !s.ok()) return s;
  } else {
    absl::StatusOr<ColorParam> a = p.Color("alpha", Vec3(0.1f));
    if (!a.ok()) return a.status();
    p.desc().colors["alpha_u"] = *a;
    p.desc().colors["alpha_v"] = *a;
  }
  // Visible-normal sampling is how irfarm samples GGX always (see microfacet.h).
  return p.Bool("sample_visible", true).status();
}

// The distribution's roughness, possibly textured.
struct MicrofacetParams {
  MicrofacetType type = MicrofacetType::kBeckmann;
  TexturedColor alpha_u, alpha_v;
  MicrofacetParams(const BsdfDesc& d, const BsdfBuildContext& ctx)
      : type(d.String("distribution", "beckmann") == "ggx" ? MicrofacetType::kGgx
                                                           : MicrofacetType::kBeckmann),
        alpha_u(ctx.Color(d.Color("alpha_u", Vec3(0.1f)))),
        alpha_v(ctx.Color(d.Color("alpha_v", Vec3(0.1f)))) {}
  Microfacet At(const BsdfContext& ctx) const {
    return Microfacet(type, alpha_u.EvalScalar(ctx), alpha_v.EvalScalar(ctx));
  }
};

}  // namespace irfarm
