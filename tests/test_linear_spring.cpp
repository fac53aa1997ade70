// A bond law defined in this file alone: linear springs, f = c (y - |xi|), registered at run time
// and run through everything a built-in law is (docs/developer/adding-a-law.md follows this file):
//  - the checks of every registered law (tests/law_checks.hpp): SIMD and portable loops the same
//    bits, gradient and slope, the SNES tangent's rows, calibration against the continuum energy;
//  - the scene: `model: linear_spring` with the keys its entry lists, others refused by name;
//  - a dynamic run of a stretching, breaking sheet: the energy balance (eq. 5's strain energy,
//    kinetic energy, and the critical energies of the broken bonds as dissipation);
//  - the SNES tangent the quasi-static solver assembles (Simulation::add_tangent) against central
//    differences of the internal forces, on every rank of the run, and a quasi-static preload.
// Run under MPI at 1 and 2 ranks.
#include <gtest/gtest.h>
#include <petscmat.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "law_checks.hpp"
#include "mpi_test.hpp"
#include "peri/core/petsc.hpp"
#include "peri/kernels/law_kernels.hpp"
#include "peri/models/laws/bond_lanes.hpp"
#include "peri/scene/models.hpp"
#include "peri/stages/simulation.hpp"

namespace peri {
namespace {

// ------------------------------------------------------------------------------------------------
// The law: one bond's scalar force f = c (y - |xi|) [N/m^6 with c in N/m^7], micropotential
// w = c (y - |xi|)^2 / 2, failure at y >= lambda_0 |xi|. Per bond, over the row factor c:
//   coefficient = f w V / (c y) = w V (1 - |xi| / y),
// with w V and w V |xi| per slot, 1/y by simd::Root; d coefficient / d(y^2) = w V |xi| / (2 y^3).

struct LinearSpringLaw {
  double c = 0;        ///< spring constant per unit measure [N/m^7]
  double horizon = 0;  ///< delta [m]
  StretchFailure failure;

  double delta() const noexcept { return horizon; }
  bool breaks() const noexcept { return failure.breaks; }
  /// w at y = lambda_0 |xi|, per unit measure.
  double critical_energy(double xi2) const noexcept {
    const double s = failure.critical0 - 1.0;
    return 0.5 * c * s * s * xi2;
  }
  /// d f / dy at the reference state (stable step).
  double reference_stiffness(double) const noexcept { return c; }

  static constexpr bool kVectorized = true;
  template <class P, class Shape, bool Energy>
  struct Lanes {
    using Pack = P;
    using V = typename P::V;
    using M = typename P::M;
    static constexpr int W = P::W;
    static constexpr bool kEnergy = Energy;
    enum { kFloor, kBreak, kWeight, kWeightXi, kXiLen, kEnergyWeight, kSlots };
    using Bonds = BondLanes<P, Energy ? kSlots : kXiLen>;  // (the energy's slots last)
    static constexpr bool kSlotValues = true;
    double c_row, crit_s, c_energy_s;
    simd::Root<P> root;
    explicit Lanes(const LinearSpringLaw& L) : c_row(L.c), crit_s(L.failure.critical0), c_energy_s(0.5 * L.c) {}
    double row_factor() const { return c_row; }
    static const void* slot_tag() { return &Lanes<simd::Scalar, Shape, false>::slot_tag_storage; }
    static inline const char slot_tag_storage = 0;
    std::array<double, 4> slot_key() const { return {crit_s, c_energy_s, 0.0, 0.0}; }

