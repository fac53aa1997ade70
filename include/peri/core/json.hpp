// JSON text for summary.json and its parts: a string with its escapes, a number (null when not
// finite, 12 significant digits).
#pragma once
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>
#include <string>

namespace peri {

inline std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char ch : text) {
    if (ch == '"' || ch == '\\') {
      out += '\\';
      out += ch;
    } else if (static_cast<unsigned char>(ch) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned char>(ch));
      out += buf;
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

inline std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream s;
  s << std::setprecision(12) << v;
  return s.str();
}

}  // namespace peri
