// The registry of bond laws: the only list of them. Each entry is one law of models/laws/ with its
// calibration from a scene material (the stiffness per unit micromodulus in each kind of body,
// model.hpp's closed forms) and its kernels (make_law_entry). Laws added at run time
// (register_law: a test's own law) join the same table.
#include <algorithm>
#include <cmath>
#include <deque>

#include "peri/core/error.hpp"
#include "peri/kernels/law_kernels.hpp"
#include "peri/models/laws/membrane.hpp"
#include "peri/models/laws/membrane_hardening.hpp"
#include "peri/models/laws/pmb.hpp"
#include "peri/models/marder.hpp"
#include "peri/models/model.hpp"
#include "peri/scene/models.hpp"
#include "peri/scene/scene.hpp"

namespace peri {
namespace {

constexpr double kPi = 3.14159265358979323846;
using Derived = std::vector<std::pair<std::string, double>>;

bool in_plane(const BodyGeometry& g) { return g.traits.dimension == 2; }

// Shear modulus per unit micromodulus of the membrane law (eq. 19: pi h R) and of PMB bonds
// (membrane: pi h R3 / 8; solid: K = 2 pi R4 / 9 per unit c and mu = 3K/5).
double mu_per_c(bool membrane_law, const BodyGeometry& g, bool conical) {
  if (in_plane(g))
    return membrane_law ? kPi * g.thickness * influence_moment(1, g.horizon, conical)
                        : kPi * g.thickness * influence_moment(2, g.horizon, conical) / 8.0;
  return 0.6 * 2.0 * kPi * influence_moment(3, g.horizon, conical) / 9.0;
}

// Fibers (eq. 31, cross-section A, uniaxial): membrane law E = 8 A c R0, PMB E = A c R1.
double youngs_per_c_fiber(bool membrane_law, const BodyGeometry& g, bool conical) {
  return membrane_law ? 8.0 * g.area * influence_moment(0, g.horizon, conical)
                      : g.area * influence_moment(1, g.horizon, conical);
}

// The micromodulus of a stretch-based law from the material's one stiffness input.
// (Refused where it is not a usable double: check_micromodulus names the cause.)
double micromodulus(const Material& m, const BodyGeometry& g, const std::string& where, bool membrane_law,
                    bool conical) {
  if (m.micromodulus) return *m.micromodulus;
  if (g.traits.dimension == 1) {  // one modulus in 1D: the bar's E (a "bulk modulus" is read as E too)
    double e = 0;
    if (m.wave_speed) e = m.density * *m.wave_speed * *m.wave_speed;
    if (m.bulk_modulus) e = *m.bulk_modulus;
    if (m.youngs_modulus) e = *m.youngs_modulus;
    const double per_c = youngs_per_c_fiber(membrane_law, g, conical), c = e / per_c;
    check_micromodulus(m, g, where, e, per_c, c);
    return c;
  }
  const bool membrane = in_plane(g);
  double mu = 0;
  if (m.wave_speed) mu = m.density * *m.wave_speed * *m.wave_speed / 3.0;
  if (m.bulk_modulus) mu = membrane ? *m.bulk_modulus / 2.0 : 0.6 * *m.bulk_modulus;
  if (m.youngs_modulus) mu = membrane ? 3.0 * *m.youngs_modulus / 8.0 : 0.4 * *m.youngs_modulus;
  const double per_c = mu_per_c(membrane_law, g, conical), c = mu / per_c;
  check_micromodulus(m, g, where, mu, per_c, c);
  return c;
}

// critical_stretch (membrane: lambda_0; PMB: the strain s_0, + 1) and eq. (29)'s value at delta.
StretchFailure failure_of(const Material& m, double to_stretch) {
  StretchFailure f;
  if (!m.critical_stretch) return f;
  f.breaks = true;
  f.critical0 = *m.critical_stretch + to_stretch;
  f.critical_delta = m.critical_stretch_at_horizon ? *m.critical_stretch_at_horizon + to_stretch : f.critical0;
  return f;
}

template <class L>
ElasticConstants stretch_elastic(const L& law, bool membrane_law, const BodyGeometry& g, double density) {
  if (g.traits.dimension == 1) return isotropic_constants(law.c * youngs_per_c_fiber(membrane_law, g, law.conical), g, density);
  return isotropic_constants(law.c * mu_per_c(membrane_law, g, law.conical), g, density);
}

const LawEntry* entry_named(const char* name);

// Reference bond lengths are kept to 2^-46 relative: a smaller failure strain would break bonds
// at rest.
std::string strain_problem(double strain, const std::string& expected) {
  if (strain >= 1e-10) return "";
  return expected +
         " (a smaller failure strain is below the resolution of reference bond lengths and breaks bonds at rest)";
}

constexpr const char* kMembraneStability =
    "stiffens in compression by 1 + 3/lambda^4, so snapping-back fragments need a smaller safety_factor, e.g. 0.35";

// The membrane law, or with a hardening key the membrane law with eq. (16)'s term.
void calibrate_membrane(const Material& m, const BodyGeometry& g, const std::string& where, BondLaw& out) {
  if (g.traits.dimension == 3)
    throw InputError(where + ": material '" + m.name +
                     "' uses the membrane micropotential (eq. 13), which is defined for membrane "
                     "and fiber bodies only; expected model: pmb for a solid body");
  MembraneLaw law;
  law.horizon = g.horizon;
  law.conical = m.influence == Influence::Conical;
  law.c = micromodulus(m, g, where, true, law.conical);
  law.failure = failure_of(m, 0.0);
  if (m.hardening) {
    const MembraneHardeningLaw hard{law, m.hardening->coefficient, m.hardening->exponent};
    out = BondLaw(entry_named("membrane_hardening"), hard);
  } else {
    out = BondLaw(entry_named("membrane"), law);
  }
}

LawEntry membrane_entry() {
  LawEntry e = make_law_entry<MembraneLaw>(
      "membrane", "rubbery membrane micropotential, eqs. (13), (15); failure at lambda_0 (eqs. 11, 22, 29)");
  e.stability_note = kMembraneStability;
  e.material_keys = {"influence", "critical_stretch", "critical_stretch_at_horizon", "tip_advance", "tip_advance_tips", "hardening"};
  e.critical_problem = [](double x) -> std::string {
    if (!(x > 1)) return "the membrane model needs a critical stretch lambda_0 > 1";
    return strain_problem(x - 1, "expected a critical stretch lambda_0 >= 1 + 1e-10");
  };
  e.calibrate = calibrate_membrane;
  e.elastic = [](const void* c, const BodyGeometry& g, double density) {
    return stretch_elastic(*static_cast<const MembraneLaw*>(c), true, g, density);
  };
  e.derived = [](const void* c) { return Derived{{"micromodulus", static_cast<const MembraneLaw*>(c)->c}}; };
  return e;
}

LawEntry membrane_hardening_entry() {
  LawEntry e = make_law_entry<MembraneHardeningLaw>(
      "membrane_hardening", "the membrane micropotential with power-law hardening, eq. (16) (model membrane, key hardening)");
  e.stability_note = kMembraneStability;
  e.scene_model = false;  // model: membrane with a hardening key
  e.calibrate = calibrate_membrane;
  // At small strain eq. (16)'s term adds c' n (n - 1)/2 eps^2 g to the membrane law's 4 c eps^2 g:
  // the moduli of a membrane law with c + c' n (n - 1) / 8.
  e.elastic = [](const void* c, const BodyGeometry& g, double density) {
    const MembraneHardeningLaw& h = *static_cast<const MembraneHardeningLaw*>(c);
    MembraneLaw effective = h.base;
    effective.c += h.hard_c * h.hard_n * (h.hard_n - 1.0) / 8.0;
    return stretch_elastic(effective, true, g, density);
  };
  e.derived = [](const void* c) { return Derived{{"micromodulus", static_cast<const MembraneHardeningLaw*>(c)->base.c}}; };
  return e;
}

LawEntry pmb_entry() {
  LawEntry e = make_law_entry<PmbLaw>("pmb", "prototype microelastic brittle bonds: f = c s g, failure at the strain s_0");
  e.stability_note =
      "keeps its bond stiffness at any strain, so its bound holds throughout; look for a tool pressed in faster "
      "than the sheet can follow, or a load that moves nodes a large part of the spacing per step";
  e.material_keys = {"influence", "critical_stretch", "critical_stretch_at_horizon", "tip_advance", "tip_advance_tips"};
  e.critical_problem = [](double x) -> std::string {
    if (!(x > 0)) return "the pmb model needs a critical bond strain s_0 > 0";
    return strain_problem(x, "expected a critical bond strain s_0 >= 1e-10");
  };
  e.calibrate = [](const Material& m, const BodyGeometry& g, const std::string& where, BondLaw& out) {
    PmbLaw law;
    law.horizon = g.horizon;
    law.conical = m.influence == Influence::Conical;
    law.c = micromodulus(m, g, where, false, law.conical);
    law.failure = failure_of(m, 1.0);  // PMB's critical value is a strain s_0
    out = BondLaw(entry_named("pmb"), law);
  };
  e.elastic = [](const void* c, const BodyGeometry& g, double density) {
    return stretch_elastic(*static_cast<const PmbLaw*>(c), false, g, density);
  };
  e.derived = [](const void* c) { return Derived{{"micromodulus", static_cast<const PmbLaw*>(c)->c}}; };
  return e;
}

std::deque<LawEntry>& table() {
  static std::deque<LawEntry> laws = [] {
    std::deque<LawEntry> t;
    t.push_back(membrane_entry());
    t.push_back(membrane_hardening_entry());
    t.push_back(pmb_entry());
    return t;
  }();
  return laws;
}

MaterialModel model_of(const LawEntry& e) {
  MaterialModel m;
  m.name = e.name;
  m.description = e.description;
  m.keys = e.material_keys;
  m.stiffness = e.stiffness_keys;
  m.critical_problem = e.critical_problem;
  return m;
}

// The scene's catalog: the registry's scene models, then Marder's lattice (its own loop, not a
// bond law of the registry).
std::deque<MaterialModel>& catalog() {
  static std::deque<MaterialModel> models = [] {
    std::deque<MaterialModel> c;
    for (const LawEntry& e : table())
      if (e.scene_model) c.push_back(model_of(e));
    MaterialModel marder;
    marder.name = "marder";
    marder.description = "Marder's two- and three-body lattice law (lattice bodies), eqs. (28)-(33)";
    marder.lattice = true;
    marder.stiffness = {};
    marder.lattice_problem = [](const MarderParams& p, double spacing) {
      return marder_parameter_problem(p.a, p.b, spacing, p.cutoff, p.fracture_separation, p.options);
    };
    c.push_back(marder);
    return c;
  }();
  return models;
}

const LawEntry* entry_named(const char* name) { return find_law(name); }

}  // namespace

const LawEntry* find_law(const std::string& name) {
  for (const LawEntry& e : table())
    if (e.name == name) return &e;
  return nullptr;
}

void register_law(const LawEntry& entry) {
  if (find_law(entry.name) || find_material_model(entry.name))
    throw Error("register_law: a law named '" + entry.name + "' exists already");
  std::deque<MaterialModel>& models = catalog();  // (built from the table as it is before this entry)
  table().push_back(entry);
  if (entry.scene_model) models.push_back(model_of(entry));
}

const MaterialModel* find_material_model(const std::string& name) {
  for (const MaterialModel& m : catalog())
    if (m.name == name) return &m;
  return nullptr;
}

std::vector<std::string> material_model_names() {
  std::vector<std::string> names;
  for (const MaterialModel& m : catalog()) names.push_back(m.name);
  return names;
}

std::vector<const LawEntry*> registered_laws() {
  std::vector<const LawEntry*> all;
  for (const LawEntry& e : table()) all.push_back(&e);
  return all;
}

}  // namespace peri
