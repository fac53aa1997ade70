// A bond law at run time: the constants of one law of models/laws/ (a small struct of pure
// functions, written once for double and for SIMD packs) held by value, with the law's entry in
// the registry: its name and the functions instantiated for it (kernels/law_kernels.hpp). The
// registry of laws by name is the only list of bond laws: the scene's `model:` names an entry,
// calibration, the bond loops and the SNES tangent reach the law through it.
#pragma once
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <new>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace peri {

struct BondView;
struct RowBlocks;
struct BondTally;
struct BodyGeometry;
struct Material;

/// Small-strain constants of a calibrated law in a body (isotropic).
struct ElasticConstants {
  double mu = 0;           ///< shear modulus [Pa]
  double bulk = 0;         ///< K: in-plane lambda+mu (membranes), 3D bulk (solids), E (fibers) [Pa]
  double youngs = 0;       ///< E [Pa]
  double c_longitudinal = 0, c_shear = 0, c_rayleigh = 0;  ///< wave speeds [m/s]
};

class BondLaw;

/// What the registry holds for one bond law. The function pointers receive the law's constants
/// (BondLaw::constants()); make_law_entry<L> (kernels/law_kernels.hpp) fills them from the law's
/// one definition.
struct LawEntry {
  std::string name;
  std::string description;  ///< one line for --describe-keys and the docs
  bool vectorized = false;  ///< the bond loop's SIMD path serves it (else the portable walk)
  /// Values the law keeps per ordered bond (its kHistory: e.g. the largest stretch reached),
  /// zero at the start, changed only by the force passes that commit (explicit steps, quasi-static
  /// break passes) and kept in checkpoints; 0: none.
  int history = 0;
  /// What an unstable explicit step means for this law, completing "the <name> law (body ...) ":
  /// the instability messages' likely cause.
  std::string stability_note;
  // The scene's view (scene/models.hpp): whether `model: <name>` selects it (a law reached through
  // another, as hardening through the membrane's `hardening` key, is not), the material keys it
  // takes besides density and one stiffness input, the stiffness inputs it calibrates from, and
  // the check of its critical value (empty when acceptable, else what was expected).
  bool scene_model = true;
  std::vector<std::string> material_keys;
  std::vector<std::string> stiffness_keys{"wave_speed", "bulk_modulus", "youngs_modulus", "micromodulus"};
  std::string (*critical_problem)(double x) = nullptr;
  // One bond, per unit quadrature measure (the tangent, tests, closed-form checks):
  double (*coefficient)(const void* law, double xi2, double y2) = nullptr;  ///< f / y [N/m^7]
  double (*slope)(const void* law, double xi2, double y2) = nullptr;        ///< d(f/y)/d(y^2)
  double (*energy)(const void* law, double xi2, double y2) = nullptr;       ///< micropotential w [J/m^6]
  bool (*broken_at)(const void* law, double xi2, double y2) = nullptr;      ///< failure test
  double (*critical_energy)(const void* law, double xi2) = nullptr;         ///< w at failure
  double (*reference_stiffness)(const void* law, double xi2) = nullptr;     ///< df/dy at y = |xi|
  void (*make_intact)(void* law) = nullptr;  ///< the same law with failure switched off
  // Calibration: from a material (scene) in a body to the law's constants, and back.
  void (*calibrate)(const Material&, const BodyGeometry&, const std::string& where, BondLaw& out) = nullptr;
  ElasticConstants (*elastic)(const void* law, const BodyGeometry&, double density) = nullptr;
  /// The law's derived constants worth reporting (summary.json, the resolved scene), e.g. the
  /// micromodulus.
  std::vector<std::pair<std::string, double>> (*derived)(const void* law) = nullptr;
  // Loops over bonds (kernels/forces.hpp's entry points dispatch here).
  void (*forces)(const void* law, const BondView&, const RowBlocks&, double* force, bool with_energy,
                 BondTally&) = nullptr;
  /// The same as `forces` on the portable walk alone (tests compare the two: the same bits).
  void (*portable_forces)(const void* law, const BondView&, const RowBlocks&, double* force, bool with_energy,
                          BondTally&) = nullptr;
  double (*energy_sum)(const void* law, const BondView&, const std::int32_t* rows, std::size_t n,
                       double* density) = nullptr;
  void (*row_tangent)(const void* law, const BondView&, std::int32_t row, std::vector<std::int32_t>& cols,
                      std::vector<double>& blocks) = nullptr;
};

/// The constants of one registered law, by value (copyable; at most kStorage bytes).
class BondLaw {
 public:
  static constexpr std::size_t kStorage = 96;
  BondLaw() = default;
  /// Law L's constants under its registry entry (L: a law of models/laws/, with delta() and breaks()).
  template <class L>
  BondLaw(const LawEntry* entry, const L& constants)
      : entry_(entry), horizon_(constants.delta()), breaks_(constants.breaks()) {
    static_assert(sizeof(L) <= kStorage && alignof(L) <= alignof(std::max_align_t));
    static_assert(std::is_trivially_copyable_v<L>);
    std::memcpy(storage_, &constants, sizeof(L));
  }
  bool empty() const { return entry_ == nullptr; }
  const LawEntry& entry() const { return *entry_; }
  const std::string& name() const { return entry_->name; }
  const void* constants() const { return storage_; }
  /// The constants as law L (the caller knows the law, e.g. from name()).
  template <class L>
  const L& as() const { return *std::launder(reinterpret_cast<const L*>(storage_)); }
  double horizon() const { return horizon_; }
  bool breaks() const { return breaks_; }
  /// The same law whose bonds never fail (quasi-static residuals and tangents).
  BondLaw intact() const {
    BondLaw b = *this;
    b.entry_->make_intact(b.storage_);
    b.breaks_ = false;
    return b;
  }
  double coefficient(double xi2, double y2) const { return entry_->coefficient(storage_, xi2, y2); }
  double slope(double xi2, double y2) const { return entry_->slope(storage_, xi2, y2); }
  double energy(double xi2, double y2) const { return entry_->energy(storage_, xi2, y2); }
  bool broken_at(double xi2, double y2) const { return entry_->broken_at(storage_, xi2, y2); }
  double critical_energy(double xi2) const { return entry_->critical_energy(storage_, xi2); }
  double reference_stiffness(double xi2) const { return entry_->reference_stiffness(storage_, xi2); }
  std::vector<std::pair<std::string, double>> derived() const { return entry_->derived(storage_); }
  /// One derived constant by name (e.g. "micromodulus"); NaN if the law has none by that name.
  double derived(const std::string& key) const {
    for (const auto& [k, value] : derived())
      if (k == key) return value;
    return NAN;
  }

 private:
  const LawEntry* entry_ = nullptr;
  double horizon_ = 0;
  bool breaks_ = false;
  alignas(std::max_align_t) unsigned char storage_[kStorage] = {};
};

/// Law L's constants under the registered law `name` (Error if none is registered).
template <class L>
BondLaw make_bond_law(const std::string& name, const L& constants);

/// The registry of bond laws by name: the built-in laws (kernels/laws.cpp), and any added with
/// register_law (a test's own law). Not thread-safe: register before runs start.
const LawEntry* find_law(const std::string& name);
void register_law(const LawEntry& entry);
std::vector<const LawEntry*> registered_laws();

template <class L>
BondLaw make_bond_law(const std::string& name, const L& constants) {
  const LawEntry* entry = find_law(name);
  if (!entry) throw std::invalid_argument("no bond law named '" + name + "' is registered");
  return BondLaw(entry, constants);
}

}  // namespace peri
