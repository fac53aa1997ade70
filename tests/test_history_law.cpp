// A bond law with per-bond history, defined in this file alone: bilinear softening springs (a
// softening PMB). Each ordered bond keeps the largest strain it has reached, kappa; the bond
// force follows the bilinear envelope on loading and the secant back to the origin on unloading,
// and the energy released as kappa grows is booked as dissipated. Registered at run time and run
// through what a law with history needs (docs/developer/adding-a-law.md, "Per-bond history"):
//  - the checks of every law (tests/law_checks.hpp) at zero history;
//  - one bond through a strain path: the envelope, secant unloading and reloading, and the energy
//    dissipated to failure against the envelope's area (the bond's work of fracture);
//  - a dynamic run of a slit sheet whose bonds soften and break: the energy balance with the
//    softening's dissipation booked;
//  - a run stopped at a checkpoint and resumed: the same bits as the run not stopped, the
//    history of every bond included.
// Run under MPI at 1 and 2 ranks.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <type_traits>
#include <vector>

#include "law_checks.hpp"
#include "mpi_test.hpp"
#include "peri/io/restart.hpp"
#include "peri/kernels/law_kernels.hpp"
#include "peri/models/laws/bond_lanes.hpp"
#include "peri/stages/simulation.hpp"

namespace peri {
namespace {

// ------------------------------------------------------------------------------------------------
// The law. Bond strain s = y/|xi| - 1; the envelope f = c s up to the peak strain s_p = s_0 / 2,
// then c s_p (s_0 - s) / (s_0 - s_p) down to zero at s_0, where the bond breaks. With kappa the
// largest strain reached, a bond keeps the fraction
//   phi(kappa) = 1 (kappa <= s_p),  s_p (s_0 - kappa) / (kappa (s_0 - s_p)) (s_p < kappa < s_0)
// of its stiffness: f = phi c s, w = phi c s^2 |xi| / 2 (PMB's micropotential, softened). A force
// pass that commits raises kappa to the current strain first and books the energy dissipated on
// the envelope from the old kappa to the new (dissipated_by); a breaking bond books what it still
// held.

struct SofteningLaw {
  double c = 0;              ///< micromodulus [N/m^6]
  double horizon = 0;        ///< delta [m]
  double s0 = INFINITY;      ///< failure strain
  bool can_break = false;
  static constexpr double kPeak = 0.5;  ///< s_p / s_0
  static constexpr int kHistory = 1;    ///< kappa
  static constexpr bool kVectorized = false;

  double delta() const noexcept { return horizon; }
  bool breaks() const noexcept { return can_break; }
  /// What a bond holds when it breaks: nothing (its softening dissipated it all).
  double critical_energy(double) const noexcept { return 0.0; }
  double reference_stiffness(double xi2) const noexcept { return c / std::sqrt(xi2); }
  /// phi(kappa).
  double kept(double kappa) const noexcept {
    const double sp = kPeak * s0;
    if (kappa <= sp) return 1.0;
    if (kappa >= s0) return 0.0;
    return sp * (s0 - kappa) / (kappa * (s0 - sp));
  }
  /// Energy a bond has dissipated once its largest strain is kappa (< s_0), per unit |xi| and
  /// measure: the envelope's work to kappa less what the bond still holds there,
  /// D = int_0^kappa f ds - phi c kappa^2 / 2 (zero up to the peak; c s_p s_0 / 2 at s_0). In
  /// closed form, so that a step's share D(kappa_new) - D(kappa_old) is exact, whatever its size.
  double dissipated_by(double kappa) const noexcept {
    const double sp = kPeak * s0;
    if (kappa <= sp) return 0.0;
    const double k = std::min(kappa, s0);
    const double work = 0.5 * c * sp * sp + c * sp / (s0 - sp) * (s0 * (k - sp) - 0.5 * (k * k - sp * sp));
    return work - 0.5 * kept(k) * c * k * k;
  }

