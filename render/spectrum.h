// Mitsuba 3's <spectrum> values in RGB mode: what its scene loader turns a spectrum into when it
// renders in RGB (the references' variant), so that scenes written with spectra render alike.
//   value="v"                 a uniform spectrum: grey v where it is reflected (a reflectance, a
//                             conductor's eta); in an emitter, v times equal-energy white
//                             converted to sRGB, (1.2048, 0.9483, 0.9089) v, which is not grey.
//   value="l1:v1, l2:v2, ..." wavelengths (nm, increasing) and values, linear between them and 0
//                             outside. Integrated against the CIE 1931 colour-matching functions
//                             (5 nm table, linear between samples) on Mitsuba's grid of 1000
//                             wavelengths from 360 to 830 nm, normalised by the integral of y-bar;
//                             outside an emitter weighted by the D65 illuminant, scaled as Mitsuba
//                             scales it (0.0101012736 x the CIE table: a flat reflectance of 1
//                             gives 0.9989, not 1, in Mitsuba too); XYZ to linear sRGB.
// Checked against Mitsuba 3.9.1's own conversions within 1e-5 (tests/render/spectrum_test.cc).
// Spectrum files (filename=) and spectrum plugins (type=) are not read.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/math.h"

namespace irfarm {

// The linear sRGB of `value` (the attribute's text); `emission`: the spectrum is an emitter's.
// Negative components (a saturated spectrum outside sRGB) are returned as they are: the caller
// decides (the scene loader clamps them to 0 with a warning, as Mitsuba does).
absl::StatusOr<Vec3> SpectrumToRgb(absl::string_view value, bool emission);

}  // namespace irfarm
