// The scene reader's located YAML: values that know their key path and source line, and turn
// every problem into one InputError "<file>:<line>: <dotted.key.path>: <what is wrong>" ("--set"
// instead of "<file>:<line>" for a value an override set). The readers (src/scene/readers.cpp and
// each body kind's module, src/geometry/kinds/), the overrides and the emitter share these.
//
// Conventions of the reader:
//  - every map's keys are checked against the schema (unknown key -> error listing the allowed
//    keys), then its required keys, then its values;
//  - an optional key whose value is empty (`key:` or `key: ~`) counts as not given;
//  - numbers are plain (unquoted) scalars and must be finite; a quoted "12" is a string;
//  - integers are written as integers, or as a float whose value is exactly integral (1e3 and
//    1000.0 are accepted, 2.5 is not);
//  - booleans are true/false (also True/TRUE/False/FALSE, as in YAML 1.2);
//  - a missing key is reported at the line of the map that should contain it, an empty value at
//    the line of its key, any other value at its own line.
#pragma once
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "peri/core/error.hpp"
#include "peri/scene/keys.hpp"
#include "peri/scene/scene.hpp"

namespace peri::scene_detail {

// ------------------------------------------------------------------------------------------------
// Small text helpers

/// Shortest decimal text that reads back to the same double (1e-07 reads 1e-7).
std::string format_number(double v);
std::string join(const std::vector<std::string>& parts, std::string_view sep = ", ");
/// "parent.key" (or "key" at the top level).
std::string child_path(const std::string& parent, const std::string& key);

enum class NumberText { Ok, NotANumber, NotFinite, Subnormal };
/// A YAML plain scalar as a double: finite, and 0 or at least the smallest normal double.
NumberText parse_number(std::string_view s, double& out);
/// A node as the "got ..." part of a message (a scalar as shown_value, core/format.hpp, shows
/// it, in quotes where the file quoted it).
std::string describe(const YAML::Node& node);

/// Names given in a scene (the scene's, materials', bodies', cracks', boundaries', tools' and
/// stages') become a directory (out/<scene name>), CSV columns, JSON keys and --set path segments.
inline constexpr const char* kNameRule = "(1 to 64 characters of A-Z a-z 0-9 _ - not starting with -)";
bool valid_name(std::string_view s);
/// A refused name as a message shows it (quoted, escaped, cut after 40 characters).
std::string quote_name(std::string_view s);

// ------------------------------------------------------------------------------------------------
// Locations and messages

/// What every reader object shares: the file name and the key paths set by overrides.
class Context {
 public:
  explicit Context(std::string file) : file_(std::move(file)) {}

  void mark_overridden(const std::string& path) { overridden_.push_back(path); }

  /// True if `path` or one of its ancestors was set by an override.
  bool overridden(const std::string& path) const {
    for (const std::string& o : overridden_) {
      if (path == o) return true;
      if (o.empty() || (path.size() > o.size() && path.compare(0, o.size(), o) == 0 && path[o.size()] == '.'))
        return true;
    }
    return false;
  }

  SourceLoc loc(const YAML::Mark& mark, const std::string& path) const {
    if (overridden(path)) return SourceLoc{"--set", 0};
    return SourceLoc{file_, mark.line >= 0 ? mark.line + 1 : 0};
  }

  [[noreturn]] void fail(const SourceLoc& where, const std::string& path, const std::string& what) const {
    throw InputError(where.str() + ": " + (path.empty() ? "top level" : path) + ": " + what);
  }

 private:
  std::string file_;
  std::vector<std::string> overridden_;
};

/// A YAML value at a known key path; converts it to the expected type or throws.
class Value {
 public:
  Value(const Context& ctx, YAML::Node node, std::string path, YAML::Mark key_mark = YAML::Mark::null_mark())
      : ctx_(&ctx), node_(std::move(node)), path_(std::move(path)), key_mark_(key_mark) {}

  const Context& context() const { return *ctx_; }
  const YAML::Node& node() const { return node_; }
  const std::string& path() const { return path_; }
  bool is_null() const { return !node_.IsDefined() || node_.IsNull(); }

  SourceLoc where() const {
    // An empty value's mark points at the next token; its key's line is the useful one.
    const YAML::Mark mark = (is_null() && key_mark_.line >= 0) ? key_mark_ : node_.Mark();
    return ctx_->loc(mark, path_);
  }

  [[noreturn]] void fail(const std::string& what) const { ctx_->fail(where(), path_, what); }

  /// The value as the message's "got ..." part.
  std::string got() const { return describe(node_); }

  /// Any scalar, as text.
  std::string string() const {
    if (!node_.IsScalar()) fail("expected a string, got " + got());
    return node_.Scalar();
  }

  /// A non-empty scalar, as text.
  std::string name() const {
    if (!node_.IsScalar() || node_.Scalar().empty()) fail("expected a non-empty string, got " + got());
    return node_.Scalar();
  }

  /// The name given to a `what` (scene, crack, ...): see valid_name.
  std::string given_name(const std::string& what) const {
    const std::string s = name();
    if (!valid_name(s)) fail("expected a " + what + " name " + kNameRule + ", got " + quote_name(s));
    return s;
  }

