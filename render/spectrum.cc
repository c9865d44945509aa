#include "render/spectrum.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace irfarm {
namespace {

struct CieSample {
  double x, y, z, d65;
};
constexpr CieSample kCie[] = {
#include "render/spectrum_tables.inc"
};
constexpr int kCieCount = int(sizeof(kCie) / sizeof(kCie[0]));
constexpr double kCieFirst = 360, kCieStep = 5;
static_assert(kCieCount == 95, "5 nm from 360 to 830 nm");
// Mitsuba's grid and its scale of the D65 table (MI_CIE_D65_NORMALIZATION in Mitsuba 3.9.1).
constexpr int kGrid = 1000;
constexpr double kGridLast = 830;
constexpr double kD65Scale = 0.010101273599490354;
// CIE XYZ to linear sRGB (D65 white), the matrix Mitsuba uses.
constexpr double kXyzToRgb[3][3] = {{3.240479, -1.537150, -0.498535},
                                    {-0.969256, 1.875991, 0.041556},
                                    {0.055648, -0.204043, 1.057311}};

CieSample CieAt(double wavelength) {
  const double t = (wavelength - kCieFirst) / kCieStep;
  const int i = std::clamp(int(std::floor(t)), 0, kCieCount - 2);
  const double f = std::clamp(t - i, 0.0, 1.0);
  const CieSample& a = kCie[i];
  const CieSample& b = kCie[i + 1];
  return {a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.z + f * (b.z - a.z),
          a.d65 + f * (b.d65 - a.d65)};
}

Vec3 XyzToRgb(const double xyz[3]) {
  double rgb[3];
  for (int r = 0; r < 3; ++r)
    rgb[r] = kXyzToRgb[r][0] * xyz[0] + kXyzToRgb[r][1] * xyz[1] + kXyzToRgb[r][2] * xyz[2];
  return Vec3(float(rgb[0]), float(rgb[1]), float(rgb[2]));
}

}  // namespace

absl::StatusOr<Vec3> SpectrumToRgb(absl::string_view value, bool emission) {
  const absl::string_view text = absl::StripAsciiWhitespace(value);
  double uniform = 0;
  if (text.find(':') == absl::string_view::npos) {
    if (!absl::SimpleAtod(text, &uniform) || !std::isfinite(uniform)) {
      return absl::InvalidArgumentError(
          absl::StrCat("spectrum value '", value,
                       "' is neither a number nor wavelength:value pairs (\"400:0.1, 700:0.8\")"));
    }
    if (!emission) return Vec3(float(uniform));
    const double white[3] = {uniform, uniform, uniform};
    return XyzToRgb(white);
  }
  std::vector<double> wl, v;
  // Pairs are separated by commas, white space or both, as Mitsuba's parser splits them.
  for (absl::string_view pair :
       absl::StrSplit(text, absl::ByAnyChar(", \t\r\n"), absl::SkipEmpty())) {
    pair = absl::StripAsciiWhitespace(pair);
    const std::vector<absl::string_view> parts = absl::StrSplit(pair, ':');
    double l = 0, x = 0;
    if (parts.size() != 2 || !absl::SimpleAtod(parts[0], &l) || !absl::SimpleAtod(parts[1], &x) ||
        !std::isfinite(l) || !std::isfinite(x)) {
      return absl::InvalidArgumentError(
          absl::StrCat("spectrum entry '", pair, "' is not wavelength:value"));
    }
    if (!wl.empty() && !(l > wl.back())) {
      return absl::InvalidArgumentError(
          absl::StrCat("spectrum wavelengths must increase: ", l, " after ", wl.back()));
    }
    wl.push_back(l);
    v.push_back(x);
  }
  if (wl.size() < 2) {
    return absl::InvalidArgumentError("a spectrum needs at least two wavelength:value pairs");
  }
  double xyz[3] = {0, 0, 0}, y_sum = 0;
  size_t k = 0;  // the pair interval the grid has reached
  for (int i = 0; i < kGrid; ++i) {
    const double l = kCieFirst + (kGridLast - kCieFirst) * i / (kGrid - 1);
    const CieSample c = CieAt(l);
    y_sum += c.y;
    if (l < wl.front() || l > wl.back()) continue;
    while (k + 2 < wl.size() && l > wl[k + 1]) ++k;
    const double f = (l - wl[k]) / (wl[k + 1] - wl[k]);
    const double s = (v[k] + f * (v[k + 1] - v[k])) * (emission ? 1.0 : c.d65 * kD65Scale);
    xyz[0] += c.x * s;
    xyz[1] += c.y * s;
    xyz[2] += c.z * s;
  }
  for (double& c : xyz) c /= y_sum;
  return XyzToRgb(xyz);
}

}  // namespace irfarm
