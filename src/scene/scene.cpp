// Scene reading, validation, command-line overrides and emission.
//
// Reading goes in three steps: the YAML text is loaded into a node tree, the --set overrides are
// applied to that tree, and the tree is validated into the Scene structs. Every problem throws
// InputError with one line "<file>:<line>: <dotted.key.path>: <what is wrong>"; a value that came
// from an override reads "--set" instead of "<file>:<line>".
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
#include "peri/scene/scene.hpp"

#include "peri/scene/models.hpp"
#include "peri/scene/describe.hpp"

#include <yaml-cpp/eventhandler.h>
#include "peri/models/marder.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string_view>
#include <utility>

namespace peri {

namespace {

// ------------------------------------------------------------------------------------------------
// Small text helpers

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

std::string join(const std::vector<std::string>& parts, std::string_view sep = ", ") {
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

enum class NumberText { Ok, NotANumber, NotFinite, Subnormal };

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
  if (node.Tag() == "!") return "\"" + node.Scalar() + "\"";
  return node.Scalar();
}

/// Names given in a scene (the scene's, materials', bodies', cracks', boundaries', tools' and
/// stages') become a directory (out/<scene name>), CSV columns, JSON keys and --set path segments.
constexpr const char* kNameRule = "(1 to 64 characters of A-Z a-z 0-9 _ - not starting with -)";

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

/// One allowed key of a map: its name, whether it must be given, and what it is (for the
/// "missing required key" message); and its documentation (scene/describe.hpp): SI unit, default
/// (what an absent key means) and meaning.
struct Key {
  const char* name;
  bool required = false;
  const char* what = "";
  const char* unit = "";
  const char* fallback = "";
  const char* doc = "";
};
using Keys = std::vector<Key>;

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

