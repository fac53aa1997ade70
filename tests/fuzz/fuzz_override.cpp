// Fuzz target: the --set override language (libFuzzer entry point; replay.cpp drives it from
// ctest). The input is a list of overrides, one per line, KEY=VALUE split at the first '=' (a line
// without one is a key with an empty value, which the library must refuse or accept like any
// other); a line starting with a space continues the value before it on a new line (block YAML).
// They are applied to the embedded default scene through parse_scene, which must give a Scene or
// throw peri::InputError; an accepted scene must read the same twice and round-trip through
// emit_scene. Anything else (crash, hang, other exception, mismatch) aborts: a finding.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include "peri/core/error.hpp"
#include "peri/scene/scene.hpp"

namespace {

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "fuzz_override finding: %s\n", what.c_str());
  std::abort();
}

std::vector<peri::Override> overrides_of(const std::string& text) {
  std::vector<peri::Override> list;
  std::size_t start = 0;
  while (start < text.size() && list.size() < 64) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string line = text.substr(start, end - start);
    start = end + 1;
    if (!line.empty() && line[0] == ' ' && !list.empty()) {
      list.back().value += "\n" + line;
      continue;
    }
    const std::size_t eq = line.find('=');
    if (eq == std::string::npos)
      list.push_back({line, ""});
    else
      list.push_back({line.substr(0, eq), line.substr(eq + 1)});
  }
  return list;
}

std::string describe(const std::vector<peri::Override>& list) {
  std::string s;
  for (const peri::Override& o : list) s += "  --set '" + o.path + "=" + o.value + "'\n";
  return s;
}

// The emitted scene, or "" when the overrides are refused with InputError.
std::string read(const std::vector<peri::Override>& list) {
  try {
    return peri::emit_scene(peri::parse_scene(peri::default_scene_text(), "default.yaml", list));
  } catch (const peri::InputError& e) {
    if (std::string(e.what()).empty()) finding("InputError without a message for\n" + describe(list));
    return "";
  } catch (const std::exception& e) {
    finding(std::string("exception other than InputError: ") + e.what() + "\n" + describe(list));
  } catch (...) {
    finding("non-standard exception for\n" + describe(list));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::vector<peri::Override> list = overrides_of(std::string(reinterpret_cast<const char*>(data), size));
  const std::string emitted = read(list);
  if (emitted.empty()) return 0;
  if (read(list) != emitted) finding("the same overrides read twice give different scenes:\n" + describe(list));
  try {
    if (peri::emit_scene(peri::parse_scene(emitted, "emitted.yaml")) != emitted)
      finding("emit_scene does not round-trip:\n" + describe(list) + emitted);
  } catch (const peri::InputError& e) {
    finding(std::string("emitted scene refused: ") + e.what() + "\n" + describe(list) + emitted);
  }
  return 0;
}
