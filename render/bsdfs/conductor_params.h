// Mitsuba 3's named conductor materials as RGB complex indices of refraction (eta, k), shared
// by `conductor` and `roughconductor`, and the parameter reading they have in common.
//
// The numbers are Mitsuba 3.9.1's own RGB values (variant scalar_rgb, which integrates its
// measured spectra against the sRGB curves), read with:
//   import mitsuba as mi; mi.set_variant("scalar_rgb")
//   p = mi.traverse(mi.load_dict({"type": "conductor", "material": "Au"}))
//   print(p["eta.value"], p["k.value"])
// for every name in Mitsuba's list (a few k values that Mitsuba clamps from slightly negative
// to 0 are given as Mitsuba clamps them).
#pragma once

#include <string>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/math.h"
#include "render/bsdfs/registry.h"

namespace irfarm {

struct NamedConductor {
  const char* name;
  Vec3 eta, k;
};

inline constexpr NamedConductor kNamedConductors[] = {
    {"a-C", {2.94405f, 2.22714f, 1.96816f}, {0.887465f, 0.799299f, 0.81529f}},
    {"Ag", {0.155276f, 0.116728f, 0.138388f}, {4.82835f, 3.12222f, 2.1469f}},
    {"Al", {1.6575f, 0.880405f, 0.521244f}, {9.22381f, 6.2695f, 4.837f}},
    {"AlAs", {3.6053f, 3.23294f, 2.21632f}, {0.000679437f, 0.0f, 0.00751271f}},
    {"AlAs_palik", {3.6053f, 3.23294f, 2.21632f}, {0.000679437f, 0.0f, 0.00751271f}},
    {"AlSb", {0.0f, 4.13937f, 4.66925f}, {0.0f, 0.0940091f, 1.30057f}},
    {"AlSb_palik", {0.0f, 4.13937f, 4.66925f}, {0.0f, 0.0940091f, 1.30057f}},
    {"Au", {0.143036f, 0.375307f, 1.44205f}, {3.983f, 2.38556f, 1.60336f}},
    {"Be", {4.18501f, 3.18503f, 2.78406f}, {3.83547f, 3.01012f, 2.86899f}},
    {"Cr", {4.36967f, 2.91651f, 1.6549f}, {5.20655f, 4.23131f, 3.7547f}},
    {"CsI", {2.1449f, 1.70232f, 1.66243f}, {0.0f, 0.0f, 0.0f}},
    {"Cu", {0.201005f, 0.92375f, 1.10222f}, {3.91326f, 2.45305f, 2.14209f}},
    {"Cu_palik", {0.213229f, 0.919715f, 1.10241f}, {3.92187f, 2.45733f, 2.13658f}},
    {"Cu2O", {3.55177f, 2.94987f, 2.75188f}, {0.114207f, 0.193897f, 0.606134f}},
    {"CuO", {3.24754f, 2.44781f, 2.21022f}, {0.52109f, 0.570031f, 0.722179f}},
    {"d-C", {2.70872f, 2.31883f, 2.2289f}, {0.0f, 0.0f, 0.0f}},
    {"Hg", {2.39894f, 1.44003f, 0.90957f}, {6.32759f, 4.37192f, 3.42176f}},
    {"HgTe", {4.77904f, 3.2312f, 2.6599f}, {1.63161f, 1.58081f, 1.72929f}},
    {"Ir", {3.0863f, 2.08219f, 1.61791f}, {5.59215f, 4.06709f, 3.26731f}},
    {"K", {0.0640432f, 0.0464098f, 0.0381849f}, {2.1042f, 1.34894f, 0.913126f}},
    {"Li", {0.265791f, 0.195618f, 0.220949f}, {3.54015f, 2.31112f, 1.66861f}},
    {"MgO", {2.08958f, 1.65072f, 1.59488f}, {4.3327e-12f, 0.0f, 2.49865e-11f}},
    {"Mo", {4.48397f, 3.52513f, 2.77631f}, {4.11144f, 3.42083f, 3.15061f}},
    {"Na_palik", {0.0602694f, 0.0561409f, 0.0619884f}, {3.17927f, 2.11249f, 1.57904f}},
    {"Nb", {3.42007f, 2.79009f, 2.39563f}, {3.44139f, 2.73767f, 2.57975f}},
    {"Ni_palik", {2.3673f, 1.66337f, 1.46708f}, {4.49881f, 3.05015f, 2.34544f}},
    {"Rh", {2.58579f, 1.86022f, 1.55426f}, {6.78226f, 4.70299f, 3.97607f}},
    {"Se", {4.05831f, 2.84294f, 2.82085f}, {0.75405f, 0.638444f, 0.521808f}},
    {"SiC", {3.17234f, 2.52597f, 2.47937f}, {7.53766e-07f, 0.0f, 1.01925e-05f}},
    {"SnTe", {4.52425f, 1.98164f, 1.28159f}, {0.0f, 0.0f, 0.0f}},
    {"Ta", {2.06272f, 2.39294f, 2.62793f}, {2.40836f, 1.74149f, 1.94703f}},
    {"Te", {7.39023f, 4.4821f, 2.63711f}, {3.25602f, 3.52706f, 3.29205f}},
    {"ThF4", {1.83071f, 1.44223f, 1.38765f}, {0.0f, 0.0f, 0.0f}},
    {"TiC", {3.70053f, 2.83742f, 2.58229f}, {3.26564f, 2.35159f, 2.17279f}},
    {"TiN", {1.64845f, 1.15052f, 1.37982f}, {3.36833f, 1.9435f, 1.10207f}},
    {"TiO2", {3.45661f, 2.80174f, 2.90517f}, {0.000105265f, 0.0f, 0.000652887f}},
    {"VC", {3.65757f, 2.75274f, 2.53267f}, {3.0683f, 2.19869f, 1.96319f}},
    {"V_palik", {4.27758f, 3.51295f, 2.76107f}, {3.4913f, 2.88945f, 3.11152f}},
    {"VN", {2.8656f, 2.11919f, 1.94009f}, {3.03224f, 2.05612f, 1.61631f}},
    {"W", {4.37082f, 3.30025f, 2.99841f}, {3.50064f, 2.60487f, 2.27323f}},
};

// Reads material / eta / k / specular_reflectance as Mitsuba 3 does: eta and k are given
// explicitly, or come from `material` (default "none": a perfect mirror, recorded as k = 0 and
// eta = 0, which FresnelConductor3 below treats as reflectance 1).
inline absl::Status ParseConductorParams(BsdfParams& p) {
  absl::StatusOr<std::string> material = p.String("material", "none");
  if (!material.ok()) return material.status();
  const bool explicit_ior = p.Has("eta") || p.Has("k");
  // material="none" beside eta/k is what Mitsuba's own exports write: the eta/k then count.
  if (explicit_ior && p.Has("material") && *material != "none")
    return p.Error("material", "give either material or eta/k, not both");
  Vec3 eta(0.0f), k(0.0f);
  bool none = *material == "none";
  if (!explicit_ior && !none) {
    bool found = false;
    std::string names = "none";
    for (const NamedConductor& c : kNamedConductors) {
      if (*material == c.name) {
        eta = c.eta;
        k = c.k;
        found = true;
      }
      absl::StrAppend(&names, ", ", c.name);
    }
    if (!found)
      return p.Error("material", absl::StrCat("unknown conductor material '", *material,
                                              "' (supported: ", names, ")"));
  }
  if (explicit_ior) {
    none = false;
    absl::StatusOr<Vec3> e = p.Rgb("eta", Vec3(0.0f));
    if (!e.ok()) return e.status();
    absl::StatusOr<Vec3> kk = p.Rgb("k", Vec3(1.0f));
    if (!kk.ok()) return kk.status();
    eta = *e;
    k = *kk;
  }
  BsdfDesc& d = p.desc();
  d.floats["mirror"] = none ? 1.0f : 0.0f;
  d.colors["eta"].value = eta;
  d.colors["k"].value = k;
  return p.Color("specular_reflectance", Vec3(1.0f)).status();
}

}  // namespace irfarm
