// Fuzz target: the scene reader and validator (libFuzzer entry point; replay.cpp drives it from
// ctest). Any input must either give a Scene or throw peri::InputError; an accepted scene must
// round-trip through emit_scene, get a finite size estimate, and (when small) discretize and
// calibrate or be refused with InputError. Anything else (crash, other exception, round-trip
// mismatch) aborts: a finding.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "peri/geometry/discretization.hpp"
#include "peri/core/error.hpp"
#include "peri/models/model.hpp"
#include "peri/scene/scene.hpp"

namespace {

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "fuzz_scene finding: %s\n", what.c_str());
  std::abort();
}

void exercise(const std::string& text) {
  peri::Scene s;
  try {
    s = peri::parse_scene(text, "fuzz.yaml");
  } catch (const peri::InputError&) {
    return;  // refused with a message: the expected outcome for most inputs
  }
  const std::string emitted = peri::emit_scene(s);
  try {
    if (peri::emit_scene(peri::parse_scene(emitted, "emitted.yaml")) != emitted)
      finding("emit_scene does not round-trip:\n" + emitted);
  } catch (const peri::InputError& e) {
    finding(std::string("emitted scene refused: ") + e.what() + "\n" + emitted);
  }
  const peri::SizeEstimate e = peri::estimate_size(s);
  if (!(e.nodes >= 1) || !(e.bonds >= 0) || !(e.bytes > 0)) finding("size estimate not positive");
  if (e.nodes > 4000 || e.bonds > 4e5) return;  // the resources check refuses or allows big ones
  try {
    const peri::Nodes nodes = peri::discretize(s);
    for (const peri::Boundary& b : s.boundaries) peri::select_nodes(nodes, s, b.region, b.name);
    for (std::size_t b = 0; b < s.bodies.size(); ++b)
      peri::calibrate(s.material(s.bodies[b].material), nodes.bodies[b], s.bodies[b].name);
  } catch (const peri::InputError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  exercise(std::string(reinterpret_cast<const char*>(data), size));
  return 0;
}