  /// An integer >= lo (and <= hi). Exactly integral float spellings (1e3) are accepted.
  long integer(long lo, long hi = std::numeric_limits<long>::max()) const {
    const std::string expected = "an integer >= " + std::to_string(lo);
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
    if (v < lo || v > hi) {
      fail("expected " + expected +
           (hi < std::numeric_limits<long>::max() ? " and <= " + std::to_string(hi) : "") + ", got " + got());
    }
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
    std::vector<std::string> names;
    for (const auto& [word, e] : options) {
      if (node_.IsScalar() && !quoted() && node_.Scalar() == word) return e;
      names.emplace_back(word);
    }
    fail("expected one of: " + join(names) + "; got " + got());
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

// ------------------------------------------------------------------------------------------------
// Schema

// Each key: name, required, what (the "missing required key" message), and its documentation for
// --describe-keys and docs/user/scene-reference.md (scene/describe.hpp): unit, default (what an
// absent key means; empty: no value) and meaning. A key added here without a meaning makes
// --describe-keys fail, and one whose documentation differs from the reference page fails the
// ctest scene_reference.

const Keys kSceneKeys = {
    {.name = "name", .required = true, .what = "scene name, 1 to 64 characters of A-Z a-z 0-9 _ - not starting with -",
     .doc = "the scene's name, 1 to 64 characters of A-Z a-z 0-9 _ -, not starting with -; the default output "
            "directory is `out/<name>`"},
    {.name = "description", .fallback = "empty", .doc = "free text"},
    {.name = "materials", .required = true, .what = "map of material name to material",
     .doc = "map of material name to material (`materials.<name>`); at least one"},
    {.name = "bodies", .required = true, .what = "map of body name to body",
     .doc = "map of body name to body (`bodies.<name>`); at least one"},
    {.name = "cracks", .fallback = "none", .doc = "list of straight pre-cracks (`cracks[i]`)"},
    {.name = "boundaries", .fallback = "none",
     .doc = "list of regions with prescribed velocity components, clamps included (`boundaries[i]`)"},
    {.name = "tools", .fallback = "none", .doc = "list of rigid tools acting by contact (`tools[i]`)"},
    {.name = "long_range", .doc = "long-range pair forces between fiber nodes (`long_range`)"},
    {.name = "initial", .fallback = "at rest, undeformed", .doc = "the state before the first stage (`initial`)"},
    {.name = "stages", .required = true, .what = "list of stages, at least one",
     .doc = "list of stages run in order (`stages[i]`); at least one of kind dynamic"},
    {.name = "stability", .fallback = "the defaults below", .doc = "instability detectors of dynamic stages (`stability`)"},
    {.name = "output", .fallback = "the defaults below", .doc = "what is written and how often (`output`)"},
};

const Keys kMaterialKeys = {
    {.name = "model", .required = true, .what = "force law: membrane, pmb, marder, or another registered law",
     .doc = "the material model, one of the values of model listed with this section; it decides which other "
            "keys the material takes"},
    {.name = "density", .required = true, .what = "mass density, kg/m^3", .unit = "kg/m^3",
     .doc = "rho > 0; of the sheet's material for membranes, spheres and lattices (mass per area: rho h)"},
    {.name = "wave_speed", .unit = "m/s", .fallback = "one of four",
     .doc = "stiffness, exactly one of wave_speed, bulk_modulus, youngs_modulus, micromodulus: the small-strain "
            "longitudinal wave speed c_l > 0 (membranes, spheres, solids: mu = rho c_l^2 / 3; fibers: the bar "
            "speed, E = rho c_l^2)"},
    {.name = "bulk_modulus", .unit = "Pa", .fallback = "one of four",
     .doc = "K > 0: the in-plane modulus 2 mu of membranes and spheres, the 3D modulus 5 mu / 3 of solids, read "
            "as the bar modulus E for fibers"},
    {.name = "youngs_modulus", .unit = "Pa", .fallback = "one of four",
     .doc = "E > 0: 8 mu / 3 for membranes and spheres, 5 mu / 2 for solids, E itself for fibers"},
    {.name = "micromodulus", .unit = "J/m^6, N/m^6", .fallback = "one of four",
     .doc = "the micromodulus c > 0 itself (membrane law J/m^6, pmb N/m^6)"},
    {.name = "influence", .fallback = "constant",
     .doc = "g(xi) of eq. (13): `constant` (g = 1) or `conical` (g = 1 - xi/delta)"},
    {.name = "critical_stretch", .fallback = "none: bonds never break",
     .doc = "membrane: the stretch lambda_0 >= 1 + 1e-10 at which a bond breaks (eqs. 11, 22); pmb: the critical "
            "bond strain s_0 >= 1e-10 (a bond breaks at s = lambda - 1 >= s_0; the papers' \"critical stretch\" "
            "0.1, 0.03, 0.3 of examples 7.3-7.6 is this strain)"},
    {.name = "critical_stretch_at_horizon", .fallback = "= critical_stretch",
     .doc = "Lambda_delta of eq. (29): the critical value at xi = delta, critical_stretch being the one at xi = 0, "
            "linear in between; needs critical_stretch; the same limits"},
    {.name = "hardening", .fallback = "none",
     .doc = "power-law hardening of eq. (16), `{coefficient: c', exponent: n}` (`materials.<name>.hardening`); runs "
            "in the portable bond loop"},
    {.name = "mooney_rivlin_a", .unit = "J/kg", .fallback = "required",
     .doc = "a of W/rho = a [J1 + b J2] (Marder eq. 6), > 0"},
    {.name = "mooney_rivlin_b", .fallback = "required",
     .doc = "b; with the body's spacing Delta and the cutoff u_s: b < 2 and -2 Delta/u_s < b < Delta/u_s (the "
            "unstretched lattice is stable)"},
    {.name = "cutoff", .unit = "m", .fallback = "required", .doc = "u_s of Marder eqs. (31), (32), > 0"},
    {.name = "fracture_separation", .unit = "m", .fallback = "required",
     .doc = "u_c of Marder eqs. (31), (32), > Delta + u_s (checked at the body's spacing)"},
    {.name = "breaking", .fallback = "irreversible",
     .doc = "`irreversible`: a bond reaching u_c is cut for good with its three-body terms, and the energy removed "
            "is booked as dissipated; `reversible`: the paper's functional as written (f constant beyond u_c, h "
            "smooth; bonds act again below u_c; pre-cracks stay cut)"},
    {.name = "kelvin_viscosity", .unit = "m^2/s", .fallback = "0 (none)",
     .doc = "kinematic viscosity nu >= 0 of Kelvin dashpots on the intact bonds, force eta (e_ij . (v_j - v_i)) "
            "e_ij with eta = 8 m nu / (3 Delta^2); their work is booked as dissipated energy"},
};

const char* const kMarderKeys[] = {"mooney_rivlin_a", "mooney_rivlin_b", "cutoff", "fracture_separation", "breaking",
                                   "kelvin_viscosity"};

const Keys kHardeningKeys = {
    {.name = "coefficient", .required = true, .what = "hardening coefficient c', >= 0", .unit = "J/m^6",
     .doc = "c' >= 0 of the added energy c' (lambda^n - n lambda + n - 1) g (eq. 16, written so that the "
            "reference state is stress-free)"},
    {.name = "exponent", .required = true, .what = "hardening exponent n, > 1", .doc = "n > 1"},
};

const Keys kBodyKeys = {
    {.name = "kind", .fallback = "membrane",
     .doc = "`membrane` (a flat sheet at z = origin z), `solid` (a box of simple-cubic points; pmb materials), "
            "`lattice` (Marder's triangular lattice; marder materials), `fiber` (nodes along a path, or a "
            "generated network) or `sphere` (a spherical membrane on a geodesic grid); a key of another kind is "
            "refused, naming the kind that takes it"},
    {.name = "material", .required = true, .what = "name of a material",
     .doc = "name of an entry of materials; a lattice body needs a marder material and a marder material a "
            "lattice body"},
    {.name = "origin", .unit = "m", .fallback = "required (membrane, solid, lattice)",
     .doc = "membrane, solid, lattice: the lower corner [x, y, z]"},
    {.name = "size", .unit = "m", .fallback = "required (membrane, solid, lattice)",
     .doc = "membrane, lattice: [Lx, Ly] (or [Lx, Ly, 0]), Lx, Ly > 0; solid: [Lx, Ly, Lz], all > 0"},
    {.name = "thickness", .unit = "m", .fallback = "required (membrane, lattice, sphere)",
     .doc = "h > 0 (a node's measure is its area times h; a lattice node's mass is density h (sqrt(3)/2) "
            "Delta^2); refused for solids"},
    {.name = "spacing", .unit = "m", .fallback = "required",
     .doc = "dx > 0, at most the smallest extent of size (fiber: the path's length; sphere: the radius). Grid "
            "nodes sit at origin + (i + 1/2) dx; a lattice's Delta; a fiber's nodes are round(L / spacing) equal "
            "arc steps apart; a sphere's geodesic grid has about this spacing"},
    {.name = "grid", .fallback = "square",
     .doc = "membrane: `square` or `hexagonal` (rows along x, dx apart, rows sqrt(3)/2 dx apart); solid: `square` "
            "only"},
    {.name = "horizon_factor", .fallback = "3",
     .doc = "m of delta = m dx, >= 1; not with horizon; not for lattices"},
    {.name = "horizon", .unit = "m", .fallback = "horizon_factor x spacing",
     .doc = "delta itself, >= spacing; not with horizon_factor; not for lattices"},
    {.name = "quadrature", .fallback = "partial_area",
     .doc = "membrane, solid: the weight of a neighbour inside the horizon: `partial_area` (the exact part of its "
            "cell inside the horizon; second order), `full` (whole cells with xi <= delta) or `taper` (whole "
            "cells, the last dx/2 before delta tapered linearly to 1/2, as LAMMPS PERI does); fibers and spheres "
            "take full weights"},
    {.name = "breakable", .unit = "m", .fallback = "everywhere",
     .doc = "lattice: `{min: [x, y, z], max: [x, y, z]}`, only bonds with both ends inside this box (reference "
            "positions) may break (`bodies.<name>.breakable`)"},
    {.name = "path", .unit = "m", .fallback = "required (fiber) unless network",
     .doc = "fiber: a polyline [[x, y, z], ...] of at least 2 points, each different from the one before; n = "
            "round(L / spacing) nodes at the centres of n equal arc-length steps ds = L / n, measure A ds"},
    {.name = "network",
     .doc = "fiber, instead of path: many fibers generated in a box, bonded wherever they pass within the horizon "
            "(cross-links) (`bodies.<name>.network`)"},
    {.name = "diameter", .unit = "m", .fallback = "required (fiber)", .doc = "fiber: d > 0; cross-section A = pi d^2 / 4"},
    {.name = "segment_length", .unit = "m", .fallback = "0 (one segment)",
     .doc = "fiber: >= 0; node k lies in segment floor((k + 1/2) ds / segment_length), which long_range rules tell "
            "apart"},
    {.name = "center", .unit = "m", .fallback = "required (sphere)", .doc = "sphere: the centre [x, y, z]"},
    {.name = "radius", .unit = "m", .fallback = "required (sphere)",
     .doc = "sphere: R > 0; n = round(1.107 R / spacing) splits each icosahedron face into n^2 triangles, 10 n^2 + "
            "2 nodes; a node's area is a third of its triangles', scaled to 4 pi R^2 in all"},
    {.name = "pressure", .unit = "Pa", .fallback = "0",
     .doc = "sphere: internal pressure p >= 0, a follower load (each geodesic triangle carries p times its current "
            "area vector, a third to each corner whose bonds to the other two are intact); its work is external "
            "work; wall stress p R / (2 h) at most 100 in-plane bulk moduli; refuses quasistatic stages"},
    {.name = "pressure_ramp_time", .unit = "s", .fallback = "0",
     .doc = "sphere: the pressure rises linearly from 0 over this time, >= 0"},
};

const Keys kNetworkKeys = {
    {.name = "box", .required = true, .what = "box {min: [x, y, z], max: [x, y, z]} the fibers fill, m",
     .doc = "the box the fibers cross, `{min: [x, y, z], max: [x, y, z]}` (`bodies.<name>.network.box`)"},
    {.name = "families", .required = true, .what = "list of fiber families {direction: x or y, count}",
     .doc = "non-empty list of fiber families (`bodies.<name>.network.families[i]`)"},
    {.name = "deviation", .unit = "rad", .fallback = "0.15",
     .doc = "standard deviation >= 0 of the Gaussian angles (in the plane and out of it) between a step's "
            "direction and its family's; steps are mirrored back at the box's side faces"},
    {.name = "step", .required = true, .what = "path length between direction draws, m", .unit = "m",
     .doc = "path length between direction draws, > 0; at most 1e6 steps across the box along each family's "
            "direction"},
    {.name = "start_band", .unit = "m", .fallback = "5% of the box's smaller x, y extent",
     .doc = ">= 0: each fiber starts at a uniformly random point within this distance of the box's low face normal "
            "to its family's direction, anywhere across the other two, and walks to the far face"},
    {.name = "seed", .fallback = "1",
     .doc = "integer >= 0; the same seed gives the same paths on every rank (splitmix64 and Box-Muller; on another "
            "platform up to its libm's log and cos)"},
};

const Keys kFamilyKeys = {
    {.name = "direction", .required = true, .what = "x or y", .doc = "`x` or `y`: the direction the family's fibers cross the box"},
    {.name = "count", .required = true, .what = "number of fibers, >= 1", .doc = "number of fibers, an integer in 1 .. 100000"},
};

const Keys kLongRangeKeys = {
    {.name = "length", .required = true, .what = "a of w2 = alpha (a/y)^12 - beta (a/y)^6, m", .unit = "m",
     .doc = "a > 0 of w2(y) = alpha (a/y)^12 - beta (a/y)^6 (eqs. 32-36) on the current distance y"},
    {.name = "cutoff", .required = true, .what = "largest interacting distance, m", .unit = "m",
     .doc = "largest current distance of an interacting pair, > 0; the energy booked is w2(y) - w2(cutoff); "
            "refused at setup when it takes in more than 5000 pairs per node or 2e8 in all at the reference "
            "positions"},
    {.name = "exclusion", .unit = "m", .fallback = "the largest fiber horizon",
     .doc = ">= 0: pairs closer than this in the reference configuration (neighbours in one continuous body) do "
            "not interact"},
    {.name = "pairs", .required = true, .what = "list of pair rules {between, alpha, beta}",
     .doc = "non-empty list of rules (`long_range.pairs[i]`); the first rule of a pair's kind applies, nodes of one "
            "segment never interact, a pair no rule names does not interact"},
};

const Keys kPairRuleKeys = {
    {.name = "between", .required = true, .what = "adjacent_segments, distant_segments or other_fibers",
     .doc = "`adjacent_segments` (one fiber, segments k and k +- 1), `distant_segments` (one fiber, segments two or "
            "more apart) or `other_fibers` (different fiber bodies, or different fibers of one network)"},
    {.name = "alpha", .required = true, .what = "coefficient of (a/y)^12, J/m^6", .unit = "J/m^6",
     .doc = "coefficient of (a/y)^12, >= 0"},
    {.name = "beta", .required = true, .what = "coefficient of (a/y)^6, J/m^6 (negative: repulsive tail)",
     .unit = "J/m^6", .doc = "coefficient of (a/y)^6, any sign (negative: a repulsive 1/y^6 tail)"},
};

const Keys kBoxKeys = {
    {.name = "min", .required = true, .what = "lower corner [x, y, z], m", .unit = "m", .doc = "lower corner [x, y, z]"},
    {.name = "max", .required = true, .what = "upper corner [x, y, z], m", .unit = "m",
     .doc = "upper corner [x, y, z], >= min in every component (> min for a network's box)"},
};

const Keys kCrackKeys = {
    {.name = "name", .fallback = "crack<i>", .doc = "the crack's name, which release stages use"},
    {.name = "from", .required = true, .what = "start point [x, y, z], m", .unit = "m", .doc = "one end [x, y, z]"},
    {.name = "to", .required = true, .what = "end point [x, y, z], m", .unit = "m",
     .doc = "the other end [x, y, z], different from from. At the start every bond of a membrane, lattice, fiber "
            "or sphere whose reference segment meets the slit in the xy plane is broken (solids are not cut), "
            "unless a release stage names the crack"},
};

const Keys kBoundaryKeys = {
    {.name = "name", .required = true, .what = "boundary name, unique", .doc = "unique; stages name boundaries by it"},
    {.name = "region", .required = true, .what = "box {min: [x, y, z], max: [x, y, z]}",
     .doc = "the nodes it holds (`boundaries[i].region`); a node in several regions follows the last boundary "
            "listed"},
    {.name = "velocity", .unit = "m/s", .fallback = "[0, 0, 0] (a clamp)",
     .doc = "prescribed velocity [vx, vy, vz] of the selected components"},
    {.name = "components", .fallback = "[x, y, z]",
     .doc = "non-empty list of distinct letters from x, y, z: the components prescribed; the others move freely"},
    {.name = "ramp_time", .unit = "s", .fallback = "0", .doc = "the velocity rises linearly from 0 over this time, >= 0"},
};

const Keys kToolKeys = {
    {.name = "name", .required = true, .what = "tool name, unique", .doc = "unique; names the tool's columns in series.csv"},
    {.name = "kind", .required = true, .what = "tool kind: cylinder or sphere",
     .doc = "`cylinder` (a rigid cylinder of infinite length, axis along z) or `sphere` (a rigid sphere); tools act "
            "on every node by a penalty force with Coulomb friction, in dynamic stages (a scene with tools refuses "
            "quasistatic stages), and must start clear of the bodies"},
    {.name = "radius", .required = true, .what = "cylinder radius, m", .unit = "m", .doc = "> 0"},
    {.name = "center", .required = true, .what = "axis position [x, y] at t = 0, m", .unit = "m",
     .doc = "cylinder: axis position [x, y] at t = 0; sphere: centre [x, y, z] at t = 0"},
    {.name = "velocity", .unit = "m/s", .fallback = "at rest",
     .doc = "constant velocity: cylinder [vx, vy], sphere [vx, vy, vz]"},
    {.name = "friction", .fallback = "0",
     .doc = "Coulomb coefficient mu >= 0; friction opposes sliding over the tool's surface, along a cylinder's "
            "axis too"},
    {.name = "stiffness", .fallback = "0.5",
     .doc = "penalty stiffness relative to the stiffest node's bond stiffness, in (0, 1e6]; the stable step of a "
            "scene with tools is divided by sqrt(1 + largest stiffness)"},
};

const Keys kRegionKeys = {
    {.name = "min", .required = true, .what = "lower corner [x, y, z], m", .unit = "m", .doc = "lower corner [x, y, z]"},
    {.name = "max", .required = true, .what = "upper corner [x, y, z], m", .unit = "m",
     .doc = "upper corner [x, y, z], >= min in every component; the region holds the nodes whose reference "
            "position lies in the closed box, at least one"},
    {.name = "body", .fallback = "every body", .doc = "name of a body: only its nodes"},
};

const Keys kInitialKeys = {
    {.name = "displacement_gradient", .fallback = "zeros",
     .doc = "3 x 3 matrix G, rows as lists: u = G (X - center) (`[[0, 0, 0], [0, 0.08, 0], [0, 0, 0]]` stretches y "
            "by 8%); may move a node by at most 100 times its body's extent"},
    {.name = "velocity_gradient", .unit = "1/s", .fallback = "zeros", .doc = "3 x 3 matrix L: v = L (X - center)"},
    {.name = "center", .unit = "m", .fallback = "[0, 0, 0]", .doc = "the fixed point of both fields"},
    {.name = "seed", .fallback = "none",
     .doc = "an out-of-plane seed `{amplitude, wavelength}` (`initial.seed`)"},
};

const Keys kSeedKeys = {
    {.name = "amplitude", .required = true, .what = "seed amplitude, m", .unit = "m",
     .doc = "A >= 0 of u_z += A sin(2 pi x / Lx) sin(2 pi y / Ly) at the reference position (x, y)"},
    {.name = "wavelength", .unit = "m", .fallback = "[0, 0]",
     .doc = "[Lx, Ly], each >= 0; a wavelength of 0 drops its factor"},
};

const Keys kStageKeys = {
    {.name = "name", .fallback = "stage<i>", .doc = "the stage's name"},
    {.name = "kind", .fallback = "dynamic",
     .doc = "`dynamic` (explicit velocity Verlet), `quasistatic` (static equilibrium by PETSc SNES; no time passes) "
            "or `release` (break the bonds crossing named cracks; no time passes); a key of another kind is "
            "refused"},
    {.name = "duration", .unit = "s", .fallback = "required unless steps",
     .doc = "simulated time > 0, covered exactly by n = ceil(duration / dt) steps of duration / n"},
    {.name = "steps", .fallback = "none",
     .doc = "instead of duration: the number of steps, an integer in 1 .. 1e9, each of dt (through --set one "
            "replaces the other given in the file)"},
    {.name = "dt", .unit = "s", .fallback = "safety_factor x the stable bound",
     .doc = "time step > 0; refused above the stable bound (the message gives it) unless allow_unstable_dt; "
            "duration / dt at most 1e9"},
    {.name = "safety_factor", .fallback = "0.7", .doc = "in (0, 1]: dt = safety_factor x the stable bound"},
    {.name = "allow_unstable_dt", .fallback = "false",
     .doc = "run a dt above the stable bound anyway (the stability detectors still watch)"},
    {.name = "damping", .unit = "1/s", .fallback = "0",
     .doc = "mass-proportional viscous damping alpha >= 0 (force density -rho alpha v), alpha dt / 2 <= 1; its "
            "work is booked as dissipated energy"},
    {.name = "boundary_velocity", .unit = "m/s", .fallback = "the boundaries' own",
     .doc = "`{boundary: [vx, vy, vz], ...}`: a constant velocity of named boundaries during the stage, replacing "
            "their velocity and ramp_time"},
    {.name = "displacements", .unit = "m", .fallback = "none",
     .doc = "`{boundary: [dx, dy, dz], ...}`: displacement of named boundaries (their prescribed components) "
            "reached at the stage's end, added to where they are at its start; unnamed boundaries stay put"},
    {.name = "displacement_gradient", .fallback = "zeros",
     .doc = "3 x 3 matrix H: prescribed components also move by H (X - initial.center) over the stage "
            "(homogeneous loading of boundary bands)"},
    {.name = "load_steps", .fallback = "10",
     .doc = "initial number of load increments, an integer in 1 .. 1e6; a diverged increment is halved, one of at "
            "most 4 Newton iterations grows 1.5 x"},
    {.name = "max_load_steps", .fallback = "1000",
     .doc = "increments, cut-backs included, before the stage fails (exit status 3); an integer in 1 .. 1e8, at "
            "least load_steps"},
    {.name = "in_plane", .fallback = "true",
     .doc = "hold membranes' out-of-plane components where they are (a flat membrane has no out-of-plane "
            "stiffness at zero tension)"},
    {.name = "jacobian", .fallback = "assembled",
     .doc = "`assembled` (the bond tangent, block size 3) or `matrix_free` (finite-difference Newton-Krylov, no "
            "preconditioner)"},
    {.name = "jacobian_shift", .fallback = "1e-8",
     .doc = "in [0, 1): shift of the tangent's diagonal relative to the mean nodal stiffness; the residual is "
            "unchanged, so converged states are exact equilibria"},
    {.name = "max_break_passes", .fallback = "100",
     .doc = "re-equilibrations of one increment while bonds keep breaking, an integer in 1 .. 1e6"},
    {.name = "cracks", .fallback = "required",
     .doc = "non-empty list of names of cracks entries, each released by one stage only; they are not broken at "
            "the start: this stage breaks every intact bond crossing them in the current state and books each "
            "bond's energy as dissipated"},
};

const char* to_text(StageKind k);

/// Stage keys that only one kind of stage accepts.
const std::map<std::string, StageKind> kStageKeyKind = {
    {"duration", StageKind::Dynamic},         {"steps", StageKind::Dynamic},
    {"dt", StageKind::Dynamic},               {"safety_factor", StageKind::Dynamic},
    {"allow_unstable_dt", StageKind::Dynamic}, {"damping", StageKind::Dynamic},
    {"boundary_velocity", StageKind::Dynamic}, {"displacements", StageKind::QuasiStatic},
    {"displacement_gradient", StageKind::QuasiStatic},
    {"load_steps", StageKind::QuasiStatic},   {"max_load_steps", StageKind::QuasiStatic},
    {"in_plane", StageKind::QuasiStatic},     {"jacobian", StageKind::QuasiStatic},
    {"jacobian_shift", StageKind::QuasiStatic}, {"max_break_passes", StageKind::QuasiStatic},
    {"cracks", StageKind::Release},
};

const Keys kStabilityKeys = {
    {.name = "energy_error", .fallback = "0.05",
     .doc = ">= 0: stop a dynamic stage when the energy balance error |E - E0| exceeds this fraction of the run's "
            "largest energy term (at least the energy of a 1e-10 strain of every body); 0: off"},
    {.name = "motion_per_step", .fallback = "1",
     .doc = ">= 0: stop when a node with intact bonds moves more than this many grid spacings in one step; 0: off"},
};

const Keys kOutputKeys = {
    {.name = "frames", .fallback = "20",
     .doc = "HDF5 frames over the whole run, first and last step included; an integer >= 1 (more than the steps + "
            "1 writes every step, with a warning)"},
    {.name = "series_every", .unit = "steps", .fallback = "10",
     .doc = "a series.csv row (and a crack-tip sample) every N steps, an integer >= 1"},
    {.name = "velocity", .fallback = "true", .doc = "write the velocity field into the frames"},
    {.name = "progress_seconds", .unit = "s", .fallback = "2",
     .doc = "wall time between progress lines, >= 0 (0: at every check)"},
    {.name = "checkpoint_every_steps", .unit = "steps", .fallback = "0 (off)",
     .doc = "write checkpoint.h5 every N steps, an integer >= 0"},
    {.name = "checkpoint_every_seconds", .unit = "s", .fallback = "900",
     .doc = "write checkpoint.h5 when this much wall time has passed since the last one (rank 0's clock, checked "
            "every 20 steps), >= 0; 0: off"},
};

const char* const kStiffnessKeys[] = {"wave_speed", "bulk_modulus", "youngs_modulus", "micromodulus"};

/// Prefix of the default names of a list's unnamed entries ("crack0", "stage1"); empty when the
/// entries have no default name.
std::string default_name_prefix(const std::string& list_path) {
  if (list_path == "cracks") return "crack";
  if (list_path == "stages") return "stage";
  return "";
}

// ------------------------------------------------------------------------------------------------
// Reading the sections

/// Keeps the names of a list's entries unique.
class UniqueNames {
 public:
  explicit UniqueNames(std::string what) : what_(std::move(what)) {}
  const std::string& what() const { return what_; }

  /// `name_value`: the entry's name key if given (the error is reported there), else the entry.
  void add(const std::string& name, const std::optional<Value>& name_value, const Map& entry) {
    const auto it = first_.find(name);
    if (it == first_.end()) {
      first_.emplace(name, entry.path());
      return;
    }
    const std::string msg = "duplicate " + what_ + " name '" + name + "' (also used by " + it->second + ")";
    if (name_value) name_value->fail(msg);
    entry.fail(msg + "; give this entry a name");
  }

 private:
  std::string what_;
  std::map<std::string, std::string> first_;
};

/// Name of a list entry: its `name` key, or "<prefix><index>" when the entry has none (an empty
/// prefix: the name is required).
std::string entry_name(const Map& m, const std::string& prefix, std::size_t index, UniqueNames& names) {
  const std::optional<Value> v = prefix.empty() ? std::optional<Value>(m.at("name")) : m.get("name");
  const std::string name = v ? v->given_name(names.what()) : prefix + std::to_string(index);
  names.add(name, v, m);
  return name;
}

/// Entries of an optional list section (absent or empty value: no entries).
std::vector<Value> optional_list(const Map& top, const std::string& key, const std::string& expected) {
  const std::optional<Value> v = top.get(key);
  return v ? v->list(expected) : std::vector<Value>{};
}

// A critical value (critical_stretch, critical_stretch_at_horizon), as the model checks it.
double critical_value(const Value& v, const MaterialModel& model) {
  const double x = v.number("a number");
  if (model.critical_problem)
    if (const std::string problem = model.critical_problem(x); !problem.empty()) v.fail(problem + ", got " + v.got());
  return x;
}

/// The marder model's keys: its four constants (no peridynamic stiffness, influence, failure
/// stretch or hardening), and the breaking mode.
Material read_marder_material(const Map& m, Material mat) {
  for (const char* key : {"wave_speed", "bulk_modulus", "youngs_modulus", "micromodulus", "influence",
                          "critical_stretch", "critical_stretch_at_horizon", "hardening"})
    if (auto x = m.get(key))
      x->fail("not used by the marder model (its stiffness is mooney_rivlin_a, mooney_rivlin_b; its failure "
              "fracture_separation)");
  for (const char* key : {"mooney_rivlin_a", "mooney_rivlin_b", "cutoff", "fracture_separation"})
    if (!m.given(key)) m.missing(key, "required by the marder model");
  MarderParams p;
  p.a = m.at("mooney_rivlin_a").positive("J/kg");
  p.b = m.at("mooney_rivlin_b").number("a number");
  p.cutoff = m.at("cutoff").positive("m");
  p.fracture_separation = m.at("fracture_separation").positive("m");
  if (auto x = m.get("breaking"))
    p.reversible = x->choice<bool>({{"irreversible", false}, {"reversible", true}});
  if (auto x = m.get("kelvin_viscosity")) p.kelvin_viscosity = x->non_negative("m^2/s");
  mat.marder = p;
  return mat;
}

Material read_material(const std::string& name, const Value& v) {
  const Map m(v, &kMaterialKeys, "a map describing the material");
  Material mat;
  mat.name = name;
  mat.where = m.where();
  const Value model = m.at("model");
  const std::optional<std::string> word = model.word();
  const MaterialModel* info = word ? find_material_model(*word) : nullptr;
  if (!info) model.fail("expected one of: " + join(material_model_names()) + "; got " + model.got());
  mat.model = info->name;
  mat.density = m.at("density").positive("kg/m^3");
  if (info->lattice) return read_marder_material(m, std::move(mat));
  for (const char* key : kMarderKeys)
    if (auto x = m.get(key)) x->fail("only the marder model takes this key (model is " + mat.model + ")");
  for (const char* key : {"influence", "critical_stretch", "critical_stretch_at_horizon", "hardening"})
    if (auto x = m.get(key); x && std::find(info->keys.begin(), info->keys.end(), key) == info->keys.end()) {
      std::vector<std::string> takers;
      for (const std::string& name : material_model_names())
        if (const MaterialModel* other = find_material_model(name);
            std::find(other->keys.begin(), other->keys.end(), key) != other->keys.end())
          takers.push_back(name);
      x->fail(std::string(key) + " is available only for the " + join(takers) + " model" +
              (takers.size() > 1 ? "s" : "") + ", not for " + mat.model);
    }

  int stiffness_given = 0;
  for (const char* key : kStiffnessKeys) stiffness_given += m.given(key) ? 1 : 0;
  if (stiffness_given != 1) {
    m.fail("give exactly one of " +
               join({kStiffnessKeys[0], kStiffnessKeys[1], kStiffnessKeys[2], kStiffnessKeys[3]}) +
               " (found " + std::to_string(stiffness_given) + ")",
           {kStiffnessKeys[0], kStiffnessKeys[1], kStiffnessKeys[2], kStiffnessKeys[3]});
  }
  for (const char* key : kStiffnessKeys)
    if (auto x = m.get(key); x && std::find(info->stiffness.begin(), info->stiffness.end(), key) == info->stiffness.end())
      x->fail("the " + mat.model + " model calibrates from " + join(info->stiffness) + ", not from " + key);
  if (auto x = m.get("wave_speed")) mat.wave_speed = x->positive("m/s");
  if (auto x = m.get("bulk_modulus")) mat.bulk_modulus = x->positive("Pa");
  if (auto x = m.get("youngs_modulus")) mat.youngs_modulus = x->positive("Pa");
  if (auto x = m.get("micromodulus")) mat.micromodulus = x->positive("");

  if (auto x = m.get("influence"))
    mat.influence =
        x->choice<Influence>({{"constant", Influence::Constant}, {"conical", Influence::Conical}});
  if (auto x = m.get("critical_stretch")) mat.critical_stretch = critical_value(*x, *info);
  if (auto x = m.get("critical_stretch_at_horizon")) {
    if (!mat.critical_stretch) x->fail("requires critical_stretch (the critical value at |xi| = 0)");
    mat.critical_stretch_at_horizon = critical_value(*x, *info);
  }
  if (auto x = m.get("hardening")) {
    const Map h(*x, &kHardeningKeys, "a map {coefficient: c, exponent: n}");
    Hardening hard;
    hard.coefficient = h.at("coefficient").non_negative("");
    hard.exponent = h.at("exponent").number_if("a number > 1", [](double n) { return n > 1; });
    mat.hardening = hard;
  }
  return mat;
}

// Horizon keys shared by peridynamic bodies: horizon_factor (m spacings) or horizon [m].
void read_horizon(const Map& m, Body& b) {
  if (auto x = m.get("horizon_factor")) {
    b.horizon_factor = x->number("a number >= 1");
    if (!(b.horizon_factor >= 1))
      x->fail("horizon must be at least one spacing (expected >= 1), got " + x->got());
  }
  if (auto x = m.get("horizon")) {
    if (m.given("horizon_factor")) x->fail("give either horizon [m] or horizon_factor, not both");
    const double h = x->number("a number [m]");
    if (!(h >= b.spacing))
      x->fail("horizon must be at least one spacing (expected >= " + format_number(b.spacing) + " m), got " +
              x->got());
    b.horizon = h;
  }
}

FiberNetwork read_network(const Value& v) {
  const Map m(v, &kNetworkKeys, "a map {box, families, deviation, step, start_band, seed}");
  FiberNetwork n;
  n.where = m.where();
  const Map box(m.at("box"), &kBoxKeys, "a box {min: [x, y, z], max: [x, y, z]}");
  n.min = box.at("min").vec3("m");
  const Value max = box.at("max");
  n.max = max.vec3("m");
  for (int d = 0; d < 3; ++d)
    if (!(n.min[d] < n.max[d]))
      max.fail(std::string("expected min < max in every component, got ") + "xyz"[d] + ": min " +
               format_number(n.min[d]) + ", max " + format_number(n.max[d]));
  const Value families = m.at("families");
  const std::vector<Value> list = families.list("a list of fiber families {direction: x or y, count}");
  if (list.empty()) families.fail("expected at least one family {direction: x or y, count}, got an empty list");
  for (const Value& f : list) {
    const Map fm(f, &kFamilyKeys, "a map {direction: x or y, count}");
    FiberFamily fam;
    fam.where = fm.where();
    fam.axis = fm.at("direction").choice<int>({{"x", 0}, {"y", 1}});
    fam.count = fm.at("count").integer(1, 100000);
    n.families.push_back(fam);
  }
  if (auto x = m.get("deviation")) n.deviation = x->non_negative("rad");
  const Value step = m.at("step");
  n.step = step.positive("m");
  for (const FiberFamily& f : n.families)
    if ((n.max[f.axis] - n.min[f.axis]) / n.step > 1e6)
      step.fail("a fiber would take more than 1e6 steps of " + step.got() + " m to cross the box (" +
                format_number(n.max[f.axis] - n.min[f.axis]) + " m along " + (f.axis == 0 ? "x" : "y") +
                "); expected a step of at least 1e-6 of the box's extent");
  n.start_band = 0.05 * std::min(n.max[0] - n.min[0], n.max[1] - n.min[1]);
  if (auto x = m.get("start_band")) n.start_band = x->non_negative("m");
  if (auto x = m.get("seed")) n.seed = x->integer(0);
  return n;
}

// A fiber: polyline path, diameter, spacing along the path, horizon, segments (eq. 31).
void read_fiber(const Map& m, Body& b) {
  for (const char* key : {"origin", "size", "thickness", "grid", "quadrature", "breakable"})
    if (auto x = m.get(key))
      x->fail(std::string("not used by a fiber body (nodes along its path, full weights within the horizon)"));
  double length = INFINITY;  // of the one path (a network's fibers cross its box)
  if (auto x = m.get("network")) {
    if (m.given("path")) x->fail("give either path (one fiber) or network (many), not both");
    b.network = read_network(*x);
  } else {
    if (!m.given("path")) m.missing("path", "polyline [[x, y, z], ...] of at least 2 points, m (or network)");
    const Value path = m.at("path");
    const std::vector<Value> points = path.list("a list of at least 2 points [x, y, z], m");
    if (points.size() < 2) path.fail("expected a list of at least 2 points [x, y, z], m, got " + path.got());
    length = 0;
    for (std::size_t k = 0; k < points.size(); ++k) {
      b.path.push_back(points[k].vec3("m"));
      if (k == 0) continue;
      double d2 = 0;
      for (int c = 0; c < 3; ++c) d2 += std::pow(b.path[k][c] - b.path[k - 1][c], 2);
      if (!(d2 > 0)) points[k].fail("expected a point different from the one before it, got " + points[k].got());
      length += std::sqrt(d2);
    }
  }
  if (!m.given("diameter")) m.missing("diameter", "fiber diameter, m");
  b.diameter = m.at("diameter").positive("m");
  if (!m.given("spacing")) m.missing("spacing", "node spacing along the path, m");
  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  if (b.spacing > length)
    spacing.fail("spacing must not exceed the fiber's length along its path (" + format_number(length) +
                 " m), got " + spacing.got());
  if (auto x = m.get("segment_length")) b.segment_length = x->non_negative("m");
  read_horizon(m, b);
  b.quadrature = Quadrature::Full;
}

// A spherical membrane: center, radius, thickness, spacing, horizon, internal pressure (7.2).
void read_sphere(const Map& m, Body& b) {
  for (const char* key : {"origin", "size", "grid", "quadrature", "breakable", "path", "network", "diameter",
                          "segment_length"})
    if (auto x = m.get(key))
      x->fail("not used by a sphere body (geodesic nodes on the sphere, full weights within the horizon)");
  if (!m.given("center")) m.missing("center", "center of the sphere [x, y, z], m");
  b.origin = m.at("center").vec3("m");
  if (!m.given("radius")) m.missing("radius", "radius of the sphere, m");
  b.radius = m.at("radius").positive("m");
  if (!m.given("thickness")) m.missing("thickness", "membrane thickness, m");
  b.thickness = m.at("thickness").positive("m");
  if (!m.given("spacing")) m.missing("spacing", "node spacing on the sphere, m");
  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  if (b.spacing > b.radius)
    spacing.fail("spacing must not exceed the radius (" + format_number(b.radius) + " m), got " + spacing.got());
  read_horizon(m, b);
  if (auto x = m.get("pressure")) b.pressure = x->non_negative("Pa");
  if (auto x = m.get("pressure_ramp_time")) b.pressure_ramp_time = x->non_negative("s");
  b.quadrature = Quadrature::Full;
}

Body read_body(const std::string& name, const Value& v, const std::vector<Material>& materials) {
  const Map m(v, &kBodyKeys, "a map describing the body");
  Body b;
  b.name = name;
  b.where = m.where();
  if (auto x = m.get("kind"))
    b.kind = x->choice<BodyKind>({{"membrane", BodyKind::Membrane},
                                  {"solid", BodyKind::Solid},
                                  {"lattice", BodyKind::Lattice},
                                  {"fiber", BodyKind::Fiber},
                                  {"sphere", BodyKind::Shell}});
  const bool membrane = b.kind != BodyKind::Solid;  // membranes and lattices are flat sheets

  const Value material = m.at("material");
  b.material = material.name();
  if (std::none_of(materials.begin(), materials.end(),
                   [&](const Material& mat) { return mat.name == b.material; })) {
    std::vector<std::string> defined;
    for (const Material& mat : materials) defined.push_back(mat.name);
    material.fail("no material named '" + b.material + "'; defined: " + join(defined));
  }
  const Material& mat = *std::find_if(materials.begin(), materials.end(),
                                      [&](const Material& x) { return x.name == b.material; });
  if ((b.kind == BodyKind::Lattice) != find_material_model(mat.model)->lattice)
    material.fail(b.kind == BodyKind::Lattice
                      ? "a lattice body needs a material with model: marder, got '" + b.material + "'"
                      : "material '" + b.material + "' has model: marder, which needs a body with kind: lattice");

  for (const char* key : {"center", "radius", "pressure", "pressure_ramp_time"})
    if (b.kind != BodyKind::Shell && m.given(key))
      m.get(key)->fail("only a sphere body (kind: sphere) takes " + std::string(key));
  if (b.kind == BodyKind::Fiber) {
    read_fiber(m, b);
    return b;
  }
  if (b.kind == BodyKind::Shell) {
    read_sphere(m, b);
    return b;
  }
  for (const char* key : {"path", "network", "diameter", "segment_length"})
    if (auto x = m.get(key)) x->fail("only a fiber body (kind: fiber) takes " + std::string(key));
  if (!m.given("origin")) m.missing("origin", "lower corner [x, y, z], m");
  if (!m.given("size")) m.missing("size", "extent [Lx, Ly] of a membrane or [Lx, Ly, Lz] of a solid, m");
  if (!m.given("spacing")) m.missing("spacing", "grid spacing, m");
  b.origin = m.at("origin").vec3("m");

  const Value size = m.at("size");
  if (membrane) {
    const std::string expected = "a membrane size [Lx, Ly] (or [Lx, Ly, 0]) with Lx, Ly > 0 [m]";
    const auto xs = size.numbers(2, 3, expected, "m");
    if (!(xs[0] > 0 && xs[1] > 0) || (xs.size() == 3 && xs[2] != 0))
      size.fail("expected " + expected + ", got [" + join({format_number(xs[0]), format_number(xs[1])}) +
                (xs.size() == 3 ? ", " + format_number(xs[2]) : "") + "]");
    b.size = {xs[0], xs[1], 0.0};
  } else {
    const std::string expected = "a solid size [Lx, Ly, Lz] with all entries > 0 [m]";
    const auto xs = size.numbers(3, 3, expected, "m");
    if (!(xs[0] > 0 && xs[1] > 0 && xs[2] > 0))
      size.fail("expected " + expected + ", got [" +
                join({format_number(xs[0]), format_number(xs[1]), format_number(xs[2])}) + "]");
    b.size = {xs[0], xs[1], xs[2]};
  }

  if (membrane) {
    if (!m.given("thickness")) m.missing("thickness", "membrane thickness, m");
    b.thickness = m.at("thickness").positive("m");
  } else if (auto x = m.get("thickness")) {
    x->fail("not allowed for a solid body (only membranes have a thickness)");
  }

  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  double smallest = std::numeric_limits<double>::infinity();
  for (double l : b.size)
    if (l > 0) smallest = std::min(smallest, l);
  if (b.spacing > smallest)
    spacing.fail("spacing must not exceed the smallest extent of size (" + format_number(smallest) +
                 " m), got " + spacing.got());

  if (b.kind == BodyKind::Lattice) {
    // Nearest neighbours of a triangular lattice: no grid, horizon or quadrature to choose.
    for (const char* key : {"grid", "horizon_factor", "horizon", "quadrature"})
      if (auto x = m.get(key)) x->fail("not used by a lattice body (triangular lattice, six nearest neighbours)");
    const MarderParams& p = *mat.marder;
    const std::string why = marder_parameter_problem(p.a, p.b, b.spacing, p.cutoff, p.fracture_separation);
    if (!why.empty())
      spacing.fail("lattice spacing " + spacing.got() + " m with material '" + b.material + "' (a = " +
                   format_number(p.a) + ", b = " + format_number(p.b) + ", cutoff = " + format_number(p.cutoff) +
                   ", fracture_separation = " + format_number(p.fracture_separation) + "): " + why);
    b.grid = Grid::Hexagonal;
    b.quadrature = Quadrature::Full;
    if (auto x = m.get("breakable")) {
      const Map box(*x, &kBoxKeys, "a box {min: [x, y, z], max: [x, y, z]}");
      const Vec3 lo = box.at("min").vec3("m");
      const Value max = box.at("max");
      const Vec3 hi = max.vec3("m");
      for (int d = 0; d < 3; ++d)
        if (lo[d] > hi[d])
          max.fail(std::string("expected min <= max in every component, got ") + "xyz"[d] + ": min " +
                   format_number(lo[d]) + " > max " + format_number(hi[d]));
      b.breakable = std::array<Vec3, 2>{lo, hi};
    }
  } else if (auto x = m.get("breakable")) {
    x->fail("only a lattice body takes breakable (peridynamic bonds break by their material's critical_stretch)");
  }

  if (auto x = m.get("grid")) {
    b.grid = x->choice<Grid>({{"square", Grid::Square}, {"hexagonal", Grid::Hexagonal}});
    if (!membrane && b.grid != Grid::Square)
      x->fail("a solid body supports only grid square, got " + x->got());
  }

  read_horizon(m, b);

  if (auto x = m.get("quadrature"))
    b.quadrature =
        x->choice<Quadrature>({{"full", Quadrature::Full}, {"partial_area", Quadrature::PartialArea},
                               {"taper", Quadrature::Taper}});
  return b;
}

Crack read_crack(const Value& v, std::size_t index, UniqueNames& names) {
  const Map m(v, &kCrackKeys, "a map {name, from: [x, y, z], to: [x, y, z]}");
  Crack c;
  c.name = entry_name(m, "crack", index, names);
  c.where = m.where();
  c.from = m.at("from").vec3("m");
  const Value to = m.at("to");
  c.to = to.vec3("m");
  if (c.to == c.from) to.fail("a crack needs two different end points, got to == from");
  return c;
}

Region read_region(const Value& v, const std::vector<Body>& bodies) {
  const Map m(v, &kRegionKeys, "a box {min: [x, y, z], max: [x, y, z]}");
  Region r;
  r.where = m.where();
  r.min = m.at("min").vec3("m");
  const Value max = m.at("max");
  r.max = max.vec3("m");
  for (int d = 0; d < 3; ++d) {
    if (r.min[d] > r.max[d]) {
      max.fail(std::string("expected min <= max in every component, got ") + "xyz"[d] + ": min " +
               format_number(r.min[d]) + " > max " + format_number(r.max[d]));
    }
  }
  if (auto x = m.get("body")) {
    r.body = x->name();
    if (std::none_of(bodies.begin(), bodies.end(), [&](const Body& b) { return b.name == r.body; })) {
      std::vector<std::string> defined;
      for (const Body& b : bodies) defined.push_back(b.name);
      x->fail("no body named '" + r.body + "'; defined: " + join(defined));
    }
  }
  return r;
}

std::array<bool, 3> read_components(const Value& v) {
  const std::string expected = "a non-empty list of distinct letters from x, y, z";
  const std::vector<Value> items = v.list(expected);
  if (items.empty()) v.fail("expected " + expected + ", got " + v.got());
  std::array<bool, 3> on{false, false, false};
  for (const Value& item : items) {
    const int d = item.choice<int>({{"x", 0}, {"y", 1}, {"z", 2}});
    if (on[d]) item.fail("component '" + item.node().Scalar() + "' is given twice; expected " + expected);
    on[d] = true;
  }
  return on;
}

Boundary read_boundary(const Value& v, UniqueNames& names, const std::vector<Body>& bodies) {
  const Map m(v, &kBoundaryKeys, "a map {name, region, velocity, components, ramp_time}");
  Boundary b;
  b.name = entry_name(m, "", 0, names);
  b.where = m.where();
  b.region = read_region(m.at("region"), bodies);
  if (auto x = m.get("velocity")) b.velocity = x->vec3("m/s");
  if (auto x = m.get("components")) b.components = read_components(*x);
  if (auto x = m.get("ramp_time")) b.ramp_time = x->non_negative("s");
  return b;
}

Tool read_tool(const Value& v, UniqueNames& names) {
  const Map m(v, &kToolKeys, "a map {name, kind, radius, center, velocity, friction, stiffness}");
  Tool t;
  t.name = entry_name(m, "", 0, names);
  t.where = m.where();
  t.sphere = m.at("kind").choice<bool>({{"cylinder", false}, {"sphere", true}});
  t.radius = m.at("radius").positive("m");
  if (t.sphere) {
    t.center = m.at("center").vec3("m");
    if (auto x = m.get("velocity")) t.velocity = x->vec3("m/s");
  } else {
    const auto c = m.at("center").vec2("m");
    t.center = {c[0], c[1], 0.0};
    if (auto x = m.get("velocity")) {
      const auto u = x->vec2("m/s");
      t.velocity = {u[0], u[1], 0.0};
    }
  }
  if (auto x = m.get("friction")) t.friction = x->non_negative("");
  // The stable step shrinks by sqrt(1 + stiffness): 1e6 already makes it a thousandth.
  if (auto x = m.get("stiffness"))
    t.stiffness = x->number_if("a number in (0, 1e6]", [](double k) { return k > 0 && k <= 1e6; });
  return t;
}

Initial read_initial(const Value& v) {
  const Map m(v, &kInitialKeys, "a map {displacement_gradient, velocity_gradient, center, seed}");
  Initial init;
  if (auto x = m.get("displacement_gradient")) init.displacement_gradient = x->matrix3("");
  if (auto x = m.get("velocity_gradient")) init.velocity_gradient = x->matrix3("1/s");
  if (auto x = m.get("center")) init.center = x->vec3("m");
  if (auto x = m.get("seed")) {
    const Map seed(*x, &kSeedKeys, "a map {amplitude: A, wavelength: [Lx, Ly]}");
    init.seed_amplitude = seed.at("amplitude").non_negative("m");
    if (auto w = seed.get("wavelength")) {
      const std::string expected = "a list of 2 non-negative numbers [Lx, Ly] [m]";
      const auto xs = w->numbers(2, 2, expected, "m");
      if (!(xs[0] >= 0 && xs[1] >= 0))
        w->fail("expected " + expected + ", got [" + join({format_number(xs[0]), format_number(xs[1])}) +
                "]");
      init.seed_wavelength_x = xs[0];
      init.seed_wavelength_y = xs[1];
    }
  }
  return init;
}

/// {boundary name: [x, y, z]} with every name an entry of `boundaries`.
std::vector<BoundaryValue> read_boundary_values(const Value& v, const std::vector<Boundary>& boundaries,
                                                std::string_view unit) {
  const Map m(v, nullptr, "a map of boundary name to [x, y, z]");
  std::vector<BoundaryValue> out;
  for (const auto& [name, value] : m.items()) {
    bool known = false;
    for (const Boundary& b : boundaries) known |= b.name == name;
    if (!known) {
      std::vector<std::string> defined;
      for (const Boundary& b : boundaries) defined.push_back(b.name);
      value.fail("no boundary named '" + name + "'; defined: " + (defined.empty() ? "none" : join(defined)));
    }
    out.push_back({name, value.vec3(unit)});
  }
  return out;
}

Stage read_stage(const Value& v, std::size_t index, UniqueNames& names, const std::vector<Boundary>& boundaries,
                 const std::vector<Crack>& cracks) {
  const Map m(v, &kStageKeys, "a map describing the stage");
  Stage s;
  s.name = entry_name(m, "stage", index, names);
  s.where = m.where();
  if (auto x = m.get("kind"))
    s.kind = x->choice<StageKind>({{"dynamic", StageKind::Dynamic},
                                   {"quasistatic", StageKind::QuasiStatic},
                                   {"release", StageKind::Release}});
  for (const auto& [key, kind] : kStageKeyKind)
    if (kind != s.kind)
      if (auto x = m.get(key))
        x->fail(std::string("this key belongs to ") + to_text(kind) + " stages; this stage is " + to_text(s.kind));
  if (s.kind == StageKind::QuasiStatic) {
    if (auto x = m.get("displacements")) s.displacements = read_boundary_values(*x, boundaries, "m");
    if (auto x = m.get("displacement_gradient")) s.displacement_gradient = x->matrix3("");
    if (auto x = m.get("load_steps")) s.load_steps = x->integer(1, 1000000);
    if (auto x = m.get("max_load_steps")) s.max_load_steps = x->integer(1, 100000000);
    if (s.max_load_steps < s.load_steps)
      m.at("max_load_steps").fail("expected an integer >= load_steps (" + std::to_string(s.load_steps) + "), got " +
                                  std::to_string(s.max_load_steps));
    if (auto x = m.get("in_plane")) s.in_plane = x->boolean();
    if (auto x = m.get("jacobian"))
      s.matrix_free = x->choice<bool>({{"assembled", false}, {"matrix_free", true}});
    if (auto x = m.get("jacobian_shift"))
      s.jacobian_shift = x->number_if("a number in [0, 1)", [](double f) { return f >= 0 && f < 1; });
    if (auto x = m.get("max_break_passes")) s.max_break_passes = x->integer(1, 1000000);
    return s;
  }
  if (s.kind == StageKind::Release) {
    const Value list = m.at("cracks");
    const std::string expected = "a non-empty list of crack names";
    const auto items = list.list(expected);
    if (items.empty()) list.fail("expected " + expected + ", got an empty list");
    for (const Value& item : items) {
      const std::string name = item.name();
      bool known = false;
      for (const Crack& c : cracks) known |= c.name == name;
      if (!known) {
        std::vector<std::string> defined;
        for (const Crack& c : cracks) defined.push_back(c.name);
        item.fail("no crack named '" + name + "'; defined: " + (defined.empty() ? "none" : join(defined)));
      }
      if (std::find(s.cracks.begin(), s.cracks.end(), name) != s.cracks.end())
        item.fail("crack '" + name + "' is named twice");
      s.cracks.push_back(name);
    }
    return s;
  }
  if (auto x = m.get("damping")) s.damping = x->non_negative("1/s");
  if (auto x = m.get("boundary_velocity")) s.boundary_velocity = read_boundary_values(*x, boundaries, "m/s");
  if (auto x = m.get("steps")) s.steps = x->integer(1, kMaxStageSteps);
  if (auto x = m.get("duration")) {
    if (s.steps)
      x->fail("give either duration or steps, not both (stage '" + s.name + "' has steps: " +
              std::to_string(*s.steps) + " and duration: " + x->got() + ")");
    s.duration = x->positive("s");
  } else if (!s.steps) {
    m.missing("duration", "simulated time, s; or give steps");
  }
  if (auto x = m.get("dt")) s.dt = x->positive("s");
  if (auto x = m.get("safety_factor"))
    s.safety_factor = x->number_if("a number in (0, 1]", [](double f) { return f > 0 && f <= 1; });
  if (auto x = m.get("allow_unstable_dt")) s.allow_unstable_dt = x->boolean();
  return s;
}

Output read_output(const Value& v) {
  const Map m(v, &kOutputKeys,
              "a map {frames, series_every, velocity, progress_seconds, checkpoint_every_steps, "
              "checkpoint_every_seconds}");
  Output out;
  constexpr long int_max = std::numeric_limits<int>::max();
  if (auto x = m.get("frames")) out.frames = static_cast<int>(x->integer(1, int_max));
  if (auto x = m.get("series_every")) out.series_every = static_cast<int>(x->integer(1, int_max));
  if (auto x = m.get("velocity")) out.write_velocity = x->boolean();
  if (auto x = m.get("progress_seconds")) out.progress_seconds = x->non_negative("s");
  if (auto x = m.get("checkpoint_every_steps")) out.checkpoint_every_steps = x->integer(0);
  if (auto x = m.get("checkpoint_every_seconds")) out.checkpoint_every_seconds = x->non_negative("s");
  return out;
}

LongRange read_long_range(const Value& v, const std::vector<Body>& bodies) {
  const Map m(v, &kLongRangeKeys, "a map {length, cutoff, exclusion, pairs}");
  LongRange lr;
  lr.where = m.where();
  if (std::none_of(bodies.begin(), bodies.end(), [](const Body& b) { return b.kind == BodyKind::Fiber; }))
    v.fail("long-range forces act between fiber nodes (eqs. 32-36); the scene has no body with kind: fiber");
  lr.length = m.at("length").positive("m");
  lr.cutoff = m.at("cutoff").positive("m");
  // Default: the largest fiber horizon (bonded neighbours do not also interact at long range).
  for (const Body& b : bodies)
    if (b.kind == BodyKind::Fiber) lr.exclusion = std::max(lr.exclusion, b.horizon_value());
  if (auto x = m.get("exclusion")) lr.exclusion = x->non_negative("m");
  const Value pairs = m.at("pairs");
  const std::vector<Value> rules = pairs.list("a list of pair rules {between, alpha, beta}");
  if (rules.empty()) pairs.fail("expected at least one pair rule {between, alpha, beta}, got an empty list");
  for (const Value& r : rules) {
    const Map rm(r, &kPairRuleKeys, "a map {between, alpha, beta}");
    PairRule rule;
    rule.where = rm.where();
    rule.between = rm.at("between").choice<PairKind>({{"adjacent_segments", PairKind::AdjacentSegments},
                                                      {"distant_segments", PairKind::DistantSegments},
                                                      {"other_fibers", PairKind::OtherFibers}});
    rule.alpha = rm.at("alpha").non_negative("J/m^6");
    rule.beta = rm.at("beta").number("a number [J/m^6] (negative: a repulsive 1/y^6 tail)");
    lr.pairs.push_back(rule);
  }
  return lr;
}

Scene read_scene(const Context& ctx, const YAML::Node& root, const std::string& file) {
  const Map top(Value(ctx, root, ""), &kSceneKeys, "a map");
  Scene s;
  s.file = file;
  s.name = top.at("name").given_name("scene");
  if (auto x = top.get("description")) s.description = x->string();

  const Map materials(top.at("materials"), nullptr, "a map of material name to material");
  if (materials.empty()) top.at("materials").fail("expected at least one material, got an empty map");
  materials.check_key_names("material");
  for (const auto& [name, v] : materials.items()) s.materials.push_back(read_material(name, v));

  const Map bodies(top.at("bodies"), nullptr, "a map of body name to body");
  if (bodies.empty()) top.at("bodies").fail("expected at least one body, got an empty map");
  bodies.check_key_names("body");
  for (const auto& [name, v] : bodies.items()) s.bodies.push_back(read_body(name, v, s.materials));

  UniqueNames crack_names("crack");
  const auto cracks = optional_list(top, "cracks", "a list of cracks");
  for (std::size_t i = 0; i < cracks.size(); ++i) s.cracks.push_back(read_crack(cracks[i], i, crack_names));

  UniqueNames boundary_names("boundary");
  for (const Value& v : optional_list(top, "boundaries", "a list of boundaries"))
    s.boundaries.push_back(read_boundary(v, boundary_names, s.bodies));

  UniqueNames tool_names("tool");
  const auto tools = optional_list(top, "tools", "a list of tools");
  for (const Value& v : tools) s.tools.push_back(read_tool(v, tool_names));

  if (auto x = top.get("long_range")) s.long_range = read_long_range(*x, s.bodies);

  if (auto x = top.get("initial")) s.initial = read_initial(*x);

  const Value stages_value = top.at("stages");
  const auto stages = stages_value.list("a list of stages");
  if (stages.empty()) stages_value.fail("expected at least one stage, got an empty list");
  UniqueNames stage_names("stage");
  for (std::size_t i = 0; i < stages.size(); ++i)
    s.stages.push_back(read_stage(stages[i], i, stage_names, s.boundaries, s.cracks));
  std::map<std::string, std::string> released;  // crack -> stage releasing it
  for (std::size_t i = 0; i < s.stages.size(); ++i)
    for (const std::string& c : s.stages[i].cracks)
      if (!released.emplace(c, s.stages[i].name).second)
        stages[i].fail("crack '" + c + "' is already released by stage '" + released[c] + "'");
  bool dynamic = false;
  for (const Stage& st : s.stages) dynamic |= st.kind == StageKind::Dynamic;
  if (!dynamic) stages_value.fail("expected at least one stage of kind dynamic");
  for (std::size_t i = 0; i < s.stages.size() && !s.tools.empty(); ++i)
    if (s.stages[i].kind == StageKind::QuasiStatic)
      stages[i].fail("a quasistatic stage in a scene with tools; tools act in dynamic stages only (tools: '" +
                     s.tools.front().name + "')");

  const bool pressurized = std::any_of(s.bodies.begin(), s.bodies.end(), [](const Body& b) { return b.pressure > 0; });
  for (std::size_t i = 0; i < s.stages.size() && pressurized; ++i)
    if (s.stages[i].kind == StageKind::QuasiStatic)
      stages[i].fail("a quasistatic stage in a scene with a pressurized sphere; the pressure acts in dynamic stages "
                     "only (the quasi-static residual holds the bonds alone)");
  for (std::size_t i = 0; i < s.stages.size() && s.long_range; ++i)
    if (s.stages[i].kind == StageKind::QuasiStatic)
      stages[i].fail("a quasistatic stage in a scene with long_range; long-range forces act in dynamic stages "
                     "only (the quasi-static tangent holds the bonds alone)");

  if (auto x = top.get("stability")) {
    const Map m(*x, &kStabilityKeys, "a map {energy_error, motion_per_step}");
    if (auto e = m.get("energy_error")) s.stability.energy_error = e->non_negative("");
    if (auto e = m.get("motion_per_step")) s.stability.motion_per_step = e->non_negative("");
  }

  if (auto x = top.get("output")) s.output = read_output(*x);
  return s;
}

// ------------------------------------------------------------------------------------------------
// Loading and overrides

std::string top_level_keys() {
  std::vector<std::string> names;
  for (const Key& k : kSceneKeys) names.emplace_back(k.name);
  return join(names);
}

/// Counts the documents of a YAML stream and where each starts, and the values they hold (at
/// most kMaxSceneValues, else InputError naming the top-level key being read), without building
/// nodes.
class DocumentCounter : public YAML::EventHandler {
 public:
  explicit DocumentCounter(std::string file) : file_(std::move(file)) {}
  std::vector<YAML::Mark> starts;  ///< per document: where it starts
  std::vector<YAML::Mark> roots;   ///< per document: where its root node starts
  void OnDocumentStart(const YAML::Mark& mark) override { starts.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& m, YAML::anchor_t) override { value(m, nullptr); }
  void OnAlias(const YAML::Mark& m, YAML::anchor_t) override { value(m, nullptr); }
  void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t, const std::string& text) override {
    value(m, &text);
  }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    value(m, nullptr);
    ++depth_;
  }
  void OnSequenceEnd() override { --depth_; }
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    value(m, nullptr);
    ++depth_;
  }
  void OnMapEnd() override { --depth_; }