    /// Per-slot constants: 1e-12 |xi|^2 (coincident nodes), (lambda_0 |xi|)^2, w V, w V |xi|, |xi|
    /// and (c/2) w V (energy).
    template <class Q>
    void slot_values(typename Q::V xi2, typename Q::V inv_xi, typename Q::V measure, typename Q::V,
                     typename Q::V* out) const {
      const typename Q::V xi = Q::mul(xi2, inv_xi);
      out[kFloor] = Q::mul(Q::set1(1e-12), xi2);
      out[kBreak] = Q::mul(Q::set1(crit_s * crit_s), xi2);
      out[kWeight] = measure;
      out[kWeightXi] = Q::mul(measure, xi);
      out[kXiLen] = xi;
      out[kEnergyWeight] = Q::mul(Q::set1(c_energy_s), measure);
    }
    struct Front {
      V y2, y2g, r;
    };
    Front front(const Bonds& b, V y2) const {
      Front p;
      p.y2 = y2;
      p.y2g = P::max(y2, b.slot[kFloor]);
      p.r = root.front(p.y2g);
      return p;
    }
    V coefficient(const Bonds& b, const Front& p, V& w, unsigned& fresh) const {
      const M reached = P::ge(p.y2g, b.slot[kBreak]);
      fresh = P::bits(reached) & ~b.dead & ((1u << W) - 1u);
      const M dead = P::with_lanes(reached, b.dead);
      V y, inv_y;
      root.finish(p.y2g, p.r, y, inv_y);
      const V coef = P::fnmadd_or_zero(dead, b.slot[kWeightXi], inv_y, b.slot[kWeight]);  // w V (1 - |xi|/y)
      if constexpr (Energy) {
        const V stretch = P::sub(y, b.slot[kXiLen]);
        w = P::add(w, P::zero_where(dead, P::mul(b.slot[kEnergyWeight], P::mul(stretch, stretch))));
      }
      return coef;
    }
    V slope(const Bonds& b, const Front& p) const {
      V y, inv_y;
      root.finish(p.y2g, p.r, y, inv_y);
      return P::mul(P::mul(P::set1(0.5), b.slot[kWeightXi]), P::mul(inv_y, P::mul(inv_y, inv_y)));
    }
  };
  template <class F>
  decltype(auto) visit_shape(F&& f) const { return f(StretchShape<false, false>{}); }
  void make_intact() { failure = StretchFailure{}; }
};

// Calibration. A homogeneous strain e stretches every bond by e |xi|: w = c e^2 |xi|^2 / 2, and
// the energy density sum (eq. 5) over a full family gives, with R_k = int_0^delta xi^k dxi,
//   membrane (thickness h): W = pi h c R_3 e^2 / 2 per unit equibiaxial e = 2 K e^2, K = 2 mu;
//   solid:                  W = pi c R_4 e^2 = 9 K e^2 / 2, mu = 3 K / 5;
//   fiber (section A):      W = A c R_2 e^2 / 2 = E e^2 / 2.
double mu_or_e_per_c(const BodyGeometry& g) {
  const double pi = 3.14159265358979323846;
  switch (g.traits.dimension) {
    case 1: return g.area * influence_moment(2, g.horizon, false);
    case 3: return 0.6 * 2.0 * pi * influence_moment(4, g.horizon, false) / 9.0;
    default: return pi * g.thickness * influence_moment(3, g.horizon, false) / 8.0;
  }
}

LawEntry linear_spring_entry() {
  LawEntry e = make_law_entry<LinearSpringLaw>("linear_spring", "linear springs f = c (y - |xi|) (a test's law)");
  e.stability_note = "keeps its spring constant at any stretch; look for a load that outruns the body";
  e.material_keys = {"critical_stretch"};
  e.stiffness_keys = {"micromodulus", "bulk_modulus"};
  e.critical_problem = [](double x) -> std::string {
    return x > 1 ? "" : "the linear_spring model needs a critical stretch lambda_0 > 1";
  };
  e.calibrate = [](const Material& m, const BodyGeometry& g, const std::string& where, BondLaw& out) {
    LinearSpringLaw law;
    law.horizon = g.horizon;
    if (m.micromodulus) {
      law.c = *m.micromodulus;
    } else {  // bulk_modulus: in-plane K = 2 mu (membranes), 3D K = 5 mu / 3, a fiber's E
      const double k = *m.bulk_modulus;
      const double modulus = g.traits.dimension == 1 ? k : g.traits.dimension == 3 ? 0.6 * k : 0.5 * k;
      const double per_c = mu_or_e_per_c(g);
      law.c = modulus / per_c;
      check_micromodulus(m, g, where, modulus, per_c, law.c);
    }
    if (m.critical_stretch) law.failure = StretchFailure{true, *m.critical_stretch, *m.critical_stretch};
    out = BondLaw(find_law("linear_spring"), law);
  };
  e.elastic = [](const void* law, const BodyGeometry& g, double density) {
    return isotropic_constants(static_cast<const LinearSpringLaw*>(law)->c * mu_or_e_per_c(g), g, density);
  };
  e.derived = [](const void* law) {
    return std::vector<std::pair<std::string, double>>{{"micromodulus", static_cast<const LinearSpringLaw*>(law)->c}};
  };
  return e;
}

// Registered before main() runs, as a test's own law.
const bool kRegistered = (register_law(linear_spring_entry()), true);

const law_checks::Sample kSample{
    "linear_spring", "model: linear_spring, density: 1000, bulk_modulus: 1.0e9, critical_stretch: 1.004", ""};

RunOptions quiet() {
  RunOptions o;
  o.quiet = true;
  return o;
}

// ------------------------------------------------------------------------------------------------

TEST(LinearSpring, IsRegisteredAsALawAndASceneModel) {
  ASSERT_TRUE(kRegistered);
  ASSERT_NE(find_law("linear_spring"), nullptr);
  const std::vector<std::string> models = material_model_names();
  EXPECT_NE(std::find(models.begin(), models.end(), "linear_spring"), models.end());
  EXPECT_EQ(std::count(models.begin(), models.end(), "linear_spring"), 1);
}

TEST(LinearSpring, PassesTheChecksOfEveryLaw) {
  law_checks::simd_and_portable_loops_give_the_same_bits(kSample);
  law_checks::coefficient_is_the_energy_gradient_and_slope_its_derivative(kSample);
  law_checks::tangent_row_is_the_derivative_of_the_forces(kSample);
  law_checks::calibration_stores_the_continuum_energy(kSample);
}

// The scene takes the keys the registry entry lists and refuses the others by name, and the
// resolved scene reads back to the same law.
TEST(LinearSpring, SceneTakesItsKeysAndRefusesOthers) {
  const std::string text = law_checks::scene_text(kSample.material, false);
  const Scene scene = parse_scene(text, "spring.yaml");
  ASSERT_EQ(scene.materials.at(0).model, "linear_spring");
  const Nodes nodes = discretize(scene);
  const BondLaw law = calibrate(scene.materials[0], nodes.bodies[0], "spring.yaml");
  EXPECT_EQ(law.name(), "linear_spring");
  // K = 2 mu = pi h c delta^4 / 16 for a membrane (R_3 = delta^4 / 4)
  const BodyGeometry& g = nodes.bodies[0];
  const double pi = 3.14159265358979323846, delta = g.horizon;
  EXPECT_NEAR(law.derived("micromodulus") * pi * g.thickness * std::pow(delta, 4) / 16.0 / 1.0e9, 1.0, 1e-12);
  const Scene again = parse_scene(emit_scene(scene), "resolved.yaml");
  EXPECT_EQ(calibrate(again.materials[0], discretize(again).bodies[0], "resolved.yaml").derived("micromodulus"),
            law.derived("micromodulus"));

  auto refusal = [](const std::string& material) {
    try {
      parse_scene(law_checks::scene_text(material, false), "spring.yaml");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string base = "model: linear_spring, density: 1000";
  EXPECT_NE(refusal(base + ", youngs_modulus: 1.0e9").find("youngs_modulus"), std::string::npos)
      << refusal(base + ", youngs_modulus: 1.0e9");
  EXPECT_NE(refusal(base + ", micromodulus: 1.0e20, influence: conical").find("influence"), std::string::npos)
      << refusal(base + ", micromodulus: 1.0e20, influence: conical");
  EXPECT_NE(refusal(base + ", micromodulus: 1.0e20, critical_stretch: 0.9").find("lambda_0 > 1"), std::string::npos)
      << refusal(base + ", micromodulus: 1.0e20, critical_stretch: 0.9");
  EXPECT_EQ(refusal(base + ", micromodulus: 1.0e20"), "accepted");
}

// A slit sheet pulled apart by its top and bottom bands (20 m/s each way, from 10% strain
// and the matching velocity field), seeded with wrinkles. The strain and kinetic energies, the
// broken bonds' critical energies (dissipated) and the bands' work keep the initial total: to
// the Verlet scheme's O(dt^2) while the springs hold, and with lambda_0 = 1.15 within the energy
// a bond gains beyond lambda_0 in its last step as the slit runs (the booking of every law).
std::string stretching_sheet(const std::string& safety_factor, bool breaking) {
  return std::string(R"(
name: spring-sheet
materials:
  springs: {model: linear_spring, density: 1200, bulk_modulus: 1.2e9)") +
         (breaking ? ", critical_stretch: 1.15" : "") + R"(}
bodies:
  sheet: {material: springs, origin: [-0.01, -0.01, 0], size: [0.02, 0.02], thickness: 0.0005, spacing: 0.0005}
cracks:
  - {name: slit, from: [-0.003, 0, 0], to: [0.003, 0, 0]}
boundaries:
  - {name: top, region: {min: [-1, 0.0088, -1], max: [1, 1, 1]}, velocity: [0, 20, 0]}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0088, 1]}, velocity: [0, -20, 0]}
initial:
  displacement_gradient: [[0, 0, 0], [0, 0.1, 0], [0, 0, 0]]
  velocity_gradient: [[0, 0, 0], [0, 2000, 0], [0, 0, 0]]
  seed: {amplitude: 1.0e-6, wavelength: [0.004, 0.004]}
stages:
  - {name: pull, duration: 6.0e-5, safety_factor: )" + safety_factor + R"(}
output: {frames: 1, series_every: 10}
)";
}

RunSummary pull(const std::string& safety_factor, bool breaking) {
  Simulation sim(parse_scene(stretching_sheet(safety_factor, breaking), "spring-sheet"), PETSC_COMM_WORLD, quiet());
  sim.run();
  const RunSummary& s = sim.summary();
  const EnergyRow& e = s.final_energy;
  if (world_rank() == 0)
    std::printf("linear_spring sheet, safety factor %s%s: %lld steps, %lld bonds broken, kinetic %.4e J, strain %.4e J, "
                "dissipated %.4e J, energy balance error %.2e\n",
                safety_factor.c_str(), breaking ? ", breaking" : "", static_cast<long long>(s.steps),
                static_cast<long long>(e.broken_bonds), e.kinetic, e.strain, e.dissipated, s.energy_balance_error);
  return s;
}

TEST(LinearSpring, DynamicRunBalancesEnergy) {
  // Intact: the balance error is the Verlet scheme's, second order in dt.
  const RunSummary coarse = pull("0.7", false), fine = pull("0.35", false);
  EXPECT_EQ(coarse.final_energy.dissipated, 0.0);
  EXPECT_GT(coarse.final_energy.strain, 0.0);
  EXPECT_LT(coarse.energy_balance_error, 1e-3);
  const double order = std::log2(coarse.energy_balance_error / fine.energy_balance_error);
  if (world_rank() == 0) std::printf("linear_spring energy balance: order %.3f in dt\n", order);
  EXPECT_NEAR(order, 2.0, 0.25);
  // Breaking: the slit runs; the broken bonds' critical energies close the balance.
  const RunSummary breaking = pull("0.7", true);
  EXPECT_GT(breaking.final_energy.broken_bonds, 5 * breaking.precrack_bonds) << "the failure path went untested";
  EXPECT_GT(breaking.final_energy.dissipated, 0.1 * breaking.final_energy.strain);
  EXPECT_LT(breaking.energy_balance_error, 1e-2);
}

// The tangent the quasi-static solver assembles, K = -d(V F)/du, against central differences of
// Simulation::internal_force, column by column over every rank's unknowns, at a deformed state.
const char* kSmallSheet = R"(
name: spring-tangent
materials:
  springs: {model: linear_spring, density: 1000, bulk_modulus: 1.0e9}
bodies:
  sheet: {material: springs, origin: [0, 0, 0], size: [0.006, 0.005], thickness: 0.0005, spacing: 0.0005}
stages:
  - {name: none, steps: 1}
)";

