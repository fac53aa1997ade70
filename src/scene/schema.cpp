// The schema's enum names and default entry names (schema.hpp), and the key tables as
// documentation (scene/describe.hpp).
#include "schema.hpp"

#include <functional>

#include "peri/scene/describe.hpp"
#include "peri/scene/models.hpp"

namespace peri::scene_detail {

const char* to_text(Influence k) { return k == Influence::Constant ? "constant" : "conical"; }
const char* to_text(PairKind k) {
  return k == PairKind::AdjacentSegments ? "adjacent_segments"
         : k == PairKind::DistantSegments ? "distant_segments"
         : k == PairKind::OtherFibers     ? "other_fibers"
                                          : "segments";
}
const char* to_text(Grid k) { return k == Grid::Square ? "square" : "hexagonal"; }
const char* to_text(Quadrature k) {
  return k == Quadrature::Full ? "full" : k == Quadrature::Taper ? "taper" : "partial_area";
}
const char* to_text(StageKind k) {
  return k == StageKind::Dynamic ? "dynamic" : k == StageKind::QuasiStatic ? "quasistatic" : "release";
}
const char* to_text(bool b) { return b ? "true" : "false"; }

/// Prefix of the default names of a list's unnamed entries ("crack0", "stage1"); empty when the
/// entries have no default name.
std::string default_name_prefix(const std::string& list_path) {
  if (list_path == "cracks") return "crack";
  if (list_path == "stages") return "stage";
  return "";
}

}  // namespace peri::scene_detail

namespace peri {
namespace {

using namespace scene_detail;

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
    const bool takes = key == "model" || key == "density" || key == "kelvin_viscosity" ||
                       (m.lattice ? marder_key
                                  : std::find(m.keys.begin(), m.keys.end(), key) != m.keys.end() ||
                                        std::find(m.stiffness.begin(), m.stiffness.end(), key) != m.stiffness.end());
    if (takes) takers.push_back(name);
  }
  return takers;
}

}  // namespace

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
  // Body keys: kind and material, then each kind's own (its module's table) and its nested maps.
  out.push_back({"bodies.<name>", "", key_docs(kBodyKeys)});
  for (const BodyKind* kind : body_kinds()) {
    out.push_back({"bodies.<name>", "kind: " + kind->name, key_docs(kind->keys)});
    for (const auto& [key, keys] : kind->nested)
      out.push_back({"bodies.<name>." + key, "kind: " + kind->name, key_docs(*keys)});
  }
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
  out.push_back({"output.region", "", key_docs(kBoxKeys)});
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

std::vector<KindDoc> scene_kind_docs() {
  std::vector<KindDoc> out;
  for (const BodyKind* k : body_kinds()) out.push_back({k->name, k->summary});
  return out;
}

}  // namespace peri
