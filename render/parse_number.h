// One number from scene or mesh text (an XML attribute's token, an OBJ or ASCII PLY field), as
// the loaders read them: a leading '+' allowed, the whole token a number, finite. Out-of-range
// values are read as strtod reads them (subnormals kept, overflow to infinity, then refused).
#pragma once

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>
#include <system_error>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace irfarm {

// Removes one leading '+' from *s; false when another sign follows it ("+-2", "++2": no number,
// though from_chars would read the "-2" after the '+').
inline bool StripOnePlus(absl::string_view* s) {
  if (s->empty() || (*s)[0] != '+') return true;
  s->remove_prefix(1);
  return s->empty() || ((*s)[0] != '-' && (*s)[0] != '+');
}

// Whether a finite double is within a float's range (beyond 3.4e38 it would become infinite: a
// sphere of radius 1e39 vanished, a lamp of radiance 1e39 rendered black). False for NaN too.
inline bool FitsFloat(double v) { return std::abs(v) <= double(std::numeric_limits<float>::max()); }

// Parses `token` into *out; on failure returns why ("malformed number 'x'", "non-finite number
// 'inf'"), else "".
inline std::string ParseFinite(absl::string_view token, double* out) {
  absl::string_view s = token;
  if (!StripOnePlus(&s)) return absl::StrCat("malformed number '", token, "'");
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), *out);
  if (s.empty() || end != s.data() + s.size() ||
      (ec != std::errc() && ec != std::errc::result_out_of_range)) {
    return absl::StrCat("malformed number '", token, "'");
  }
  if (ec == std::errc::result_out_of_range) *out = std::strtod(std::string(s).c_str(), nullptr);
  if (!std::isfinite(*out)) return absl::StrCat("non-finite number '", token, "'");
  return "";
}

}  // namespace irfarm