TEST(LinearSpring, SnesTangentIsTheDerivativeOfTheInternalForce) {
  Simulation sim(parse_scene(kSmallSheet, "spring-tangent"), PETSC_COMM_WORLD, quiet());
  const Domain& d = sim.domain();
  const std::int32_t owned = d.owned;
  const std::size_t n3 = 3 * static_cast<std::size_t>(owned);
  std::mt19937 rng(17 + world_rank());
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<double> u(n3);
  for (std::int32_t i = 0; i < owned; ++i) {
    u[3 * i] = 0.1 * d.X[3 * i] + 2e-5 * U(rng);
    u[3 * i + 1] = -0.05 * d.X[3 * i + 1] + 2e-5 * U(rng);
    u[3 * i + 2] = 2e-5 * U(rng);
  }
  sim.set_displacement(u.data());

  OwnedMat J;
  PERI_PETSC(MatCreate(PETSC_COMM_WORLD, J.out()));
  MatSetSizes(J, static_cast<PetscInt>(n3), static_cast<PetscInt>(n3), PETSC_DETERMINE, PETSC_DETERMINE);
  MatSetBlockSize(J, 3);
  MatSetType(J, MATAIJ);
  MatSetUp(J);
  MatSetOption(J, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE);
  DofLayout layout;  // all 3 components of every node, in the domain's global numbering
  layout.block.assign(d.global.begin(), d.global.end());
  sim.add_tangent(J, layout);
  MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY);
  MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY);
  PetscInt first = 0, last = 0, total = 0;
  MatGetOwnershipRange(J, &first, &last);
  MatGetSize(J, &total, nullptr);
  ASSERT_EQ(last - first, static_cast<PetscInt>(n3));

  // This rank's global unknowns, in the numbering add_tangent uses (domain.global).
  std::vector<PetscInt> rows(n3);
  for (std::int32_t i = 0; i < owned; ++i)
    for (int c = 0; c < 3; ++c) rows[3 * i + c] = 3 * static_cast<PetscInt>(d.global[i]) + c;

  const double h = 1e-9;
  std::vector<double> fp(n3), fm(n3), column(n3);
  double worst = 0, largest = 0;
  for (PetscInt col = 0; col < total; ++col) {
    auto force_at = [&](double shift, std::vector<double>& f) {
      std::vector<double> v = u;
      for (std::size_t k = 0; k < n3; ++k)
        if (rows[k] == col) v[k] += shift;
      sim.set_displacement(v.data());
      sim.internal_force(f.data());
    };
    force_at(h, fp);
    force_at(-h, fm);
    MatGetValues(J, static_cast<PetscInt>(n3), rows.data(), 1, &col, column.data());
    for (std::size_t k = 0; k < n3; ++k) {
      const double fd = -(fp[k] - fm[k]) / (2 * h);
      worst = std::max(worst, std::fabs(column[k] - fd));
      largest = std::max(largest, std::fabs(column[k]));
    }
  }
  double global_worst = 0, global_largest = 0;
  MPI_Allreduce(&worst, &global_worst, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
  MPI_Allreduce(&largest, &global_largest, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
  if (world_rank() == 0)
    std::printf("linear_spring tangent: %lld unknowns, largest entry %.4e, worst difference to central differences "
                "%.3e\n",
                static_cast<long long>(total), global_largest, global_worst);
  EXPECT_GT(global_largest, 0.0);
  EXPECT_LT(global_worst, 1e-6 * global_largest);
}

// SNES with that tangent: an equibiaxial preload of a frame to lambda = 1.5. Every interior node
// has its full family, so the discrete equilibrium is affine; the springs then hold
// W = 2 K (lambda - 1)^2 per unit volume exactly (w depends on y - |xi| only), and the support
// work equals the stored energy.
const char* kFrame = R"(
name: spring-frame
materials:
  springs: {model: linear_spring, density: 1000, bulk_modulus: 1.0e9}
bodies:
  sheet: {material: springs, origin: [0, 0, 0], size: [0.008, 0.008], thickness: 0.0005, spacing: 0.0004}
boundaries:
  - {name: left, region: {min: [-1, -1, -1], max: [0.0017, 1, 1]}, components: [x, y]}
  - {name: right, region: {min: [0.0063, -1, -1], max: [1, 1, 1]}, components: [x, y]}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, 0.0017, 1]}, components: [x, y]}
  - {name: top, region: {min: [-1, 0.0063, -1], max: [1, 1, 1]}, components: [x, y]}
