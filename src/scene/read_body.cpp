// The reader of a body (bodies.<name>): its kind and material, and the checks every kind shares;
// the keys of the kind are read by the kind's own module (scene/body_kind.hpp, src/geometry/kinds/).
#include <algorithm>

#include "peri/scene/models.hpp"
#include "readers.hpp"
#include "schema.hpp"

namespace peri::scene_detail {
namespace {

// The map's allowed keys: kind, material and every kind's keys (a key no kind takes is
// unknown); which of them are required depends on the kind and is checked once it is known.
Keys body_keys() {
  Keys keys = kBodyKeys;
  for (const BodyKind* kind : body_kinds())
    for (Key k : kind->keys)
      if (std::none_of(keys.begin(), keys.end(), [&](const Key& x) { return std::string(x.name) == k.name; })) {
        k.required = false;
        keys.push_back(k);
      }
  return keys;
}

bool takes(const BodyKind& kind, const std::string& key) {
  return std::any_of(kind.keys.begin(), kind.keys.end(), [&](const Key& k) { return key == k.name; });
}

// A key given that the body's kind does not take: named with the kind that takes it, if one does.
[[noreturn]] void refuse_key(const Value& value, const std::string& key, const BodyKind& kind) {
  std::vector<std::string> takers;
  for (const BodyKind* k : body_kinds())
    if (takes(*k, key)) takers.push_back(k->name);
  if (takers.size() == 1) value.fail("only a " + takers[0] + " body (kind: " + takers[0] + ") takes " + key);
  std::vector<std::string> own{"kind", "material"};
  for (const Key& k : kind.keys) own.emplace_back(k.name);
  value.fail("not used by a " + kind.name + " body (" + kind.summary + "); expected one of: " + join(own));
}

}  // namespace

Body read_body(const std::string& name, const Value& v, const std::vector<Material>& materials) {
  const Keys keys = body_keys();
  const Map m(v, &keys, "a map describing the body");
  Body b;
  b.name = name;
  b.where = m.where();
  b.kind = find_body_kind("membrane");
  if (auto x = m.get("kind")) {
    std::vector<std::pair<std::string, const BodyKind*>> choices;
    for (const BodyKind* k : body_kinds()) choices.emplace_back(k->name, k);
    b.kind = x->choice(choices);
  }
  const BodyKind& kind = *b.kind;

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
  if (kind.traits.lattice != find_material_model(mat.model)->lattice)
    material.fail(kind.traits.lattice
                      ? "a " + kind.name + " body needs a material with model: marder, got '" + b.material + "'"
                      : "material '" + b.material + "' has model: " + mat.model +
                            ", which needs a body with kind: lattice");

  for (const auto& [key, value] : m.items())
    if (key != "kind" && key != "material" && !takes(kind, key) && m.given(key)) refuse_key(value, key, kind);
  for (const Key& k : kind.keys)
    if (k.required && !m.given(k.name)) m.missing(k.name, k.what);
  kind.read(m, b, mat);
  return b;
}

}  // namespace peri::scene_detail
