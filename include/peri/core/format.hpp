// Values as messages print them: a number to six significant digits, a text cut and escaped.
#pragma once
#include <cstddef>
#include <cstdio>
#include <iomanip>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>

namespace peri {

inline std::string number_text(double v) {
  std::ostringstream s;
  s << std::setprecision(6) << v;
  return s.str();
}

/// Characters of a value (a command-line argument, a scene value) that a message shows.
inline constexpr std::size_t kShownCharacters = 60;

/// The part of s a message shows (control characters as \xNN, at most kShownCharacters
/// characters) and what follows it ("... (N characters)" when cut, else nothing).
inline std::pair<std::string, std::string> shown_parts(std::string_view s) {
  std::string out;
  for (std::size_t k = 0; k < s.size() && k < kShownCharacters; ++k) {
    const auto c = static_cast<unsigned char>(s[k]);
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  return {out, s.size() > kShownCharacters ? "... (" + std::to_string(s.size()) + " characters)" : std::string()};
}

/// s as a message shows it: shown_parts joined.
inline std::string shown_value(std::string_view s) {
  auto [part, rest] = shown_parts(s);
  return part + rest;
}

}  // namespace peri