 private:
  void value(const YAML::Mark& m, const std::string* scalar) {
    if (roots.size() < starts.size()) roots.push_back(m);
    // Directly inside the top-level map, entries alternate key and value.
    if (depth_ == 1) {
      if (key_next_ && scalar) key_ = *scalar;
      key_next_ = !key_next_;
    }
    if (++values_ <= kMaxSceneValues) return;
    throw InputError(SourceLoc{file_, m.line >= 0 ? m.line + 1 : 1}.str() + ": " + (key_.empty() ? "top level" : key_) +
                     ": the scene holds more than " + std::to_string(kMaxSceneValues) +
                     " YAML values (numbers, strings, lists, maps) by this line; expected at most " +
                     std::to_string(kMaxSceneValues) + " (about 90000 cracks written as {from: [x, y, z], to: [x, y, z]})");
  }

  std::string file_;
  std::string key_;  // top-level key whose value is being read
  int depth_ = 0;
  bool key_next_ = true;
  long values_ = 0;
};

/// The scene text handed to yaml-cpp in 64 KiB pieces, asking `stop` before each piece (yaml-cpp
/// reads through the stream buffer as it scans), so that a long text can be abandoned mid-way.
class StoppableText : public std::streambuf {
 public:
  StoppableText(const std::string& text, const StopCheck& stop) : text_(text), stop_(stop) {}

