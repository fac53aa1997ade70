// The located YAML layer's text helpers (located_yaml.hpp).
#include "peri/scene/located_yaml.hpp"

#include <cctype>
#include <cstdio>
#include <cstring>

#include "peri/core/format.hpp"

namespace peri::scene_detail {

/// Shortest decimal text that reads back to the same double: the shortest fixed and scientific
/// forms (exponent without '+' and leading zeros), fixed unless it is more than 2 characters
/// longer. So 0.00025 and 1200 stay as they are, 1e-07 reads 1e-7.
std::string format_number(double v) {
  char buf[400];
  auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed);
  const std::string fixed(buf, r.ptr);
  r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::scientific);
  std::string sci(buf, r.ptr);
  const std::size_t e = sci.find('e');
  if (e != std::string::npos) {
    std::string exponent = sci.substr(e + 1);
    const bool negative = exponent[0] == '-';
    if (exponent[0] == '-' || exponent[0] == '+') exponent.erase(0, 1);
    exponent.erase(0, std::min(exponent.find_first_not_of('0'), exponent.size() - 1));
    sci = sci.substr(0, e + 1) + (negative ? "-" : "") + exponent;
  }
  return fixed.size() <= sci.size() + 2 ? fixed : sci;
}

std::string join(const std::vector<std::string>& parts, std::string_view sep) {
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (i > 0) out += sep;
    out += parts[i];
  }
  return out;
}

std::string child_path(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}


/// Parses a YAML plain scalar as a double. Accepts what std::from_chars accepts (plus a leading
/// '+'); YAML's .nan/.inf spellings and values beyond the largest double are reported as not
/// finite; non-zero values below the smallest normal double (2.2e-308) as subnormal, so that no
/// derived quantity silently loses its precision or becomes 0.
NumberText parse_number(std::string_view s, double& out) {
  std::string lower(s);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower == ".nan" || lower == ".inf" || lower == "+.inf" || lower == "-.inf")
    return NumberText::NotFinite;
  if (s.size() >= 2 && s[0] == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  if (s.empty()) return NumberText::NotANumber;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  if (r.ptr != s.data() + s.size()) return NumberText::NotANumber;
  if (r.ec == std::errc::result_out_of_range)  // too large, or too small in magnitude
    return std::fabs(std::strtod(std::string(s).c_str(), nullptr)) < 1 ? NumberText::Subnormal : NumberText::NotFinite;
  if (r.ec != std::errc()) return NumberText::NotANumber;
  if (!std::isfinite(out)) return NumberText::NotFinite;
  return out != 0 && std::fabs(out) < std::numeric_limits<double>::min() ? NumberText::Subnormal : NumberText::Ok;
}

/// A node as the "got ..." part of a message: scalars as written (quoted ones in quotes), other
/// nodes by their kind.
std::string describe(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "nothing (empty value)";
  if (node.IsMap()) return node.size() == 0 ? "an empty map" : "a map";
  if (node.IsSequence())
    return node.size() == 0 ? "an empty list" : "a list of " + std::to_string(node.size());
  auto [part, rest] = shown_parts(node.Scalar());
  return node.Tag() == "!" ? "\"" + part + "\"" + rest : part + rest;
}


bool valid_name(std::string_view s) {
  if (s.empty() || s.size() > 64 || s[0] == '-') return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
}

/// A refused name as a message shows it: one line in double quotes, '"' and '\\' escaped, other
/// bytes outside printable ASCII as \xNN, cut after 40 characters (the length then added).
std::string quote_name(std::string_view s) {
  std::string out = "\"";
  for (std::size_t k = 0; k < s.size() && k < 40; ++k) {
    const auto c = static_cast<unsigned char>(s[k]);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
  }
  out += "\"";
  if (s.size() > 40) out += " (" + std::to_string(s.size()) + " characters)";
  return out;
}

}  // namespace peri::scene_detail
