// The registry of body kinds by name: the built-in kinds (kinds/), then any a program adds with
// register_body_kind. The only list of body kinds.
#include <deque>

#include "kinds/kinds.hpp"
#include "peri/core/error.hpp"

namespace peri {
namespace {

std::deque<BodyKind>& registry() {  // a deque: entries never move (bodies point at them)
  static std::deque<BodyKind> kinds = {kinds::membrane_kind(), kinds::solid_kind(), kinds::lattice_kind(),
                                       kinds::fiber_kind(), kinds::sphere_kind()};
  return kinds;
}

}  // namespace

const BodyKind* find_body_kind(const std::string& name) {
  for (const BodyKind& k : registry())
    if (k.name == name) return &k;
  return nullptr;
}

std::vector<const BodyKind*> body_kinds() {
  std::vector<const BodyKind*> out;
  for (const BodyKind& k : registry()) out.push_back(&k);
  return out;
}

void register_body_kind(const BodyKind& kind) {
  if (find_body_kind(kind.name)) throw Error("register_body_kind: a body kind named '" + kind.name + "' exists already");
  if (!kind.read || !kind.emit || !kind.measure_keys || !kind.node_estimate || !kind.family_estimate || !kind.discretize)
    throw Error("register_body_kind: body kind '" + kind.name + "' lacks one of its functions");
  registry().push_back(kind);
}

}  // namespace peri