 protected:
  int_type underflow() override {
    if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
    if (next_ >= text_.size()) return traits_type::eof();
    if (stop_ && stop_()) throw StopRequested("stopped while reading the scene");
    char* begin = const_cast<char*>(text_.data()) + next_;
    next_ = std::min(text_.size(), next_ + (std::size_t{1} << 16));
    setg(begin, begin, const_cast<char*>(text_.data()) + next_);
    return traits_type::to_int_type(*begin);
  }

 private:
  const std::string& text_;
  const StopCheck& stop_;
  std::size_t next_ = 0;
};

/// A stream over a StoppableText whose reads let the stop request (StopRequested) reach the caller.
struct StoppableStream : std::istream {
  StoppableStream(const std::string& text, const StopCheck& stop) : std::istream(nullptr), buffer(text, stop) {
    rdbuf(&buffer);
    exceptions(std::ios::badbit);
  }
  StoppableText buffer;
};

YAML::Node load_document(const std::string& text, const std::string& file, const StopCheck& stop) {
  std::vector<YAML::Node> docs;
  try {
    // Count the documents first. YAML::LoadAll is not used: on a token that starts no node (a
    // ',' outside a flow collection) yaml-cpp returns the same empty document forever, filling
    // memory; a document that starts where the previous one started is that token.
    DocumentCounter counter(file);
    StoppableStream in(text, stop);
    YAML::Parser parser(in);
    while (parser.HandleNextDocument(counter)) {
      const std::size_t n = counter.starts.size();
      if (n >= 2 && counter.starts[n - 1].pos == counter.starts[n - 2].pos) {
        const YAML::Mark& m = counter.starts[n - 1];
        throw InputError(SourceLoc{file, m.line >= 0 ? m.line + 1 : 1}.str() +
                         ": YAML syntax error: unexpected character '" +
                         (m.pos >= 0 && static_cast<std::size_t>(m.pos) < text.size() ? text.substr(m.pos, 1) : "") +
                         "' where a value should start");
      }
    }
    if (counter.starts.size() > 1) {
      const YAML::Mark& m = counter.roots.size() > 1 ? counter.roots[1] : counter.starts[1];
      throw InputError(SourceLoc{file, m.line >= 0 ? m.line + 1 : 1}.str() +
                       ": expected a single YAML document, found " + std::to_string(counter.starts.size()));
    }
    if (!counter.starts.empty()) {
      StoppableStream again(text, stop);
      docs.push_back(YAML::Load(again));
    }
  } catch (const YAML::Exception& e) {
    throw InputError(SourceLoc{file, e.mark.line >= 0 ? e.mark.line + 1 : 1}.str() +
                     ": YAML syntax error: " + e.msg);
  }
  if (docs.empty() || docs[0].IsNull()) {
    throw InputError(file + ":1: the scene is empty; expected a YAML map with the keys: " + top_level_keys());
  }
  if (!docs[0].IsMap()) {
    throw InputError(file + ":1: expected a YAML map at the top level (keys: " + top_level_keys() +
                     "), got " + describe(docs[0]));
  }
  return docs[0];
}