initial: {center: [0.004, 0.004, 0]}
stages:
  - {name: preload, kind: quasistatic, displacement_gradient: [[0.5, 0, 0], [0, 0.5, 0], [0, 0, 0]], load_steps: 3}
  - {name: hold, steps: 1}
output: {frames: 1}
)";

TEST(LinearSpring, QuasiStaticPreloadIsAffineAndStoresTheSupportWork) {
  const Scene scene = parse_scene(kFrame, "spring-frame");
  Simulation sim(scene, PETSC_COMM_WORLD, quiet());
  sim.begin();
  ASSERT_EQ(sim.summary().quasistatic.size(), 1u);
  const QuasiStaticStats& qs = sim.summary().quasistatic[0].second;
  const Nodes nodes = discretize(scene);
  const std::vector<double> x = sim.natural_positions();
  double dev = 0;
  const double c0 = 0.004;
  for (std::int64_t i = 0; i < nodes.size(); ++i) {
    const double ax = c0 + 1.5 * (nodes.X[3 * i] - c0), ay = c0 + 1.5 * (nodes.X[3 * i + 1] - c0);
    dev = std::max({dev, std::fabs(x[3 * i] - ax), std::fabs(x[3 * i + 1] - ay), std::fabs(x[3 * i + 2])});
  }
  const double work_error = sim.summary().quasistatic_work_error.at(0);
  if (world_rank() == 0)
    std::printf("linear_spring preload: %zu increments, %ld Newton iterations, largest deviation from affine %.3e m, "
                "support work vs stored energy %.2e\n",
                qs.increments.size(), qs.newton_iterations, dev, work_error);
  EXPECT_LT(dev, 1e-9);
  EXPECT_LE(qs.newton_iterations, 2 * static_cast<long>(qs.increments.size()));
  EXPECT_LT(work_error, 1e-9);  // the bands' force is linear in the load: the trapezoid is exact
}

}  // namespace
}  // namespace peri