  /// A finite number; `expected` describes it for the message ("a positive number [m]").
  double number(const std::string& expected = "a number") const {
    if (!node_.IsScalar() || quoted()) fail("expected " + expected + ", got " + got());
    double v = 0.0;
    switch (parse_number(node_.Scalar(), v)) {
      case NumberText::Ok:
        return v;
      case NumberText::NotFinite:
        fail("expected a finite number, got " + got());
      case NumberText::Subnormal:
        fail("expected 0 or a number of magnitude at least 2.2e-308 (the smallest normal double), got " + got());
      case NumberText::NotANumber:
        break;
    }
    fail("expected " + expected + ", got " + got());
  }

  /// A finite number for which ok(v) holds.
  template <class Pred>
  double number_if(const std::string& expected, Pred ok) const {
    const double v = number(expected);
    if (!ok(v)) fail("expected " + expected + ", got " + got());
    return v;
  }

  double positive(std::string_view unit) const {
    return number_if("a positive number" + unit_suffix(unit), [](double v) { return v > 0; });
  }

  double non_negative(std::string_view unit) const {
    return number_if("a non-negative number" + unit_suffix(unit), [](double v) { return v >= 0; });
  }

  /// An integer >= lo (and <= hi); the message names the whole range. Exactly integral float
  /// spellings (1e3) are accepted.
  long integer(long lo, long hi = std::numeric_limits<long>::max()) const {
    const std::string expected = "an integer >= " + std::to_string(lo) +
                                 (hi < std::numeric_limits<long>::max() ? " and <= " + std::to_string(hi) : "");
    if (!node_.IsScalar() || quoted()) fail("expected " + expected + ", got " + got());
    std::string_view s = node_.Scalar();
    if (s.size() >= 2 && s[0] == '+' && s[1] != '-') s.remove_prefix(1);
    long v = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec != std::errc() || r.ptr != s.data() + s.size()) {
      const double d = number(expected);
      // 2^53: beyond it a double no longer represents every integer.
      if (d != std::floor(d) || std::fabs(d) > 9007199254740992.0)
        fail("expected " + expected + ", got " + got());
      v = static_cast<long>(d);
    }
    if (v < lo || v > hi) fail("expected " + expected + ", got " + got());
    return v;
  }

  bool boolean() const {
    if (node_.IsScalar() && !quoted()) {
      const std::string& s = node_.Scalar();
      if (s == "true" || s == "True" || s == "TRUE") return true;
      if (s == "false" || s == "False" || s == "FALSE") return false;
    }
    fail("expected true or false, got " + got());
  }

  /// One of a fixed set of words.
  template <class E>
  E choice(std::initializer_list<std::pair<const char*, E>> options) const {
    return choice_of(options);
  }
  /// One of a set of words known at run time (e.g. the registered body kinds).
  template <class E>
  E choice(const std::vector<std::pair<std::string, E>>& options) const {
    return choice_of(options);
  }

  /// The entries of a list.
  std::vector<Value> list(const std::string& expected) const {
    if (!node_.IsSequence()) fail("expected " + expected + ", got " + got());
    std::vector<Value> out;
    for (std::size_t i = 0; i < node_.size(); ++i)
      out.emplace_back(*ctx_, node_[i], child_path(path_, std::to_string(i)));
    return out;
  }

  /// A list of between n_min and n_max numbers.
  std::vector<double> numbers(std::size_t n_min, std::size_t n_max, const std::string& expected,
                              std::string_view unit) const {
    const std::vector<Value> items = list(expected);
    if (items.size() < n_min || items.size() > n_max) fail("expected " + expected + ", got " + got());
    std::vector<double> out;
    for (const Value& item : items) out.push_back(item.number("a number" + unit_suffix(unit)));
    return out;
  }

  std::array<double, 2> vec2(std::string_view unit) const {
    const auto xs = numbers(2, 2, "a list of 2 numbers [x, y]" + unit_suffix(unit), unit);
    return {xs[0], xs[1]};
  }

  Vec3 vec3(std::string_view unit) const {
    const auto xs = numbers(3, 3, "a list of 3 numbers [x, y, z]" + unit_suffix(unit), unit);
    return {xs[0], xs[1], xs[2]};
  }

  /// A 3x3 matrix written as a list of 3 rows of 3 numbers; row-major.
  std::array<double, 9> matrix3(std::string_view unit) const {
    const std::string expected = "a 3x3 matrix [[a, b, c], [d, e, f], [g, h, i]]" + unit_suffix(unit);
    const std::vector<Value> rows = list(expected);
    if (rows.size() != 3) fail("expected " + expected + ", got " + got());
    std::array<double, 9> m{};
    for (int r = 0; r < 3; ++r) {
      const auto xs = rows[r].numbers(3, 3, "a row of 3 numbers" + unit_suffix(unit), unit);
      for (int c = 0; c < 3; ++c) m[3 * r + c] = xs[c];
    }
    return m;
  }

  static std::string unit_suffix(std::string_view unit) {
    return unit.empty() ? std::string() : " [" + std::string(unit) + "]";
  }

