// The --set overrides (overrides.hpp).
#include "overrides.hpp"

#include <yaml-cpp/eventhandler.h>

#include <algorithm>
#include <functional>
#include <sstream>

#include "peri/core/format.hpp"
#include "schema.hpp"

namespace peri::scene_detail {
namespace {

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

/// Counts the YAML documents of a text. yaml-cpp's Load reads the first and drops the rest, and
/// it takes text after a complete value (`[5, 0] [50, 0]`, `"abc" junk`) for a second document.
struct DocumentCount : YAML::EventHandler {
  int documents = 0;
  void OnDocumentStart(const YAML::Mark&) override { ++documents; }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t, const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

}  // namespace

/// Applies one override to the document tree and records the key paths it set (with list
/// entries by index, as validation messages name them).
void apply_override(YAML::Node& root, const Override& o, Context& ctx) {
  const auto fail = [&](const std::string& why) {
    throw InputError("--set " + shown_value(o.path) + "=" + shown_value(o.value) + ": " + why);
  };
  if (first_bad_utf8(o.value) != std::string::npos) fail("the value is not UTF-8 text; expected UTF-8");
  YAML::Node value;
  try {
    std::istringstream text(o.value);
    YAML::Parser parser(text);
    DocumentCount count;
    while (count.documents < 2 && parser.HandleNextDocument(count)) {
    }
    if (count.documents > 1)
      fail("text after the value; expected one YAML value (a value that starts with a quote or a bracket ends "
           "where it closes: to give the whole text as a string, wrap it in quotes of the other kind)");
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
        // A key inside an entry of materials or bodies that the scene lacks is a misspelt name
        // far more often than a new entry built key by key (which takes a whole map anyway).
        if (i == 1 && (segments[0] == "materials" || segments[0] == "bodies")) {
          std::vector<std::string> names;
          for (const auto& entry : const_cur) names.push_back(entry.first.as<std::string>());
          const std::string what = segments[0] == "bodies" ? "body" : "material";
          fail("the scene has no " + what + " '" + segment + "'" +
               (names.empty() ? std::string() : "; its " + segments[0] + ": " + join(names)) + " (a new " + what +
               " is given whole: --set " + segments[0] + "." + segment + "={...})");
        }
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

}  // namespace peri::scene_detail