  template <class P, class Shape, bool Energy>
  struct Lanes {
    static_assert(std::is_same_v<P, simd::Scalar>, "a law with history runs in the portable walk");
    using Pack = P;
    using V = typename P::V;
    using M = typename P::M;
    static constexpr int W = P::W;
    static constexpr bool kEnergy = Energy;
    enum { kSlots = 0 };
    using Bonds = HistoryBondLanes<P, 0>;
    const SofteningLaw& law;
    explicit Lanes(const SofteningLaw& L) : law(L) {}
    double row_factor() const { return law.c; }
    struct Front {
      double y2;
    };
    Front front(const Bonds& b, double y2) const { return {std::max(y2, 1e-24 * b.xi2)}; }
    /// phi w V (1/|xi| - 1/y), and with Energy phi (c/2) s^2 |xi| w V.
    double coefficient(const Bonds& b, const Front& p, double& w, unsigned& fresh) const {
      fresh = 0;
      if (b.dead) return 0.0;
      const double xi = b.xi2 * b.inv_xi, y = std::sqrt(p.y2), s = y * b.inv_xi - 1.0;
      const double before = b.history.values ? b.history.values[0] : 0.0, kappa = std::max(before, s);
      const double stored = 0.5 * law.c * s * s * xi * b.measure;  // unsoftened, times w V
      const double phi_before = law.kept(before);
      if (law.can_break && kappa >= law.s0) {
        fresh = 1;
        if (b.history.commit) {
          if (b.history.values) b.history.values[0] = kappa;
          if (b.history.dissipated) *b.history.dissipated += phi_before * stored;
        }
        return 0.0;
      }
      double phi = phi_before;
      if (b.history.commit && kappa > before) {
        phi = law.kept(kappa);
        if (b.history.values) b.history.values[0] = kappa;
        if (b.history.dissipated)
          *b.history.dissipated += (law.dissipated_by(kappa) - law.dissipated_by(before)) * xi * b.measure;
      }
      if constexpr (Energy) w += phi * stored;
      return phi * b.measure * (b.inv_xi - 1.0 / y);
    }
    /// d coefficient / d(y^2) at fixed phi: phi w V / (2 y^3).
    double slope(const Bonds& b, const Front& p) const {
      const double phi = law.kept(b.history.values ? b.history.values[0] : 0.0), y = std::sqrt(p.y2);
      return 0.5 * phi * b.measure / (y * y * y);
    }
  };
  template <class F>
  decltype(auto) visit_shape(F&& f) const { return f(StretchShape<false, false>{}); }
  void make_intact() { can_break = false; }
};

// PMB's calibration (w = c s^2 |xi| / 2): in-plane mu = pi h c delta^3 / 24 (K = 2 mu), 3D
// mu = 3 K / 5 with K = pi c delta^4 / 18 ... per unit c, as models/laws/pmb.hpp's entry.
double mu_per_c(const BodyGeometry& g) {
  const double pi = 3.14159265358979323846;
  if (g.traits.dimension == 3) return 0.6 * 2.0 * pi * influence_moment(3, g.horizon, false) / 9.0;
  return pi * g.thickness * influence_moment(2, g.horizon, false) / 8.0;
}

LawEntry softening_entry() {
  LawEntry e = make_law_entry<SofteningLaw>("softening_spring", "bilinear softening springs (a test's law with history)");
  e.stability_note = "softens past half its failure strain; a softening bond makes no step less stable";
  e.material_keys = {"critical_stretch"};
  e.stiffness_keys = {"bulk_modulus"};
  e.critical_problem = [](double x) -> std::string {
    return x > 0 ? "" : "the softening_spring model needs a failure strain s_0 > 0";
  };
  e.calibrate = [](const Material& m, const BodyGeometry& g, const std::string& where, BondLaw& out) {
    if (g.traits.dimension == 1) throw InputError(where + ": softening_spring: membranes and solids only");
    SofteningLaw law;
    law.horizon = g.horizon;
    const double mu = g.traits.dimension == 3 ? 0.6 * *m.bulk_modulus : 0.5 * *m.bulk_modulus;
    law.c = mu / mu_per_c(g);
    check_micromodulus(m, g, where, mu, mu_per_c(g), law.c);
    if (m.critical_stretch) {
      law.s0 = *m.critical_stretch;
      law.can_break = true;
    }
    out = BondLaw(find_law("softening_spring"), law);
  };
  e.elastic = [](const void* law, const BodyGeometry& g, double density) {
    return isotropic_constants(static_cast<const SofteningLaw*>(law)->c * mu_per_c(g), g, density);
  };
  e.derived = [](const void* law) {
    return std::vector<std::pair<std::string, double>>{{"micromodulus", static_cast<const SofteningLaw*>(law)->c}};
  };
  return e;
}

const bool kRegistered = (register_law(softening_entry()), true);

const law_checks::Sample kSample{"softening_spring",
                                 "model: softening_spring, density: 1000, bulk_modulus: 1.0e9, critical_stretch: 0.008", ""};

RunOptions quiet() {
  RunOptions o;
  o.quiet = true;
  return o;
}

// ------------------------------------------------------------------------------------------------

TEST(HistoryLaw, IsRegisteredWithItsHistory) {
  ASSERT_TRUE(kRegistered);
  const LawEntry* e = find_law("softening_spring");
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->history, 1);
  EXPECT_FALSE(e->vectorized);
  for (const LawEntry* other : registered_laws())
    if (other != e) EXPECT_EQ(other->history, 0) << other->name;
}

TEST(HistoryLaw, PassesTheChecksOfEveryLaw) {
  law_checks::simd_and_portable_loops_give_the_same_bits(kSample);
  law_checks::coefficient_is_the_energy_gradient_and_slope_its_derivative(kSample);
  law_checks::tangent_row_is_the_derivative_of_the_forces(kSample);
  law_checks::calibration_stores_the_continuum_energy(kSample);
}

// One bond (|xi| = 1 mm, w V = 1) through a strain path, by the law's lanes with its history.
struct OneBond {
  SofteningLaw law;
  double kappa = 0, dissipated = 0, xi = 1e-3;
  using L = SofteningLaw::Lanes<simd::Scalar, StretchShape<false, false>, true>;
  /// Force per unit measure^2 at strain s after a committing pass, and whether it broke.
  double at(double s, bool& broke, double* energy = nullptr) {
    const L lanes(law);
    L::Bonds b{};
    b.d0 = (1 + s) * xi;
    b.xi2 = xi * xi;
    b.inv_xi = 1 / xi;
    b.measure = 1;
    b.dead = 0;
    b.history = BondHistory{&kappa, true, &dissipated};
    double w = 0;
    unsigned fresh = 0;
    const double coef = lanes.coefficient(b, lanes.front(b, b.d0 * b.d0), w, fresh);
    broke = fresh != 0;
    if (energy) *energy = w;
    return lanes.row_factor() * coef * b.d0;
  }
};

TEST(HistoryLaw, OneBondFollowsTheEnvelopeAndUnloadsAlongTheSecant) {
  OneBond bond;
  bond.law.c = 2.0e18;
  bond.law.s0 = 0.01;
  bond.law.can_break = true;
  const double c = bond.law.c, s0 = 0.01, sp = 0.005;
  bool broke = false;
  // Loading to 0.8 s_0 in small steps: the envelope.
  const int n = 20000;
  double envelope_error = 0;
  for (int k = 1; k <= n; ++k) {
    const double s = 0.008 * k / n;
    const double f = bond.at(s, broke);
    const double expect = s <= sp ? c * s : c * sp * (s0 - s) / (s0 - sp);
    envelope_error = std::max(envelope_error, std::fabs(f - expect) / (c * sp));
  }
  EXPECT_LT(envelope_error, 1e-12);
  EXPECT_NEAR(bond.kappa, 0.008, 1e-17);
  // Unloading to 0.3 s_0 and reloading to 0.8 s_0: the secant, phi(0.8 s_0) = 1/4; no dissipation.
  const double dissipated = bond.dissipated;
  for (double s : {0.006, 0.003, 0.0, 0.003, 0.008}) {
    const double f = bond.at(s, broke);
    EXPECT_NEAR(f, c * s / 4.0, 1e-12 * c * sp) << s;
    EXPECT_FALSE(broke);
  }
  EXPECT_EQ(bond.dissipated, dissipated);
  EXPECT_NEAR(bond.kappa, 0.008, 1e-17);
  // What it dissipated on the way: the envelope's area to 0.8 s_0 less the secant's triangle.
  const double area = 0.5 * c * sp * sp + c * sp / (s0 - sp) * (s0 * (0.008 - sp) - 0.5 * (0.008 * 0.008 - sp * sp));
  EXPECT_NEAR(dissipated / bond.xi, area - 0.5 * 0.25 * c * 0.008 * 0.008, 1e-9 * area);
  // On to failure: the work of fracture is the envelope's area c s_p s_0 / 2 times |xi|, all of it
  // dissipated (to the discretisation of the path: O(1/n)).
  for (int k = 1; k <= n && !broke; ++k) bond.at(0.008 + 0.004 * k / n, broke);
  EXPECT_TRUE(broke);
  const double work = 0.5 * c * sp * s0 * bond.xi;
  if (world_rank() == 0)
    std::printf("one softening bond: dissipated %.9e, envelope area %.9e (ratio %.6f)\n", bond.dissipated, work,
                bond.dissipated / work);
  EXPECT_NEAR(bond.dissipated / work, 1.0, 2e-4);
}

// A slit sheet pulled apart (as tests/test_linear_spring.cpp's), whose bonds soften and break.
std::string sheet(const std::string& safety_factor = "0.5") {
  return R"(
name: softening-sheet
materials:
  springs: {model: softening_spring, density: 1200, bulk_modulus: 1.2e9, critical_stretch: 0.15}
bodies:
  sheet: {material: springs, origin: [-0.01, -0.01, 0], size: [0.02, 0.02], thickness: 0.0005, spacing: 0.0005}
cracks:
  - {name: slit, from: [-0.003, 0, 0], to: [0.003, 0, 0]}
boundaries:
  - {name: top, region: {min: [-1, 0.0088, -1], max: [1, 1, 1]}, velocity: [0, 20, 0]}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0088, 1]}, velocity: [0, -20, 0]}
