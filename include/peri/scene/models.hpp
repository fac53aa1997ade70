// The material models the scene reader accepts (`model:` of a material), as the reader needs to
// know them: which keys each takes and how its critical value is checked. The law registry
// provides this catalog (src/kernels/laws.cpp, from each law's entry), so the scene layer checks a
// material without including any law, and a law registered at run time is a model too.
#pragma once
#include <string>
#include <vector>

namespace peri {

struct MarderParams;

struct MaterialModel {
  std::string name;         ///< the value of `model:`
  std::string description;  ///< one line (--describe-keys, docs)
  /// Marder's lattice: its own keys (mooney_rivlin_a ...), and only lattice bodies take it.
  bool lattice = false;
  /// Which of the shared peridynamic keys it takes besides density and exactly one stiffness
  /// (wave_speed, bulk_modulus, youngs_modulus, micromodulus): influence, critical_stretch,
  /// critical_stretch_at_horizon, hardening.
  std::vector<std::string> keys;
  /// The stiffness inputs it can calibrate from (a subset of the four above).
  std::vector<std::string> stiffness;
  /// The check of a critical value (critical_stretch and critical_stretch_at_horizon): empty when x
  /// is acceptable, else what was expected ("the membrane model needs a critical stretch lambda_0
  /// > 1"), to which the reader adds the value it got.
  std::string (*critical_problem)(double x) = nullptr;
  /// A lattice model's check of its parameters at a body's lattice spacing [m]: empty when
  /// usable, else why not (the reader names the body, the material and the values).
  std::string (*lattice_problem)(const MarderParams& p, double spacing) = nullptr;
};

/// The model of that name, or nullptr (defined by the law registry).
const MaterialModel* find_material_model(const std::string& name);
/// Every model's name, in the registry's order.
std::vector<std::string> material_model_names();

}  // namespace peri
