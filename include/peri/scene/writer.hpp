// The emitter's line-oriented YAML writer and its value texts (src/scene/emit.cpp; each body
// kind's module writes its own keys with them).
#pragma once
#include <array>
#include <initializer_list>
#include <optional>
#include <string>
#include <utility>

#include "peri/scene/located_yaml.hpp"

namespace peri::scene_detail {

/// A string as a YAML scalar: plain when that reads back as the same string, else double-quoted.
std::string yaml_string(const std::string& s);
/// Numbers as a YAML flow list "[a, b, c]", each the shortest text that reads back the same.
std::string flow(std::initializer_list<double> xs);
std::string flow(const Vec3& v);
/// A 3x3 row-major matrix as a flow list of its rows.
std::string flow(const std::array<double, 9>& m);

/// The text of an enum's value, as the scene writes it (src/scene/schema.cpp).
const char* to_text(Influence k);
const char* to_text(PairKind k);
const char* to_text(Grid k);
const char* to_text(Quadrature k);
const char* to_text(StageKind k);
const char* to_text(bool b);

/// Line-oriented YAML writer: `key(indent, name, value)` writes "<indent>name: value".
class Writer {
 public:
  void line(int indent, const std::string& text) {
    out_.append(static_cast<std::size_t>(indent), ' ');
    out_ += text;
    out_ += '\n';
  }
  void key(int indent, const std::string& name, const std::string& value) {
    line(indent, name + ":" + (value.empty() ? "" : " " + value));
  }
  void key(int indent, const std::string& name, double value) { key(indent, name, format_number(value)); }
  void optional(int indent, const std::string& name, const std::optional<double>& value) {
    if (value) key(indent, name, *value);
  }
  std::string str() && { return std::move(out_); }

 private:
  std::string out_;
};

}  // namespace peri::scene_detail