  /// The plain (unquoted) scalar, or nothing (a quoted string, a list, a map).
  std::optional<std::string> word() const {
    if (node_.IsScalar() && !quoted()) return node_.Scalar();
    return std::nullopt;
  }

 private:
  template <class Options>
  auto choice_of(const Options& options) const {
    std::vector<std::string> names;
    for (const auto& [word, e] : options) {
      if (node_.IsScalar() && !quoted() && node_.Scalar() == word) return e;
      names.emplace_back(word);
    }
    fail("expected one of: " + join(names) + "; got " + got());
  }

  /// Quoted (or otherwise non-plain) scalars are strings, never numbers or booleans.
  bool quoted() const { return node_.Tag() == "!"; }

  const Context* ctx_;
  YAML::Node node_;
  std::string path_;
  YAML::Mark key_mark_;
};

/// A YAML map at a known key path. The constructor checks the keys: each must be a non-empty
/// scalar, given once, and (with a schema) allowed; required keys must be present.
class Map {
 public:
  /// `keys` null: free keys (names of materials, bodies).
  Map(const Value& v, const Keys* keys, const std::string& expected)
      : ctx_(&v.context()), path_(v.path()), where_(v.where()) {
    if (!v.node().IsMap()) v.fail("expected " + expected + ", got " + v.got());
    for (auto it = v.node().begin(); it != v.node().end(); ++it) {
      const YAML::Node k = it->first;  // a copy: `it->` yields a temporary
      if (!k.IsScalar() || k.Scalar().empty()) {
        Value kv(*ctx_, k, path_);
        kv.fail("expected a name as map key, got " + kv.got());
      }
      const std::string name = k.Scalar();
      const std::string path = child_path(path_, name);
      for (const Entry& e : entries_) {
        if (e.name == name) {
          ctx_->fail(ctx_->loc(k.Mark(), path), path,
                     "duplicate key (first given at line " + std::to_string(e.key_mark.line + 1) + ")");
        }
      }
      if (keys != nullptr &&
          std::none_of(keys->begin(), keys->end(), [&](const Key& key) { return name == key.name; })) {
        std::vector<std::string> allowed;
        for (const Key& key : *keys) allowed.emplace_back(key.name);
        ctx_->fail(ctx_->loc(k.Mark(), path), path, "unknown key; expected one of: " + join(allowed));
      }
      entries_.push_back(Entry{name, k.Mark(), it->second});
    }
    if (keys != nullptr) {
      for (const Key& key : *keys)
        if (key.required && find(key.name) == nullptr) missing(key.name, key.what);
    }
  }

  const std::string& path() const { return path_; }
  const SourceLoc& where() const { return where_; }
  bool empty() const { return entries_.empty(); }

  /// Free keys that name a `what` each (materials, bodies): see valid_name; reported at the key.
  void check_key_names(const std::string& what) const {
    for (const Entry& e : entries_)
      if (!valid_name(e.name))
        ctx_->fail(ctx_->loc(e.key_mark, child_path(path_, e.name)), path_,
                   "expected a " + what + " name " + kNameRule + " as key, got " + quote_name(e.name));
  }

  /// An optional key: empty when absent or given with an empty value.
  std::optional<Value> get(const std::string& key) const {
    const Entry* e = find(key);
    if (e == nullptr || e->value.IsNull()) return std::nullopt;
    return value(*e);
  }

  bool given(const std::string& key) const { return get(key).has_value(); }

  /// A required key (its presence was checked by the constructor or by the caller).
  Value at(const std::string& key) const {
    const Entry* e = find(key);
    if (e == nullptr) missing(key, "");
    return value(*e);
  }

  /// All entries in file order (for maps with free keys).
  std::vector<std::pair<std::string, Value>> items() const {
    std::vector<std::pair<std::string, Value>> out;
    for (const Entry& e : entries_) out.emplace_back(e.name, value(e));
    return out;
  }

  /// An error about the map as a whole. It reads "--set" if the map or one of the `involved`
  /// keys was set by an override.
  [[noreturn]] void fail(const std::string& what, std::initializer_list<const char*> involved = {}) const {
    SourceLoc where = where_;
    for (const char* key : involved)
      if (find(key) != nullptr && ctx_->overridden(child_path(path_, key))) where = {"--set", 0};
    ctx_->fail(where, path_, what);
  }

  [[noreturn]] void missing(const std::string& key, const std::string& what) const {
    fail("missing required key '" + key + "'" + (what.empty() ? "" : " (" + what + ")"));
  }

 private:
  struct Entry {
    std::string name;
    YAML::Mark key_mark;
    YAML::Node value;
  };

  const Entry* find(const std::string& key) const {
    for (const Entry& e : entries_)
      if (e.name == key) return &e;
    return nullptr;
  }

  Value value(const Entry& e) const { return Value(*ctx_, e.value, child_path(path_, e.name), e.key_mark); }

  const Context* ctx_;
  std::string path_;
  SourceLoc where_;
  std::vector<Entry> entries_;
};


}  // namespace peri::scene_detail