/// Index of the entry of list `list` (at key path `list_path`) that `segment` addresses: a
/// 0-based index, or the value of the entries' `name` key (or their default name).
std::size_t find_entry(const YAML::Node& list, const std::string& segment, const std::string& list_path,
                       const std::function<void(const std::string&)>& fail) {
  const bool digits =
      std::all_of(segment.begin(), segment.end(), [](char c) { return c >= '0' && c <= '9'; });
  if (digits) {
    std::size_t index = 0;
    const auto r = std::from_chars(segment.data(), segment.data() + segment.size(), index);
    if (r.ec != std::errc() || index >= list.size()) {
      fail("index " + segment + " is out of range: " + list_path + " has " + std::to_string(list.size()) +
           " entries");
    }
    return index;
  }
  const std::string prefix = default_name_prefix(list_path);
  std::vector<std::string> names;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node entry = list[i];
    std::string name;
    if (entry.IsMap() && entry["name"].IsDefined() && entry["name"].IsScalar())
      name = entry["name"].Scalar();
    else if (!prefix.empty())
      name = prefix + std::to_string(i);
    if (!name.empty() && name == segment) return i;
    if (!name.empty()) names.push_back(name);
  }
  fail("no entry named '" + segment + "' in " + list_path +
       (names.empty() ? std::string(" (it has no named entries)") : "; names: " + join(names)));
  return 0;
}

