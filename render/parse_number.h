// One number from scene or mesh text (an XML attribute's token, an OBJ or ASCII PLY field), as
// the loaders read them: a leading '+' allowed, the whole token a number, finite. Out-of-range
// values are read as strtod reads them (subnormals kept, overflow to infinity, then refused).
#pragma once

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <string>
#include <system_error>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace irfarm {

// Parses `token` into *out; on failure returns why ("malformed number 'x'", "non-finite number
// 'inf'"), else "".
inline std::string ParseFinite(absl::string_view token, double* out) {
  absl::string_view s = token;
  // One '+' only: "+-2" is no number (from_chars would read the "-2" after it).
  if (!s.empty() && s[0] == '+') {
    s.remove_prefix(1);
    if (!s.empty() && (s[0] == '-' || s[0] == '+'))
      return absl::StrCat("malformed number '", token, "'");
  }
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
