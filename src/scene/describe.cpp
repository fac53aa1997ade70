// The scene's keys as documentation (peridrive --describe-keys): the reader's schema, section by
// section, as Markdown tables (the generated part of docs/user/scene-reference.md) or as text.
#include "peri/scene/describe.hpp"

#include <cctype>
#include <sstream>

#include "peri/core/error.hpp"

namespace peri {
namespace {

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

std::string default_of(const KeyDoc& k) {
  if (k.required) return "required";
  return k.fallback.empty() ? "-" : k.fallback;
}

std::string title_of(const KeySection& s, bool markdown) {
  std::string t = s.path.empty() ? "top level" : markdown ? "`" + s.path + "`" : s.path;
  return s.condition.empty() ? t : t + ", " + s.condition;
}

// A table cell: pipes escaped (GitHub tables split on them, inside code spans too), and a '<'
// that would open an HTML tag outside a code span (crack<i>) written as an entity.
std::string cell(const std::string& text) {
  std::string out;
  bool code = false;
  for (std::size_t k = 0; k < text.size(); ++k) {
    const char c = text[k];
    if (c == '`') code = !code;
    if (c == '|') out += '\\';
    const char next = k + 1 < text.size() ? text[k + 1] : ' ';
    if (c == '<' && !code && (std::isalpha(static_cast<unsigned char>(next)) || next == '/' || next == '!')) {
      out += "&lt;";
      continue;
    }
    out += c;
  }
  return out;
}

// `text` wrapped at `width` columns, every line indented by `indent` spaces.
std::string wrapped(const std::string& text, std::size_t indent, std::size_t width = 100) {
  std::istringstream words(text);
  std::string word, line, out;
  while (words >> word) {
    if (!line.empty() && indent + line.size() + 1 + word.size() > width) {
      out += std::string(indent, ' ') + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  if (!line.empty()) out += std::string(indent, ' ') + line + "\n";
  return out;
}

void markdown_models(std::ostringstream& out, const std::vector<ModelDoc>& models) {
  out << "Values of `model`:\n\n| model | meaning | stiffness from |\n| --- | --- | --- |\n";
  for (const ModelDoc& m : models) {
    std::vector<std::string> keys;
    for (const std::string& k : m.stiffness) keys.push_back("`" + k + "`");
    out << "| `" << m.name << "` | " << cell(m.meaning) << " | "
        << (keys.empty() ? "its own keys" : join(keys)) << " |\n";
  }
  out << "\n";
}

void markdown_kinds(std::ostringstream& out, const std::vector<KindDoc>& kinds) {
  out << "Values of `kind` (each takes the keys of its section below):\n\n| kind | nodes |\n| --- | --- |\n";
  for (const KindDoc& k : kinds) out << "| `" << k.name << "` | " << cell(k.meaning) << " |\n";
  out << "\n";
}

void text_kinds(std::ostringstream& out, const std::vector<KindDoc>& kinds) {
  out << "  values of kind:\n";
  for (const KindDoc& k : kinds) out << wrapped(k.name + ": " + k.meaning, 6);
}

void text_models(std::ostringstream& out, const std::vector<ModelDoc>& models) {
  out << "  values of model:\n";
  for (const ModelDoc& m : models)
    out << wrapped(m.name + ": " + m.meaning +
                       (m.stiffness.empty() ? "" : " (stiffness from " + join(m.stiffness) + ")"),
                   6);
}

}  // namespace

std::string describe_scene_keys(KeyFormat format) {
  const std::vector<KeySection> sections = scene_key_sections();
  for (const KeySection& s : sections)
    for (const KeyDoc& k : s.keys)
      if (k.meaning.empty())
        throw Error("scene key '" + (s.path.empty() ? k.name : s.path + "." + k.name) +
                    "' has no meaning in the schema (src/scene/schema.hpp, or its body kind's module in "
                    "src/geometry/kinds/); document it there");
  const std::vector<ModelDoc> models = scene_model_docs();
  const std::vector<KindDoc> kinds = scene_kind_docs();
  const bool markdown = format == KeyFormat::Markdown;
  std::ostringstream out;
  if (!markdown)
    out << "Scene keys (SI units). KEY [unit] = default; required: must be given; -: no value when absent.\n";
  for (const KeySection& s : sections) {
    if (markdown) {
      out << "### " << title_of(s, true) << "\n\n";
      if (s.path == "materials.<name>" && s.condition.empty()) markdown_models(out, models);
      if (s.path == "bodies.<name>" && s.condition.empty()) markdown_kinds(out, kinds);
      out << "| key | unit | default | meaning |\n| --- | --- | --- | --- |\n";
      for (const KeyDoc& k : s.keys)
        out << "| `" << k.name << "` | " << cell(k.unit) << " | " << cell(default_of(k)) << " | "
            << cell(k.meaning) << " |\n";
      out << "\n";
    } else {
      out << "\n" << title_of(s, false) << "\n";
      for (const KeyDoc& k : s.keys) {
        out << "  " << k.name << (k.unit.empty() ? "" : " [" + k.unit + "]") << " = " << default_of(k)
            << "\n";
        out << wrapped(k.meaning, 6);
      }
      if (s.path == "materials.<name>" && s.condition.empty()) text_models(out, models);
      if (s.path == "bodies.<name>" && s.condition.empty()) text_kinds(out, kinds);
    }
  }
  std::string text = out.str();
  if (markdown && text.size() > 1) text.pop_back();  // no blank line at the end
  return text;
}

}  // namespace peri