/// Applies one override to the document tree and records the key paths it set (with list
/// entries by index, as validation messages name them).
void apply_override(YAML::Node& root, const Override& o, Context& ctx) {
  const auto fail = [&](const std::string& why) {
    throw InputError("--set " + o.path + "=" + o.value + ": " + why);
  };
  YAML::Node value;
  try {
    value = YAML::Load(o.value);
  } catch (const YAML::Exception& e) {
    fail("cannot read the value as YAML: " + e.msg);
  }
  std::vector<std::string> segments;
  for (std::size_t start = 0;;) {
    const std::size_t dot = o.path.find('.', start);
    segments.push_back(o.path.substr(start, dot == std::string::npos ? dot : dot - start));
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  if (std::any_of(segments.begin(), segments.end(), [](const std::string& s) { return s.empty(); }))
    fail("expected a dotted key path such as bodies.sheet.spacing");

  YAML::Node cur = root;
  std::string path;  // canonical path of `cur`
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const std::string& segment = segments[i];
    const bool last = i + 1 == segments.size();
    YAML::Node next;
    if (cur.IsSequence()) {
      const std::size_t index = find_entry(cur, segment, path, fail);
      path = child_path(path, std::to_string(index));
      if (last) {
        YAML::Node slot = cur[index];
        slot = value;
        break;
      }
      next.reset(cur[index]);
    } else if (cur.IsMap()) {
      path = child_path(path, segment);
      if (last) {
        cur[segment] = value;
        break;
      }
      const YAML::Node& const_cur = cur;
      const YAML::Node existing = const_cur[segment];
      if (!existing.IsDefined() || existing.IsNull()) {
        cur[segment] = YAML::Node(YAML::NodeType::Map);
        ctx.mark_overridden(path);
      }
      next.reset(cur[segment]);
    } else {
      fail("'" + path + "' holds a single value (" + (cur.IsScalar() ? cur.Scalar() : "empty") +
           "), not a map or a list, so it has no entry '" + segment + "'");
    }
    cur.reset(next);
  }
  // A stage's steps and duration exclude each other: an override of one replaces the other where
  // the file gave it (both given by overrides stay, and are refused).
  const std::string leaf = segments.back();
  if (cur.IsMap() && !value.IsNull() && (leaf == "steps" || leaf == "duration") && path.rfind("stages.", 0) == 0 &&
      std::count(path.begin(), path.end(), '.') == 2) {
    const std::string other = leaf == "steps" ? "duration" : "steps";
    const std::string stage_path = path.substr(0, path.size() - leaf.size() - 1);
    const YAML::Node& const_cur = cur;
    if (const_cur[other].IsDefined() && !ctx.overridden(child_path(stage_path, other))) cur.remove(other);
  }
  ctx.mark_overridden(path);
}

