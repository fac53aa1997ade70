// The scene's keys as documentation, from the reader's own schema: every key of every map the
// reader accepts (the key tables of src/scene/schema.hpp and of the body kinds' modules) with its
// unit, default and meaning, the material models of the law registry's catalog (scene/models.hpp)
// and the body kinds of the kind registry (scene/body_kind.hpp). `peridrive --describe-keys
// [--format markdown|text]` prints it; the Markdown form is the generated part of
// docs/user/scene-reference.md, which the ctest `scene_reference` compares with it.
#pragma once
#include <string>
#include <vector>

namespace peri {

/// One key of a scene map as the reader's schema documents it.
struct KeyDoc {
  std::string name;
  bool required = false;
  std::string unit;      ///< SI unit; empty for numbers without one, words and maps
  std::string fallback;  ///< what an absent key means (the default); empty: no value
  std::string meaning;   ///< what it is and the values it takes
};

/// The keys of one scene map: `path` names the map as --set does, with <name> for a free key
/// and [i] for a list entry ("bodies.<name>.network", "stages[i]"); `condition` says when these
/// keys apply ("model: membrane, pmb", "kind: dynamic"); empty: always.
struct KeySection {
  std::string path;
  std::string condition;
  std::vector<KeyDoc> keys;
};

/// A material model of the catalog, for the table of `model:` values.
struct ModelDoc {
  std::string name;
  std::string meaning;
  std::vector<std::string> stiffness;  ///< the stiffness keys it calibrates from
};

/// A body kind of the registry, for the table of `kind:` values.
struct KindDoc {
  std::string name;
  std::string meaning;
};

/// Every map of a scene, in the order of a scene file (defined beside the key tables, in
/// src/scene/schema.cpp).
std::vector<KeySection> scene_key_sections();
/// The material models the reader accepts, in the catalog's order.
std::vector<ModelDoc> scene_model_docs();
/// The body kinds the reader accepts, in the registry's order.
std::vector<KindDoc> scene_kind_docs();

enum class KeyFormat { Markdown, Text };

/// The whole description. Throws peri::Error naming a key that has no meaning in the schema.
std::string describe_scene_keys(KeyFormat format);

}  // namespace peri