initial:
  displacement_gradient: [[0, 0, 0], [0, 0.03, 0], [0, 0, 0]]
  velocity_gradient: [[0, 0, 0], [0, 2000, 0], [0, 0, 0]]
stages:
  - {name: pull, duration: 4.0e-5, safety_factor: )" +
         safety_factor + R"(}
output: {frames: 1, series_every: 10}
)";
}

RunSummary pull(const std::string& safety_factor) {
  Simulation sim(parse_scene(sheet(safety_factor), "softening-sheet"), PETSC_COMM_WORLD, quiet());
  sim.run();
  const RunSummary& s = sim.summary();
  const EnergyRow& e = s.final_energy;
  if (world_rank() == 0)
    std::printf("softening sheet, safety factor %s: %lld steps, %lld bonds broken (%lld pre-cut), dissipated %.4e J, "
                "strain %.4e J, kinetic %.4e J, external work %.4e J; energy balance error %.2e\n",
                safety_factor.c_str(), static_cast<long long>(s.steps), static_cast<long long>(e.broken_bonds),
                static_cast<long long>(s.precrack_bonds), e.dissipated, e.strain, e.kinetic, e.external_work,
                s.energy_balance_error);
  return s;
}

// The slit runs and bonds soften ahead of it: the dissipation (half the external work here) is
// booked, so the balance closes to the Verlet scheme's error, which falls as dt^2 (without the
// softening's share the balance would miss it all).
TEST(HistoryLaw, DynamicRunBooksTheSofteningAsDissipation) {
  const RunSummary coarse = pull("0.5"), fine = pull("0.25");
  const EnergyRow& e = coarse.final_energy;
  EXPECT_GT(e.broken_bonds, 2 * coarse.precrack_bonds) << "the slit did not run";
  EXPECT_GT(e.dissipated, 0.5 * e.strain);
  EXPECT_LT(coarse.energy_balance_error, 2e-2);
  const double order = std::log2(coarse.energy_balance_error / fine.energy_balance_error);
  if (world_rank() == 0) std::printf("softening sheet: energy balance order %.2f in dt\n", order);
  EXPECT_NEAR(order, 2.0, 0.4);
}