// ------------------------------------------------------------------------------------------------
// Emitting

/// A string as a YAML scalar: plain when that reads back as the same string, else double-quoted.
std::string yaml_string(const std::string& s) {
  static const char* const reserved[] = {"true", "false", "yes",  "no",  "on",  "off",
                                         "y",    "n",     "null", "nan", "inf", "infinity"};
  bool plain =
      !s.empty() && (std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_') && s.back() != ' ';
  for (char c : s) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (!(std::isalnum(u) || c == '_' || c == '-' || c == '.' || c == '/' || c == ' ')) plain = false;
  }
  if (plain) {
    std::string lower = s;
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    for (const char* r : reserved)
      if (lower == r) plain = false;
  }
  if (plain) return s;
  std::string out = "\"";
  for (char c : s) {
    const unsigned char u = static_cast<unsigned char>(c);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (u < 0x20 || u == 0x7f) {
          static const char hex[] = "0123456789abcdef";
          out += "\\x";
          out += hex[u >> 4];
          out += hex[u & 15];
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string flow(std::initializer_list<double> xs) {
  std::vector<std::string> parts;
  for (double x : xs) parts.push_back(format_number(x));
  return "[" + join(parts) + "]";
}

std::string flow(const Vec3& v) { return flow({v[0], v[1], v[2]}); }

std::string flow(const std::array<double, 9>& m) {
  return "[" + flow({m[0], m[1], m[2]}) + ", " + flow({m[3], m[4], m[5]}) + ", " + flow({m[6], m[7], m[8]}) +
         "]";
}

const char* to_text(Influence k) { return k == Influence::Constant ? "constant" : "conical"; }
const char* to_text(BodyKind k) {
  return k == BodyKind::Membrane ? "membrane"
         : k == BodyKind::Solid  ? "solid"
         : k == BodyKind::Lattice ? "lattice"
         : k == BodyKind::Fiber  ? "fiber"
                                 : "sphere";
}
const char* to_text(PairKind k) {
  return k == PairKind::AdjacentSegments ? "adjacent_segments"
         : k == PairKind::DistantSegments ? "distant_segments"
                                          : "other_fibers";
}
const char* to_text(Grid k) { return k == Grid::Square ? "square" : "hexagonal"; }
const char* to_text(Quadrature k) {
  return k == Quadrature::Full ? "full" : k == Quadrature::Taper ? "taper" : "partial_area";
}
const char* to_text(StageKind k) {
  return k == StageKind::Dynamic ? "dynamic" : k == StageKind::QuasiStatic ? "quasistatic" : "release";
}
const char* to_text(bool b) { return b ? "true" : "false"; }

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

void emit_material(Writer& w, const Material& m) {
  w.key(2, yaml_string(m.name), "");
  w.key(4, "model", m.model);
  w.key(4, "density", m.density);
  if (m.marder) {
    w.key(4, "mooney_rivlin_a", m.marder->a);
    w.key(4, "mooney_rivlin_b", m.marder->b);
    w.key(4, "cutoff", m.marder->cutoff);
    w.key(4, "fracture_separation", m.marder->fracture_separation);
    w.key(4, "breaking", m.marder->reversible ? "reversible" : "irreversible");
    if (m.marder->kelvin_viscosity > 0) w.key(4, "kelvin_viscosity", m.marder->kelvin_viscosity);
    return;
  }
  w.optional(4, "wave_speed", m.wave_speed);
  w.optional(4, "bulk_modulus", m.bulk_modulus);
  w.optional(4, "youngs_modulus", m.youngs_modulus);
  w.optional(4, "micromodulus", m.micromodulus);
  // The shared keys the model takes (its catalog entry), resolved: influence with its default.
  const MaterialModel* model = find_material_model(m.model);
  const auto takes = [&](const char* key) {
    return model && std::find(model->keys.begin(), model->keys.end(), key) != model->keys.end();
  };
  if (takes("influence")) w.key(4, "influence", to_text(m.influence));
  w.optional(4, "critical_stretch", m.critical_stretch);
  w.optional(4, "critical_stretch_at_horizon", m.critical_stretch_at_horizon);
  if (m.hardening) {
    w.key(4, "hardening",
          "{coefficient: " + format_number(m.hardening->coefficient) +
              ", exponent: " + format_number(m.hardening->exponent) + "}");
  }
}

// horizon and horizon_factor exclude each other: write the one in effect.
void emit_horizon(Writer& w, const Body& b) {
  if (b.horizon)
    w.key(4, "horizon", *b.horizon);
  else
    w.key(4, "horizon_factor", b.horizon_factor);
}

void emit_body(Writer& w, const Body& b) {
  const bool membrane = b.kind != BodyKind::Solid;
  w.key(2, yaml_string(b.name), "");
  w.key(4, "kind", to_text(b.kind));
  w.key(4, "material", yaml_string(b.material));
  if (b.kind == BodyKind::Shell) {
    w.key(4, "center", flow(b.origin));
    w.key(4, "radius", b.radius);
    w.key(4, "thickness", b.thickness);
    w.key(4, "spacing", b.spacing);
    emit_horizon(w, b);
    w.key(4, "pressure", b.pressure);
    w.key(4, "pressure_ramp_time", b.pressure_ramp_time);
    return;
  }
  if (b.kind == BodyKind::Fiber) {
    if (b.network) {
      const FiberNetwork& n = *b.network;
      w.key(4, "network", "");
      w.key(6, "box", "{min: " + flow(n.min) + ", max: " + flow(n.max) + "}");
      std::vector<std::string> fams;
      for (const FiberFamily& f : n.families)
        fams.push_back(std::string("{direction: ") + (f.axis == 0 ? "x" : "y") + ", count: " + std::to_string(f.count) + "}");
      w.key(6, "families", "[" + join(fams) + "]");
      w.key(6, "deviation", n.deviation);
      w.key(6, "step", n.step);
      w.key(6, "start_band", n.start_band);
      w.key(6, "seed", std::to_string(n.seed));
    } else {
      std::vector<std::string> points;
      for (const Vec3& p : b.path) points.push_back(flow(p));
      w.key(4, "path", "[" + join(points) + "]");
    }
    w.key(4, "diameter", b.diameter);
    w.key(4, "spacing", b.spacing);
    w.key(4, "segment_length", b.segment_length);
    emit_horizon(w, b);
    return;
  }
  w.key(4, "origin", flow(b.origin));
  w.key(4, "size", membrane ? flow({b.size[0], b.size[1]}) : flow(b.size));
  if (membrane) w.key(4, "thickness", b.thickness);
  w.key(4, "spacing", b.spacing);
  if (b.breakable)
    w.key(4, "breakable", "{min: " + flow((*b.breakable)[0]) + ", max: " + flow((*b.breakable)[1]) + "}");
  if (b.kind == BodyKind::Lattice) return;
  w.key(4, "grid", to_text(b.grid));
  emit_horizon(w, b);
  w.key(4, "quadrature", to_text(b.quadrature));
}

void emit_boundary(Writer& w, const Boundary& b) {
  w.key(2, "- name", yaml_string(b.name));
  std::string region = "{min: " + flow(b.region.min) + ", max: " + flow(b.region.max);
  if (!b.region.body.empty()) region += ", body: " + yaml_string(b.region.body);
  w.key(4, "region", region + "}");
  w.key(4, "velocity", flow(b.velocity));
  std::vector<std::string> comps;
  for (int d = 0; d < 3; ++d)
    if (b.components[d]) comps.emplace_back(1, "xyz"[d]);
  w.key(4, "components", "[" + join(comps) + "]");
  w.key(4, "ramp_time", b.ramp_time);
}

void emit_tool(Writer& w, const Tool& t) {
  w.key(2, "- name", yaml_string(t.name));
  w.key(4, "kind", t.sphere ? "sphere" : "cylinder");
  w.key(4, "radius", t.radius);
  w.key(4, "center", t.sphere ? flow(t.center) : flow({t.center[0], t.center[1]}));
  w.key(4, "velocity", t.sphere ? flow(t.velocity) : flow({t.velocity[0], t.velocity[1]}));
  w.key(4, "friction", t.friction);
  w.key(4, "stiffness", t.stiffness);
}

std::string flow_values(const std::vector<BoundaryValue>& values) {
  std::vector<std::string> items;
  for (const BoundaryValue& b : values) items.push_back(yaml_string(b.boundary) + ": " + flow(b.value));
  return "{" + join(items) + "}";
}

void emit_stage(Writer& w, const Stage& s) {
  w.key(2, "- name", yaml_string(s.name));
  w.key(4, "kind", to_text(s.kind));
  if (s.kind == StageKind::QuasiStatic) {
    w.key(4, "displacements", flow_values(s.displacements));
    w.key(4, "displacement_gradient", flow(s.displacement_gradient));
    w.key(4, "load_steps", std::to_string(s.load_steps));
    w.key(4, "max_load_steps", std::to_string(s.max_load_steps));
    w.key(4, "in_plane", to_text(s.in_plane));
    w.key(4, "jacobian", s.matrix_free ? "matrix_free" : "assembled");
    w.key(4, "jacobian_shift", s.jacobian_shift);
    w.key(4, "max_break_passes", std::to_string(s.max_break_passes));
    return;
  }
  if (s.kind == StageKind::Release) {
    std::vector<std::string> names;
    for (const std::string& c : s.cracks) names.push_back(yaml_string(c));
    w.key(4, "cracks", "[" + join(names) + "]");
    return;
  }
  // With steps given, duration is optional; 0 stands for "not given".
  if (!(s.steps && s.duration == 0.0)) w.key(4, "duration", s.duration);
  if (s.steps) w.key(4, "steps", std::to_string(*s.steps));
  w.optional(4, "dt", s.dt);
  w.key(4, "safety_factor", s.safety_factor);
  w.key(4, "allow_unstable_dt", to_text(s.allow_unstable_dt));
  w.key(4, "damping", s.damping);
  if (!s.boundary_velocity.empty()) w.key(4, "boundary_velocity", flow_values(s.boundary_velocity));
}

// The schema as documentation (scene/describe.hpp).

std::vector<KeyDoc> key_docs(const Keys& keys, const std::function<bool(const Key&)>& take = {}) {
  std::vector<KeyDoc> out;
  for (const Key& k : keys)
    if (!take || take(k)) out.push_back({k.name, k.required, k.unit, k.fallback, k.doc});
  return out;
}

// The models of the catalog that take a material key, as the reader decides it (read_material).
std::vector<std::string> models_taking(const std::string& key) {
  const bool marder_key = std::find(std::begin(kMarderKeys), std::end(kMarderKeys), key) != std::end(kMarderKeys);
  std::vector<std::string> takers;
  for (const std::string& name : material_model_names()) {
    const MaterialModel& m = *find_material_model(name);
    const bool takes = key == "model" || key == "density" ||
                       (m.lattice ? marder_key
                                  : std::find(m.keys.begin(), m.keys.end(), key) != m.keys.end() ||
                                        std::find(m.stiffness.begin(), m.stiffness.end(), key) != m.stiffness.end());
    if (takes) takers.push_back(name);
  }
  return takers;
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Public functions

std::vector<KeySection> scene_key_sections() {
  std::vector<KeySection> out;
  out.push_back({"", "", key_docs(kSceneKeys)});
  // Material keys, grouped by the models that take them (every model first).
  std::vector<std::vector<std::string>> groups;
  for (const Key& k : kMaterialKeys) {
    const std::vector<std::string> takers = models_taking(k.name);
    if (takers.empty() || std::find(groups.begin(), groups.end(), takers) != groups.end()) continue;
    groups.push_back(takers);
    const bool every = takers.size() == material_model_names().size();
    out.push_back({"materials.<name>", every ? "" : "model: " + join(takers),
                   key_docs(kMaterialKeys, [&](const Key& x) { return models_taking(x.name) == takers; })});
  }
  out.push_back({"materials.<name>.hardening", "model: " + join(models_taking("hardening")), key_docs(kHardeningKeys)});
  out.push_back({"bodies.<name>", "", key_docs(kBodyKeys)});
  out.push_back({"bodies.<name>.breakable", "kind: lattice", key_docs(kBoxKeys)});
  out.push_back({"bodies.<name>.network", "kind: fiber", key_docs(kNetworkKeys)});
  out.push_back({"bodies.<name>.network.box", "kind: fiber", key_docs(kBoxKeys)});
  out.push_back({"bodies.<name>.network.families[i]", "kind: fiber", key_docs(kFamilyKeys)});
  out.push_back({"cracks[i]", "", key_docs(kCrackKeys)});
  out.push_back({"boundaries[i]", "", key_docs(kBoundaryKeys)});
  out.push_back({"boundaries[i].region", "", key_docs(kRegionKeys)});
  out.push_back({"tools[i]", "", key_docs(kToolKeys)});
  out.push_back({"long_range", "", key_docs(kLongRangeKeys)});
  out.push_back({"long_range.pairs[i]", "", key_docs(kPairRuleKeys)});
  out.push_back({"initial", "", key_docs(kInitialKeys)});
  out.push_back({"initial.seed", "", key_docs(kSeedKeys)});
  // Stage keys: those of every kind, then each kind's own (kStageKeyKind, as the reader refuses them).
  out.push_back({"stages[i]", "", key_docs(kStageKeys, [](const Key& k) { return !kStageKeyKind.count(k.name); })});
  for (StageKind kind : {StageKind::Dynamic, StageKind::QuasiStatic, StageKind::Release})
    out.push_back({"stages[i]", std::string("kind: ") + to_text(kind), key_docs(kStageKeys, [&](const Key& k) {
                     const auto it = kStageKeyKind.find(k.name);
                     return it != kStageKeyKind.end() && it->second == kind;
                   })});
  out.push_back({"stability", "", key_docs(kStabilityKeys)});
  out.push_back({"output", "", key_docs(kOutputKeys)});
  return out;
}

std::vector<ModelDoc> scene_model_docs() {
  std::vector<ModelDoc> out;
  for (const std::string& name : material_model_names()) {
    const MaterialModel& m = *find_material_model(name);
    out.push_back({m.name, m.description, m.stiffness});
  }
  return out;
}

const Material& Scene::material(const std::string& material_name) const {
  const int i = material_index(material_name);
  if (i < 0) {
    std::vector<std::string> defined;
    for (const Material& m : materials) defined.push_back(m.name);
    throw InputError("no material named '" + material_name + "'; defined: " + join(defined));
  }
  return materials[static_cast<std::size_t>(i)];
}

/// Position of the material in `materials`, or -1 if there is none of that name.
int Scene::material_index(const std::string& material_name) const {
  for (std::size_t i = 0; i < materials.size(); ++i)
    if (materials[i].name == material_name) return static_cast<int>(i);
  return -1;
}

bool Scene::released_later(const std::string& crack) const {
  for (const Stage& st : stages)
    for (const std::string& c : st.cracks)
      if (c == crack) return true;
  return false;
}

Scene parse_scene(const std::string& text, const std::string& file, const std::vector<Override>& overrides,
                  const StopCheck& stop) {
  Context ctx(file);
  YAML::Node root = load_document(text, file, stop);
  for (const Override& o : overrides) apply_override(root, o, ctx);
  return read_scene(ctx, root, file);
}

Scene load_scene(const std::string& path, const std::vector<Override>& overrides, const StopCheck& stop) {
  const auto fail = [&](int err) {
    throw InputError("cannot read scene file '" + path + "': " + std::strerror(err));
  };
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) fail(errno);
  std::string text;
  char buf[1 << 16];
  for (;;) {
    const std::size_t n = std::fread(buf, 1, sizeof buf, f.get());
    text.append(buf, n);
    if (n < sizeof buf) break;
  }
  if (std::ferror(f.get())) fail(errno != 0 ? errno : EIO);
  return parse_scene(text, path, overrides, stop);
}

std::string emit_scene(const Scene& s, const std::vector<std::string>& derived) {
  Writer w;
  w.key(0, "name", yaml_string(s.name));
  w.key(0, "description", yaml_string(s.description));
  w.key(0, "materials", "");
  for (const Material& m : s.materials) emit_material(w, m);
  w.key(0, "bodies", "");
  for (const Body& b : s.bodies) emit_body(w, b);
  if (!s.cracks.empty()) {
    w.key(0, "cracks", "");
    for (const Crack& c : s.cracks) {
      w.key(2, "- name", yaml_string(c.name));
      w.key(4, "from", flow(c.from));
      w.key(4, "to", flow(c.to));
    }
  }
  if (!s.boundaries.empty()) {
    w.key(0, "boundaries", "");
    for (const Boundary& b : s.boundaries) emit_boundary(w, b);
  }
  if (!s.tools.empty()) {
    w.key(0, "tools", "");
    for (const Tool& t : s.tools) emit_tool(w, t);
  }
  if (s.long_range) {
    const LongRange& lr = *s.long_range;
    w.key(0, "long_range", "");
    w.key(2, "length", lr.length);
    w.key(2, "cutoff", lr.cutoff);
    w.key(2, "exclusion", lr.exclusion);
    w.key(2, "pairs", "");
    for (const PairRule& r : lr.pairs)
      w.line(4, std::string("- {between: ") + to_text(r.between) + ", alpha: " + format_number(r.alpha) +
                    ", beta: " + format_number(r.beta) + "}");
  }
  const Initial& init = s.initial;
  w.key(0, "initial", "");
  w.key(2, "displacement_gradient", flow(init.displacement_gradient));
  w.key(2, "velocity_gradient", flow(init.velocity_gradient));
  w.key(2, "center", flow(init.center));
  w.key(2, "seed",
        "{amplitude: " + format_number(init.seed_amplitude) +
            ", wavelength: " + flow({init.seed_wavelength_x, init.seed_wavelength_y}) + "}");
  w.key(0, "stages", "");
  for (const Stage& st : s.stages) emit_stage(w, st);
  w.key(0, "stability", "");
  w.key(2, "energy_error", s.stability.energy_error);
  w.key(2, "motion_per_step", s.stability.motion_per_step);
  w.key(0, "output", "");
  w.key(2, "frames", std::to_string(s.output.frames));
  w.key(2, "series_every", std::to_string(s.output.series_every));
  w.key(2, "velocity", to_text(s.output.write_velocity));
  w.key(2, "progress_seconds", s.output.progress_seconds);
  w.key(2, "checkpoint_every_steps", std::to_string(s.output.checkpoint_every_steps));
  w.key(2, "checkpoint_every_seconds", s.output.checkpoint_every_seconds);
  for (const std::string& text : derived) {
    // One comment line per line of text, so that the result stays valid YAML.
    std::size_t start = 0;
    for (;;) {
      const std::size_t nl = text.find('\n', start);
      w.line(0, "# " + text.substr(start, nl == std::string::npos ? nl : nl - start));
      if (nl == std::string::npos) break;
      start = nl + 1;
    }
  }
  return std::move(w).str();
}

}  // namespace peri