TEST(HistoryLaw, ResumedRunIsBitForBitWithItsHistory) {
  const Scene scene = parse_scene(sheet(), "softening-sheet");
  Simulation whole(scene, PETSC_COMM_WORLD, quiet());
  whole.run();
  long pid = ::getpid();
  MPI_Bcast(&pid, 1, MPI_LONG, 0, PETSC_COMM_WORLD);
  const std::string path =
      (std::filesystem::temp_directory_path() / ("history-law-" + std::to_string(pid) + ".h5")).string();
  const std::int64_t at = whole.total_steps() / 2 + 3;
  std::size_t kept = 0;
  {
    Simulation first(scene, PETSC_COMM_WORLD, quiet());
    first.begin();
    first.advance(at);
    const Checkpoint c = first.make_checkpoint();
    if (world_rank() == 0) kept = c.extras.at("bonds.history").size() / 3;
    store_checkpoint(path, c, PETSC_COMM_WORLD);
  }
  RunOptions o = quiet();
  o.restart = load_checkpoint(path, PETSC_COMM_WORLD);
  Simulation second(scene, PETSC_COMM_WORLD, o);
  second.run();
  if (world_rank() == 0) {
    std::remove(path.c_str());
    std::remove(previous_checkpoint_path(path).c_str());
  }
  const auto xa = whole.natural_positions(), xb = second.natural_positions();
  std::size_t differing = 0;
  for (std::size_t k = 0; k < xa.size(); ++k) differing += xa[k] != xb[k];
  const std::vector<double> ha = gather_history_to_root(whole.domain(), PETSC_COMM_WORLD),
                            hb = gather_history_to_root(second.domain(), PETSC_COMM_WORLD);
  if (world_rank() == 0) {
    std::printf("resumed at step %lld: %zu bonds with history in the checkpoint; %zu of %zu positions differ; "
                "%zu vs %zu bonds with history at the end\n",
                static_cast<long long>(at), kept, differing, xa.size(), ha.size() / 3, hb.size() / 3);
    EXPECT_GT(kept, 100u) << "no bond had softened at the checkpoint: the history went untested";
    EXPECT_EQ(ha, hb);
  }
  EXPECT_EQ(differing, 0u);
  EXPECT_EQ(whole.broken_bonds(), second.broken_bonds());
  EXPECT_EQ(whole.summary().final_energy.dissipated, second.summary().final_energy.dissipated);
}

}  // namespace
}  // namespace peri
