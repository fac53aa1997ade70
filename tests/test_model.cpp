// Closed-form checks of the bond laws, their quadrature and their calibration (serial).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "peri/bonds/bonds.hpp"
#include "peri/partition/domain.hpp"
#include "peri/kernels/forces.hpp"
#include "peri/models/laws/membrane.hpp"
#include "peri/models/laws/membrane_hardening.hpp"
#include "peri/models/laws/pmb.hpp"
#include "peri/models/model.hpp"
#include "peri/scene/scene.hpp"

namespace peri {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Registered laws from their constants.
BondLaw membrane(double c, double delta, double critical0 = INFINITY, double critical_delta = NAN,
                 bool conical = false) {
  MembraneLaw m;
  m.c = c;
  m.horizon = delta;
  m.conical = conical;
  if (std::isfinite(critical0)) m.failure = {true, critical0, std::isnan(critical_delta) ? critical0 : critical_delta};
  return make_bond_law("membrane", m);
}
BondLaw pmb(double c, double delta, double critical0 = INFINITY, double critical_delta = NAN, bool conical = false) {
  PmbLaw m;
  m.c = c;
  m.horizon = delta;
  m.conical = conical;
  if (std::isfinite(critical0)) m.failure = {true, critical0, std::isnan(critical_delta) ? critical0 : critical_delta};
  return make_bond_law("pmb", m);
}
BondLaw hardening(const BondLaw& membrane_law, double hard_c, double hard_n) {
  return make_bond_law("membrane_hardening", MembraneHardeningLaw{membrane_law.as<MembraneLaw>(), hard_c, hard_n});
}
// The calibrated law's micromodulus (its derived constant).
double micromodulus(const BondLaw& law) { return law.derived("micromodulus"); }
// The stretch failure of a membrane or PMB law.
StretchFailure failure_of(const BondLaw& law) {
  return law.name() == "pmb" ? law.as<PmbLaw>().failure : law.as<MembraneLaw>().failure;
}
// The same law (membrane or PMB) with another shape: conical g, eq. (29)'s lambda_0 at delta.
BondLaw reshaped(const BondLaw& base, bool conical, double critical_delta) {
  auto edit = [&](auto law) {
    law.conical = conical;
    law.failure.critical_delta = critical_delta;
    return BondLaw(&base.entry(), law);
  };
  return base.name() == "pmb" ? edit(base.as<PmbLaw>()) : edit(base.as<MembraneLaw>());
}

BodyGeometry membrane_geometry(double delta, int m, Quadrature q) {
  BodyGeometry g;
  g.traits = find_body_kind("membrane")->traits;
  g.horizon = delta;
  g.spacing = delta / m;
  g.thickness = 1.0;
  g.cell_area = g.spacing * g.spacing;
  g.quadrature = q;
  return g;
}

// Energy density (eq. 5) of an interior node of a uniform grid under the homogeneous
// deformation diag(l1, l2). With damage, bonds at or past the critical stretch hold their energy
// at breaking, w(lambda_0) (the accounting of eq. 27 for a monotonic path).
double discrete_energy_density(const BondLaw& law, const BodyGeometry& g, double l1, double l2,
                               double l3 = 1.0) {
  const double dx = g.spacing;
  const int M = static_cast<int>(std::ceil(g.horizon / dx)) + 1;
  const bool solid = g.traits.dimension == 3;
  const double cell = solid ? dx * dx * dx : g.cell_area * g.thickness;
  double W = 0;
  for (int k = solid ? -M : 0; k <= (solid ? M : 0); ++k)
    for (int j = -M; j <= M; ++j)
      for (int i = -M; i <= M; ++i) {
        if (i == 0 && j == 0 && k == 0) continue;
        const double xi[3] = {i * dx, j * dx, k * dx};
        const double w = quadrature_weight(g, xi);
        if (w == 0) continue;
        const double s2 = xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2];
        const double y2 = l1 * l1 * xi[0] * xi[0] + l2 * l2 * xi[1] * xi[1] + l3 * l3 * xi[2] * xi[2];
        double e;
        if (law.broken_at(s2, y2)) {
          e = law.critical_energy(s2);
        } else {
          e = law.energy(s2, y2);
        }
        W += 0.5 * e * w * cell;
      }
  return W;
}

double eq19(double c, double h, double R, double l1, double l2) {
  return kPi * h * c * R / 2.0 * (l1 * l1 + l2 * l2 + 2.0 / (l1 * l2) - 4.0);
}

// eq. (28): damaged homogeneous energy, 1 <= l2 <= l0 <= l1.
double eq28(double c, double h, double R, double l0, double l1, double l2) {
  const double th0 = std::asin(std::sqrt((l1 * l1 - l0 * l0) / (l1 * l1 - l2 * l2)));
  return 2.0 * h * c * R *
         ((l0 * l0 + 1.0 / (l0 * l0)) * th0 + (l1 * l1 + l2 * l2) * (kPi / 4.0 - th0 / 2.0) +
          std::sin(2.0 * th0) / 4.0 * (l2 * l2 - l1 * l1) +
          1.0 / (l1 * l2) * std::atan(l1 / l2 / std::tan(th0)) - kPi);
}

TEST(Quadrature, DiscRectangleAreaIsExact) {
  const double r = 1.3;
  EXPECT_NEAR(disc_rectangle_area(r, -2, 2, -2, 2), kPi * r * r, 1e-13);
  EXPECT_NEAR(disc_rectangle_area(r, 0, 2, 0, 2), kPi * r * r / 4, 1e-13);
  EXPECT_NEAR(disc_rectangle_area(r, -0.5, 0.5, -0.5, 0.5), 1.0, 1e-15);  // square inside
  EXPECT_NEAR(disc_rectangle_area(r, 0, 2, -2, 2), kPi * r * r / 2, 1e-13);
  // A strip x in [1, 2]: circular segment area r^2 acos(1/r) - sqrt(r^2 - 1).
  EXPECT_NEAR(disc_rectangle_area(r, 1, 2, -2, 2), r * r * std::acos(1 / r) - std::sqrt(r * r - 1), 1e-13);
}

TEST(Quadrature, WeightsAreSymmetric) {
  const BodyGeometry g = membrane_geometry(1.0, 3, Quadrature::PartialArea);
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j) {
      const double a[3] = {i * g.spacing, j * g.spacing, 0}, b[3] = {-a[0], -a[1], 0};
      EXPECT_EQ(quadrature_weight(g, a), quadrature_weight(g, b));
    }
}

// Both neighbour searches, the lattice stencils and the cell list (which skips candidates beyond
// reach() on their raw distance), find exactly the nodes a search over every pair gives a positive
// weight, with the same weights, in ascending order: square and hexagonal membranes and solids,
// each quadrature, horizons that are and are not multiples of the spacing, bodies of one and two
// rows or layers, and two bodies in one scene (the second's natural ids offset by the first's).
TEST(Bonds, NeighbourSearchMatchesAllPairs) {
  const char* bodies[] = {
      "  b: {material: m, origin: [0, 0, 0], size: [0.013, 0.011], thickness: 0.001, spacing: 0.001, horizon: 0.003, quadrature: partial_area}",
      "  b: {material: m, origin: [0.2, -0.1, 0], size: [0.013, 0.011], thickness: 0.001, spacing: 0.001, horizon: 0.0035, quadrature: full, grid: hexagonal}",
      "  b: {material: m, origin: [0, 0, 0], size: [0.013, 0.011], thickness: 0.001, spacing: 0.001, horizon: 0.004, quadrature: partial_area, grid: hexagonal}",
      "  b: {kind: solid, material: m, origin: [0, 0, 0], size: [0.008, 0.007, 0.006], spacing: 0.001, horizon: 0.003015, quadrature: taper}",
      "  b: {kind: solid, material: m, origin: [1.0, 2.0, 3.0], size: [0.008, 0.007, 0.006], spacing: 0.001, horizon: 0.0025, quadrature: partial_area}",
      "  b: {kind: solid, material: m, origin: [0, 0, 0], size: [0.009, 0.002, 0.001], spacing: 0.001, horizon: 0.003, quadrature: partial_area}",
      "  b: {material: m, origin: [0, 0, 0], size: [0.012, 0.001], thickness: 0.001, spacing: 0.001, horizon: 0.003, grid: hexagonal}",
      "  a: {material: m, origin: [0, 0, 0], size: [0.007, 0.005], thickness: 0.001, spacing: 0.001, horizon: 0.003}\n"
      "  b: {material: m, origin: [0.003, 0.002, 0], size: [0.009, 0.006], thickness: 0.001, spacing: 0.0015, horizon: 0.0045, grid: hexagonal}"};
  for (const char* body : bodies) {
    const std::string text = std::string("name: k\nmaterials:\n  m: {model: pmb, density: 1000, bulk_modulus: 1.0e9}\n"
                                         "bodies:\n") + body + "\nstages:\n  - {name: r, steps: 1}\n";
    const Scene scene = parse_scene(text, "t");
    const Nodes nodes = discretize(scene);
    double max_reach = 0;
    for (const BodyGeometry& g : nodes.bodies) max_reach = std::max(max_reach, reach(g));
    for (const bool stencils : {true, false}) {
      const CellList cells(nodes, max_reach, stencils);
      for (std::size_t b = 0; b < nodes.bodies.size(); ++b)
        EXPECT_EQ(cells.stencil(static_cast<int>(b)) != nullptr, stencils) << body;
      std::vector<std::int64_t> ids;
      std::vector<double> w;
      std::int64_t pairs = 0, mismatched = 0;
      for (std::int64_t i = 0; i < nodes.size(); ++i) {
        const BodyGeometry& g = nodes.bodies[nodes.body[i]];
        neighbours_of(nodes, cells, i, ids, w);
        std::size_t k = 0;
        for (std::int64_t j = 0; j < nodes.size(); ++j) {
          if (j == i || nodes.body[j] != nodes.body[i]) continue;
          double xi[3];
          reference_offset(g, &nodes.X[3 * i], &nodes.X[3 * j], xi);
          const double wj = quadrature_weight(g, xi);
          if (!(wj > 0)) continue;
          ++pairs;
          mismatched += !(k < ids.size() && ids[k] == j && w[k] == wj);
          ++k;
        }
        mismatched += static_cast<std::int64_t>(ids.size() - k);
      }
      EXPECT_GT(pairs, 4 * nodes.size()) << body;
      EXPECT_EQ(mismatched, 0) << body << (stencils ? " (stencils)" : " (cells)");
    }
  }
}

// The taper of LAMMPS' PERI package: 1/2 + (delta - |xi|)/dx within dx/2 of delta (delta = 3.015 dx).
TEST(Quadrature, TaperWeightsNearTheHorizon) {
  BodyGeometry g;
  g.traits = find_body_kind("solid")->traits;
  g.spacing = 1e-3;
  g.horizon = 3.015e-3;
  g.quadrature = Quadrature::Taper;
  auto w = [&](int i, int j, int k) {
    const double xi[3] = {i * g.spacing, j * g.spacing, k * g.spacing};
    return quadrature_weight(g, xi);
  };
  EXPECT_EQ(w(1, 1, 1), 1.0);                                       // |xi| = 1.73 dx: inside
  EXPECT_EQ(w(2, 1, 1), 1.0);                                       // 2.45 dx < delta - dx/2
  EXPECT_NEAR(w(2, 2, 1), 0.515, 1e-12);
  EXPECT_NEAR(w(2, 2, 0), 0.5 + 3.015 - std::sqrt(8.0), 1e-12);  // |xi| = 2.83 dx
  EXPECT_NEAR(w(3, 0, 0), 0.515, 1e-12);
  EXPECT_EQ(w(3, 1, 0), 0.0);                                       // 3.16 dx > delta
}

// Eq. (19): the discrete energy density converges to the closed form as dx -> 0 at fixed delta.
TEST(MembraneLaw, HomogeneousEnergyConvergesToEq19) {
  const double delta = 1.0, c = 1.0, h = 1.0, R = delta * delta / 2.0;
  const BondLaw law = membrane(c, delta);
  const double stretches[][2] = {{1.1, 1.0}, {1.5, 1.2}, {2.0, 0.8}, {3.0, 1.0}, {2.9, 3.1}};
  const int ms[] = {3, 6, 12, 24, 48};
  for (Quadrature q : {Quadrature::PartialArea, Quadrature::Full}) {
    for (const auto& s : stretches) {
      const double exact = eq19(c, h, R, s[0], s[1]);
      double err[5];
      for (int k = 0; k < 5; ++k)
        err[k] = std::fabs(discrete_energy_density(law, membrane_geometry(delta, ms[k], q), s[0], s[1]) - exact) / exact;
      const double rate = std::log(err[3] / err[4]) / std::log(2.0);
      std::printf("eq19 %-12s lambda=(%.1f,%.1f): rel. error m=3 %.2e, 6 %.2e, 12 %.2e, 24 %.2e, 48 %.2e; observed order %.2f\n",
                  q == Quadrature::PartialArea ? "partial-area" : "full", s[0], s[1], err[0], err[1], err[2], err[3], err[4], rate);
      if (q == Quadrature::PartialArea) {
        EXPECT_LT(err[4], 2e-4);
        EXPECT_LT(err[4], err[2]);
        EXPECT_GT(std::log(err[2] / err[4]) / std::log(4.0), 1.5) << "expected about second order";
      } else {
        EXPECT_LT(err[4], 5e-2);  // full cells: converges, erratically (lattice points in a disc)
      }
    }
  }
}

// Eqs. (27)-(28): damaged homogeneous energy past lambda_0.
TEST(MembraneLaw, DamagedEnergyConvergesToEq28) {
  const double delta = 1.0, c = 1.0, h = 1.0, R = delta * delta / 2.0;
  const BondLaw law = membrane(c, delta, 2.0);
  const double cases[][2] = {{2.5, 1.2}, {3.0, 1.5}, {2.2, 1.0}, {2.05, 1.9}};
  for (const auto& s : cases) {
    const double exact = eq28(c, h, R, 2.0, s[0], s[1]);
    EXPECT_LT(exact, eq19(c, h, R, s[0], s[1]));  // damage lowers the stored+dissipated energy
    double prev = 1e9;
    for (int m : {6, 12, 24, 48}) {
      const double err =
          std::fabs(discrete_energy_density(law, membrane_geometry(delta, m, Quadrature::PartialArea), s[0], s[1]) - exact) / exact;
      std::printf("eq28 lambda=(%.2f,%.2f) m=%2d: rel. error %.2e\n", s[0], s[1], m, err);
      if (m == 48) EXPECT_LT(err, 5e-3);
      if (m >= 24) EXPECT_LT(err, prev * 1.05);
      prev = err;
    }
  }
}

Material make_material(const std::string& kind) {
  Material m;
  m.name = "test";
  m.model = kind;
  m.density = 1200;
  return m;
}

TEST(Calibration, ClosedFormsOfEachLaw) {
  // Membrane law from a wave speed: pi h c R = rho c_l^2 / 3 (eq. 19 small strain).
  Material m = make_material("membrane");
  m.wave_speed = 1000;
  BodyGeometry g = membrane_geometry(7.5e-4, 3, Quadrature::PartialArea);
  g.thickness = 5e-4;
  BondLaw law = calibrate(m, g, "test");
  const double c = micromodulus(law);
  EXPECT_NEAR(c, 1200 * 1e6 / 3 / (kPi * 5e-4 * 7.5e-4 * 7.5e-4 / 2), c * 1e-14);
  ElasticConstants e = elastic_constants(law, g, 1200);
  EXPECT_NEAR(e.c_longitudinal, 1000, 1e-9);
  EXPECT_NEAR(e.c_shear, 1000 / std::sqrt(3.0), 1e-9);
  EXPECT_NEAR(e.c_rayleigh / e.c_shear, 0.919402, 1e-5);  // lambda = mu
  // Conical g: R = delta^2 / 6.
  m.influence = Influence::Conical;
  EXPECT_NEAR(micromodulus(calibrate(m, g, "test")), 3 * c, c * 1e-12);
  // PMB membrane from in-plane bulk modulus: c = 12 K / (pi h delta^3).
  Material p = make_material("pmb");
  p.bulk_modulus = 300e6;
  EXPECT_NEAR(micromodulus(calibrate(p, g, "test")), 12 * 300e6 / (kPi * 5e-4 * std::pow(7.5e-4, 3)), 1e-6 * 12 * 300e6 / (kPi * 5e-4 * std::pow(7.5e-4, 3)));
  // PMB solid: c = 18 K / (pi delta^4).
  BodyGeometry s;
  s.traits = find_body_kind("solid")->traits;
  s.horizon = 3.015e-3;
  s.spacing = 1e-3;
  p.bulk_modulus = 14.9e9;
  EXPECT_NEAR(micromodulus(calibrate(p, s, "test")), 18 * 14.9e9 / (kPi * std::pow(3.015e-3, 4)), 1e-3);
  // The membrane law is refused for solids.
  EXPECT_THROW(calibrate(m, s, "test"), InputError);
}

// The calibration, checked against the discrete energy: a small homogeneous strain of a finely
// resolved body stores the energy of the continuum with the calibrated moduli.
TEST(Calibration, DiscreteSmallStrainEnergyMatchesModuli) {
  const double e = 1e-4;
  {
    Material m = make_material("membrane");
    m.bulk_modulus = 800e6;
    BodyGeometry g = membrane_geometry(1.0, 24, Quadrature::PartialArea);
    const BondLaw law = calibrate(m, g, "t");
    // equibiaxial: W = 2 K e^2; uniaxial strain: W = (lambda + 2 mu) e^2 / 2 = 3 mu e^2 / 2
    EXPECT_NEAR(discrete_energy_density(law, g, 1 + e, 1 + e) / (2 * 800e6 * e * e), 1.0, 2e-3);
    EXPECT_NEAR(discrete_energy_density(law, g, 1 + e, 1) / (1.5 * 400e6 * e * e), 1.0, 2e-3);
  }
  {
    Material m = make_material("pmb");
    m.bulk_modulus = 300e6;
    BodyGeometry g = membrane_geometry(1.0, 24, Quadrature::PartialArea);
    const BondLaw law = calibrate(m, g, "t");
    EXPECT_NEAR(discrete_energy_density(law, g, 1 + e, 1 + e) / (2 * 300e6 * e * e), 1.0, 2e-3);
  }
  {
    Material m = make_material("pmb");
    m.bulk_modulus = 14.9e9;
    BodyGeometry g;
    g.traits = find_body_kind("solid")->traits;
    g.horizon = 1.0;
    g.spacing = 1.0 / 10;
    g.quadrature = Quadrature::PartialArea;
    const BondLaw law = calibrate(m, g, "t");
    // isotropic: W = 9 K e^2 / 2
    EXPECT_NEAR(discrete_energy_density(law, g, 1 + e, 1 + e, 1 + e) / (4.5 * 14.9e9 * e * e), 1.0, 5e-3);
  }
}

// Forces are the exact negative gradient of the bond energy (finite differences), for every law.
TEST(Forces, AreNegativeGradientOfEnergy) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  const int n = 12;  // node 0 and 11 neighbours
  std::vector<double> X(3 * n), u(3 * n), V(n);
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 2; ++c) X[3 * i + c] = i ? 0.9 * U(rng) : 0.0;
    X[3 * i + 2] = 0;
    for (int c = 0; c < 3; ++c) u[3 * i + c] = 0.2 * U(rng);
    V[i] = 0.5 + 0.1 * i;
  }
  std::vector<std::int64_t> offsets{0, n - 1};
  std::vector<std::int32_t> nbr;
  for (int j = 1; j < n; ++j) nbr.push_back(j);
  std::vector<std::uint8_t> broken(n - 1, 0);
  // Family pattern of row 0: |xi|^2 and w_0j V_j with random quadrature weights.
  std::vector<double> xi2(n - 1), measure(n - 1);
  for (int j = 1; j < n; ++j) {
    xi2[j - 1] = 0;
    for (int c = 0; c < 3; ++c) xi2[j - 1] += (X[3 * j + c] - X[c]) * (X[3 * j + c] - X[c]);
    measure[j - 1] = (0.5 + 0.5 * std::fabs(U(rng))) * V[j];
  }
  PatternBuilder builder;
  builder.add_row(xi2, measure, 1.3);
  const FamilyPatterns patterns = builder.finish();
  std::vector<double> x(3 * n);
  const std::vector<BondLaw> laws{membrane(2.0, 1.3), membrane(2.0, 1.3, INFINITY, NAN, true),
                                  hardening(membrane(2.0, 1.3), 0.7, 3.5), pmb(2.0, 1.3)};
  const std::int32_t row = 0;
  for (const BondLaw& law : laws) {
    BondView v{X.data(), u.data(), V.data(), offsets.data(), nbr.data(), broken.data(), &patterns, x.data(), n};
    current_positions(X.data(), u.data(), 0, n, n, x.data());
    std::vector<double> F(3 * n, 0.0);
    BondTally t;
    bond_forces(law, v, &row, 1, F.data(), true, t);
    for (int c = 0; c < 3; ++c) {
      const double h = 1e-6, u0 = u[c];
      u[c] = u0 + h;
      current_positions(X.data(), u.data(), 0, n, n, x.data());
      const double ep = bond_energy(law, v, &row, 1);
      u[c] = u0 - h;
      current_positions(X.data(), u.data(), 0, n, n, x.data());
      const double em = bond_energy(law, v, &row, 1);
      u[c] = u0;
      current_positions(X.data(), u.data(), 0, n, n, x.data());
      // bond_energy = V_0/2 sum_j w V_j; the force density is -d/du_0 of sum_j w V_j.
      const double grad = (ep - em) / (2 * h) * 2.0 / V[0];
      EXPECT_NEAR(F[c], -grad, 1e-6 * (1 + std::fabs(grad))) << "component " << c;
    }
    EXPECT_NEAR(t.strain_energy, bond_energy(law, v, &row, 1), 1e-12 * std::fabs(t.strain_energy));
  }
}

// A node's damage is the broken share of its family's measures w V_j; rows without a broken flag
// are 0, whether row_broken says so or the flags are read (bits other than kBrokenFlag, which
// mark lattice bonds, are no damage).
TEST(Forces, NodeDamageIsTheBrokenShareOfTheMeasures) {
  // Rows 0 and 1 of four nodes, each bonded to the other three; row 0 with a family pattern.
  const std::vector<double> X = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<double> V = {1.0, 2.0, 3.0, 4.0};
  const std::vector<std::int64_t> offsets = {0, 3, 6};
  const std::vector<std::int32_t> nbr = {1, 2, 3, 0, 2, 3};
  PatternBuilder builder;
  builder.add_row({1.0, 1.0, 2.0}, {0.5 * 2.0, 1.0 * 3.0, 0.25 * 4.0}, 1.5);  // w V_j: 1, 3, 1
  builder.add_free_row({1.0, 1.0, 1.0});
  const FamilyPatterns patterns = builder.finish();
  std::vector<std::uint8_t> broken(6, 0), row_broken(2, 0);
  BondView v{X.data(), nullptr, V.data(), offsets.data(), nbr.data(), broken.data(), &patterns};
  const std::int32_t rows[] = {0, 1};
  auto damage = [&](bool with_row_bytes) {
    v.row_broken = with_row_bytes ? row_broken.data() : nullptr;
    std::vector<double> d(2, -1.0);
    node_damage(v, rows, 2, d.data());
    return d;
  };
  EXPECT_EQ(damage(true), (std::vector<double>{0.0, 0.0}));
  broken[4] = 2;  // another bit than kBrokenFlag: no damage
  row_broken[1] = 1;
  EXPECT_EQ(damage(true), (std::vector<double>{0.0, 0.0}));
  EXPECT_EQ(damage(false), (std::vector<double>{0.0, 0.0}));
  broken[1] = kBrokenFlag;  // row 0's bond to node 2: w V_j = 3 of 5
  broken[5] = kBrokenFlag | 2;  // row 1's bond to node 3: V_3 = 4 of 1 + 3 + 4 (free row: weight 1)
  row_broken = {1, 1};
  for (const bool with_row_bytes : {true, false}) {
    const std::vector<double> d = damage(with_row_bytes);
    EXPECT_DOUBLE_EQ(d[0], 3.0 / 5.0);
    EXPECT_DOUBLE_EQ(d[1], 4.0 / 8.0);
  }
}

// The energy booked at breaking, w(lambda_0) in closed form, is the micropotential evaluated at
// y = lambda_0 |xi| for every law shape (membrane with and without hardening, conical influence,
// linear lambda_0; PMB).
TEST(BondLaw, CriticalEnergyIsTheMicropotentialAtLambda0) {
  for (int shape = 0; shape < 8; ++shape) {
    const bool is_pmb = shape & 1, conical = shape & 2, linear = shape & 4;
    const double c0 = is_pmb ? 1.0005 : 1.8, cd = linear ? (is_pmb ? 1.0002 : 1.3) : c0;
    BondLaw law = is_pmb ? pmb(3.7e9, 3e-3, c0, cd, conical) : membrane(3.7e9, 3e-3, c0, cd, conical);
    if (!is_pmb && conical) law = hardening(law, 1.1e8, 3);
    for (double xi : {1e-3, 2.2e-3, 2.9e-3}) {
      const double xi2 = xi * xi, lc = c0 + (cd - c0) * xi / 3e-3;
      const double w = law.energy(xi2, lc * lc * xi2);
      EXPECT_GT(w, 0) << "shape " << shape;
      // energy() recovers the stretch as y/|xi| - 1, losing lc / (lc - 1) times the round-off
      // (about 5000 for PMB's s_0 = 5e-4); the closed form uses lambda_0 - 1 itself.
      EXPECT_NEAR(law.critical_energy(xi2), w, 1e-14 * lc / (lc - 1.0) * w) << "shape " << shape << " xi " << xi;
    }
  }
}

TEST(Forces, BreakingIsIrreversibleAndBooksEnergy) {
  std::vector<double> X{0, 0, 0, 1, 0, 0}, u{0, 0, 0, 0.5, 0, 0}, V{1, 1};
  std::vector<std::int64_t> offsets{0, 1};
  std::vector<std::int32_t> nbr{1};
  std::vector<std::uint8_t> broken{0};
  const BondLaw law = membrane(1, 2, 2.0);
  std::vector<double> x(6);
  BondView v{X.data(), u.data(), V.data(), offsets.data(), nbr.data(), broken.data(), nullptr, x.data(), 2};
  std::vector<double> F(6);
  const std::int32_t row = 0;
  BondTally t;
  current_positions(X.data(), u.data(), 0, 2, 2, x.data());
  bond_forces(law, v, &row, 1, F.data(), false, t);
  EXPECT_EQ(broken[0], 0);
  EXPECT_GT(F[0], 0);
  u[3] = 1.0;  // stretch exactly lambda_0 = 2: breaks (eq. 11: intact only while lambda < lambda_0)
  current_positions(X.data(), u.data(), 0, 2, 2, x.data());
  bond_forces(law, v, &row, 1, F.data(), false, t);
  EXPECT_EQ(broken[0], 1);
  EXPECT_EQ(F[0], 0.0);
  EXPECT_EQ(t.newly_broken, 1);
  EXPECT_NEAR(t.dissipated, 0.5 * law.energy(1.0, 4.0), 1e-15);  // half per end
  u[3] = 0.0;  // back to the reference length: stays broken
  current_positions(X.data(), u.data(), 0, 2, 2, x.data());
  bond_forces(law, v, &row, 1, F.data(), false, t);
  EXPECT_EQ(broken[0], 1);
  EXPECT_EQ(F[0], 0.0);
  EXPECT_EQ(t.newly_broken, 1);
}

// The production kernel (family patterns, current positions, AVX-512 where the build has it)
// against a direct evaluation of the law per bond from reference positions, measures and
// quadrature weights, on a grid membrane and a cubic solid with random displacements, for every
// law shape; and the same bonds broken.
// A one-body scene on one rank: its nodes, the domain of all of them, and the body's bond law.
struct OneRankBody {
  Nodes nodes;
  Domain d;
  BondLaw law;
  // split_x > 0: the domain of part 0 of two, the nodes with x < split_x (its ghosts beyond).
  explicit OneRankBody(const char* text, double split_x = 0) {
    const Scene scene = parse_scene(text, "kernel-test");
    nodes = discretize(scene);
    const CellList cells(nodes, reach(nodes.bodies[0]));
    std::vector<int> parts(nodes.size(), 0);
    if (split_x > 0)
      for (std::int64_t i = 0; i < nodes.size(); ++i) parts[i] = nodes.X[3 * i] < split_x ? 0 : 1;
    const Partition part = partition_from_parts(nodes, parts, split_x > 0 ? 2 : 1);
    d = build_domain(scene, nodes, cells, part, 0);
    law = calibrate(scene.materials[0], nodes.bodies[0], "t");
  }
};

TEST(Forces, KernelMatchesDirectEvaluationOfTheLaw) {
  const char* scenes[] = {
      "name: k\nmaterials:\n  m: {model: membrane, density: 1200, bulk_modulus: 8.0e8, critical_stretch: 1.004}\n"
      "bodies:\n  s: {material: m, origin: [0, 0, 0], size: [0.02, 0.015], thickness: 0.0005, spacing: 0.001, quadrature: partial_area}\n"
      "stages:\n  - {name: r, steps: 1}\n",
      "name: k\nmaterials:\n  m: {model: pmb, density: 2200, bulk_modulus: 1.49e10, critical_stretch: 0.005}\n"
      "bodies:\n  b: {kind: solid, material: m, origin: [0, 0, 0], size: [0.016, 0.017, 0.006], spacing: 0.001, horizon: 0.003015, quadrature: taper}\n"
      "stages:\n  - {name: r, steps: 1}\n"};
  // Both bodies have runs of eight and more rows (eight-lane blocks) and strided runs along the x
  // faces, whose lengths are not multiples of four (a last block overlapping the one before).
  // Each also as part 0 of two split across the x lines: the rows next to the cut have ghost
  // neighbours and form strided runs whose neighbours shift per slot (RowRun::slot_shifts).
  for (int variant = 0; variant < 4; ++variant) {
    const char* text = scenes[variant / 2];
    const bool split = variant % 2;
    OneRankBody body(text, split ? 0.0081 : 0.0);
    const Nodes& nodes = body.nodes;
    Domain& d = body.d;
    const BondLaw& base = body.law;
    const double c0 = failure_of(base).critical0, cd = 1.0 + 0.5 * (c0 - 1.0);
    const std::vector<BondLaw> laws{base, reshaped(base, true, c0), reshaped(base, false, cd), reshaped(base, true, cd)};
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    std::vector<double> u(3 * static_cast<std::size_t>(d.local())), x(3 * static_cast<std::size_t>(d.local()));
    for (double& c : u) c = 4e-6 * U(rng);  // strains up to about 1%: some bonds break
    current_positions(d.X.data(), u.data(), 0, d.local(), d.local(), x.data());
    std::vector<std::int32_t> rows(d.owned);
    for (std::int32_t i = 0; i < d.owned; ++i) rows[i] = i;
    {
      const BondView topology{d.X.data(), u.data(), d.volume.data(), d.bonds.offsets.data(), d.bonds.neighbor.data(),
                              d.bonds.broken.data(), &d.bonds.patterns, x.data(), d.local()};
      const RowBlocks plan = plan_rows(topology, rows.data(), rows.size());
      std::int64_t shifted = 0, mirrored = 0, mirrored_shifted = 0;
      for (const RowRun& run : plan.runs) {
        shifted += run.slot_shifts >= 0 ? run.count : 0;
        mirrored += run.mirror >= 0 ? run.count : 0;
        mirrored_shifted += run.mirror >= 0 && run.slot_shifts >= 0 ? run.count : 0;
      }
      EXPECT_EQ(split, d.ghosts > 0);
      EXPECT_EQ(split, shifted > 0) << "rows in runs with per-slot shifts: " << shifted;
      // The strided runs of eight rows or more (x faces; with ghosts, per-slot shifts) read the
      // plan's mirror, where the vector loop is compiled in.
      if (std::string(bond_kernel_isa()) != "portable") {
        EXPECT_GT(mirrored, 0);
        EXPECT_EQ(split, mirrored_shifted > 0) << "mirrored rows with per-slot shifts: " << mirrored_shifted;
      }
    }
    for (const BondLaw& law : laws) {
      std::vector<std::uint8_t> broken(d.bonds.broken.size(), 0);
      BondView v{d.X.data(), u.data(), d.volume.data(), d.bonds.offsets.data(), d.bonds.neighbor.data(),
                 broken.data(), &d.bonds.patterns, x.data(), d.local()};
      std::vector<double> F(3 * static_cast<std::size_t>(d.owned));
      BondTally t;
      bond_forces(law, v, rows.data(), rows.size(), F.data(), true, t);
      double worst = 0, energy = 0, rounding = 0, dissipated = 0;
      std::int64_t mismatched = 0, broken_direct = 0;
      for (std::int32_t i = 0; i < d.owned; ++i) {
        double f[3] = {0, 0, 0}, scale = 0, w = 0;
        for (std::int64_t b = d.bonds.offsets[i]; b < d.bonds.offsets[i + 1]; ++b) {
          const std::int32_t j = d.bonds.neighbor[b];
          double xi[3], r[3], raw_xi2 = 0, y2 = 0;
          reference_offset(nodes.bodies[0], &d.X[3 * i], &d.X[3 * j], xi);
          for (int c = 0; c < 3; ++c) {
            r[c] = xi[c] + u[3 * j + c] - u[3 * i + c];
            raw_xi2 += xi[c] * xi[c];
            y2 += r[c] * r[c];
          }
          // The stored |xi|^2 is rounded to 2^-46 horizon^2 (bonds.hpp); the law is evaluated at it.
          const double xi2 = rounded_xi2(raw_xi2, law.horizon());
          rounding = std::max(rounding, std::fabs(xi2 - raw_xi2) / (law.horizon() * law.horizon()));
          const bool breaks = law.broken_at(xi2, y2);
          broken_direct += breaks;
          mismatched += breaks != static_cast<bool>(broken[b] & 1);
          const double m = static_cast<float>(quadrature_weight(nodes.bodies[0], xi)) * d.volume[j];
          if (breaks) {  // booked at its breaking stretch lambda_0 (eqs. 26-27), half per end
            dissipated += 0.5 * d.volume[i] * law.critical_energy(xi2) * m;
            continue;
          }
          const double k = law.coefficient(xi2, y2) * m;
          for (int c = 0; c < 3; ++c) {
            f[c] += k * r[c];
            scale += std::fabs(k * r[c]);
          }
          w += law.energy(xi2, y2) * m;
        }
        energy += 0.5 * d.volume[i] * w;
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::fabs(F[3 * i + c] - f[c]) / scale);
      }
      std::printf("kernel vs direct: largest force difference %.2e, broken %lld\n", worst, static_cast<long long>(broken_direct));
      EXPECT_LT(worst, 1e-12) << "largest force difference relative to the sum of |bond forces|";
      EXPECT_LE(rounding, std::ldexp(1.0, -46));
      EXPECT_EQ(mismatched, 0);
      EXPECT_GT(broken_direct, 0);
      EXPECT_EQ(t.newly_broken, broken_direct);
      EXPECT_NEAR(t.strain_energy, energy, 1e-9 * energy);
      EXPECT_NEAR(t.dissipated, dissipated, 1e-12 * dissipated);
      // A flag is broken or not, nothing else: breaking sets no other bit (each break is booked as
      // it is flagged).
      std::int64_t unbooked = 0;
      for (std::uint8_t f : broken) unbooked += f > 1;
      EXPECT_EQ(unbooked, 0);
      // A second call finds those bonds already broken: nothing new breaks, and the forces and
      // energy are the same bits (a bond broken before the call adds nothing, as one breaking in it).
      std::vector<double> F2(F.size());
      BondTally t2;
      bond_forces(law, v, rows.data(), rows.size(), F2.data(), true, t2);
      EXPECT_EQ(t2.newly_broken, 0);
      EXPECT_EQ(F2, F);
      EXPECT_EQ(t2.strain_energy, t.strain_energy);
      // With the rows' summary bytes (as Simulation passes them) the loop skips the flags of rows
      // marked intact: the same bits and the same bonds broken, and afterwards exactly the rows
      // with a broken bond are marked; a second call (blocks with broken bonds) agrees too.
      std::vector<std::uint8_t> broken_s(d.bonds.broken.size(), 0), summary(d.owned, 0);
      BondView vs = v;
      vs.broken = broken_s.data();
      vs.row_broken = summary.data();
      std::vector<double> Fs(F.size());
      BondTally ts;
      bond_forces(law, vs, rows.data(), rows.size(), Fs.data(), true, ts);
      EXPECT_EQ(Fs, F);
      EXPECT_EQ(broken_s, broken);
      EXPECT_EQ(ts.newly_broken, t.newly_broken);
      std::int64_t mismarked = 0, marked = 0;
      for (std::int32_t i = 0; i < d.owned; ++i) {
        bool any = false;
        for (std::int64_t b = d.bonds.offsets[i]; b < d.bonds.offsets[i + 1]; ++b) any = any || broken[b] != 0;
        mismarked += (summary[i] != 0) != any;
        marked += summary[i] != 0;
      }
      EXPECT_EQ(mismarked, 0);
      EXPECT_GT(marked, 0);
      bond_forces(law, vs, rows.data(), rows.size(), Fs.data(), true, ts);
      EXPECT_EQ(Fs, F);
      // Strided runs read from the mirror (eight lanes) or gathered element by element (four):
      // the same bits, the same bonds broken and booked, on the breaking call and on the next,
      // whose blocks hold broken bonds.
      const RowBlocks mirrored = plan_rows(vs, rows.data(), rows.size());
      RowBlocks gathered = mirrored;
      for (RowRun& run : gathered.runs) run.mirror = -1;
      std::vector<std::uint8_t> broken_m(broken.size(), 0), broken_g(broken.size(), 0), summary_m(d.owned, 0),
          summary_g(d.owned, 0);
      BondView vm = vs, vg = vs;
      vm.broken = broken_m.data();
      vm.row_broken = summary_m.data();
      vg.broken = broken_g.data();
      vg.row_broken = summary_g.data();
      BondTally first;
      for (int call = 0; call < 3; ++call) {
        if (call == 2) {
          // Flags cleared in place (a restart would load others): after forget_broken the plan's
          // cache of dead lanes (RowBlocks::dead_cache_entries) is read from the flags again, and the
          // first call's bonds break and are booked again.
          std::fill(broken_m.begin(), broken_m.end(), 0);
          std::fill(summary_m.begin(), summary_m.end(), 0);
          mirrored.forget_broken();
        }
        std::vector<double> Fm(F.size()), Fg(F.size());
        BondTally tm, tg;
        bond_forces(law, vm, mirrored, Fm.data(), true, tm);
        if (call == 2) {
          EXPECT_EQ(Fm, F);
          EXPECT_EQ(broken_m, broken);
          EXPECT_EQ(tm.newly_broken, first.newly_broken);
          EXPECT_EQ(tm.dissipated, first.dissipated);
          continue;
        }
        bond_forces(law, vg, gathered, Fg.data(), true, tg);
        if (call == 0) first = tm;
        EXPECT_EQ(Fm, Fg);
        EXPECT_EQ(Fm, F);
        EXPECT_EQ(broken_m, broken_g);
        EXPECT_EQ(summary_m, summary_g);
        EXPECT_EQ(tm.newly_broken, tg.newly_broken);
        EXPECT_EQ(tm.strain_energy, tg.strain_energy);
        EXPECT_EQ(tm.dissipated, tg.dissipated);
      }
      EXPECT_EQ(broken_m, broken);
      if (std::string(bond_kernel_isa()) != "portable") EXPECT_GT(mirrored.dead_cache_entries, 0);
    }
  }
}

// Boxes (RowBox: a bond between two lines evaluated once, its coefficient handed to the other
// end) give the same bits as every bond evaluated from both ends: forces, flags, rows' summary
// bytes and broken counts (the booked energy to its summation order), on calls where bonds break during the call, where lines hold bonds broken
// before it, and with a horizon of four spacings (wider pad and window). A 3D block gets no boxes
// (too few of its bonds pair across lines to pay, find_box) and the same bits either way.
TEST(Forces, PairedBondsGiveTheSameBitsAsBothEnds) {
  const char* scenes[] = {
      "name: k\nmaterials:\n  m: {model: membrane, density: 1200, bulk_modulus: 8.0e8, critical_stretch: 1.004}\n"
      "bodies:\n  s: {material: m, origin: [0, 0, 0], size: [0.06, 0.03], thickness: 0.0005, spacing: 0.001, quadrature: partial_area}\n"
      "stages:\n  - {name: r, steps: 1}\n",
      "name: k\nmaterials:\n  m: {model: pmb, density: 1200, bulk_modulus: 8.0e8, critical_stretch: 0.004}\n"
      "bodies:\n  s: {material: m, origin: [0, 0, 0], size: [0.05, 0.04], thickness: 0.0005, spacing: 0.001, horizon: 0.004, quadrature: full}\n"
      "stages:\n  - {name: r, steps: 1}\n",
      "name: k\nmaterials:\n  m: {model: pmb, density: 2200, bulk_modulus: 1.49e10, critical_stretch: 0.005}\n"
      "bodies:\n  b: {kind: solid, material: m, origin: [0, 0, 0], size: [0.02, 0.012, 0.01], spacing: 0.001, horizon: 0.003015, quadrature: taper}\n"
      "stages:\n  - {name: r, steps: 1}\n"};
  for (const char* text : scenes) {
    OneRankBody body(text);
    Domain& d = body.d;
    const BondLaw& law = body.law;
    std::vector<std::int32_t> rows(d.owned);
    for (std::int32_t i = 0; i < d.owned; ++i) rows[i] = i;
    std::vector<double> u(3 * static_cast<std::size_t>(d.local())), x(u.size());
    BondView v{d.X.data(), u.data(), d.volume.data(), d.bonds.offsets.data(), d.bonds.neighbor.data(),
               nullptr, &d.bonds.patterns, x.data(), d.local()};
    const RowBlocks paired = plan_rows(v, rows.data(), rows.size(), true);
    const RowBlocks plain = plan_rows(v, rows.data(), rows.size(), false);
    const bool solid = std::string(text).find("kind: solid") != std::string::npos;
    ASSERT_EQ(paired.boxes.empty(), solid);
    EXPECT_TRUE(plain.boxes.empty());
    std::int64_t pairs = 0;
    for (const RowBox& box : paired.boxes)
      for (const BoxSlot& slot : box.slots) pairs += slot.kind == BoxSlot::Produce;
    EXPECT_EQ(pairs > 0, !solid);
    // Two states for each plan, each called three times: random strains of up to about 1% (a few
    // bonds break in the first call, in lines that were intact) and a strain concentrated on a band
    // of rows (lines broken before later calls, next to intact ones).
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    double y_mid = 0;
    for (std::int32_t i = 0; i < d.local(); ++i) y_mid += d.X[3 * i + 1] / d.local();
    for (int state = 0; state < 2; ++state) {
      for (std::int32_t i = 0; i < d.local(); ++i)
        for (int c = 0; c < 3; ++c) {
          const double band = state == 1 && std::fabs(d.X[3 * i + 1] - y_mid) < 0.0015 ? 40.0 : 1.0;
          u[3 * i + c] = (state == 0 ? 4e-6 : 2e-7) * band * U(rng);
        }
      current_positions(d.X.data(), u.data(), 0, d.local(), d.local(), x.data());
      std::vector<std::uint8_t> flags_a(d.bonds.broken.size(), 0), flags_b = flags_a, sum_a(d.owned, 0), sum_b = sum_a;
      // New flags (perhaps where the last state's were): the plans forget the dead lanes they kept.
      paired.forget_broken();
      plain.forget_broken();
      for (int call = 0; call < 3; ++call) {
        std::vector<double> Fa(3 * static_cast<std::size_t>(d.owned)), Fb(Fa.size());
        BondTally ta, tb;
        BondView va = v, vb = v;
        va.broken = flags_a.data();
        va.row_broken = sum_a.data();
        vb.broken = flags_b.data();
        vb.row_broken = sum_b.data();
        bond_forces(law, va, paired, Fa.data(), false, ta);
        bond_forces(law, vb, plain, Fb.data(), false, tb);
        EXPECT_EQ(Fa, Fb) << "state " << state << " call " << call;
        EXPECT_EQ(flags_a, flags_b);
        EXPECT_EQ(sum_a, sum_b);
        EXPECT_EQ(ta.newly_broken, tb.newly_broken);
        // Each row books the same bits; the plans visit the rows in different orders (the plain
        // plan's run tails form strided runs, plan_rows), so the rows' bookings add up in another order.
        EXPECT_NEAR(ta.dissipated, tb.dissipated, 1e-13 * ta.dissipated);
        if (call == 0) EXPECT_GT(ta.newly_broken, 0) << "state " << state;
        // Next call: a little more strain, so more bonds break in lines that are intact so far.
        for (double& c : u) c *= 1.05;
        current_positions(d.X.data(), u.data(), 0, d.local(), d.local(), x.data());
      }
    }
  }
}

}  // namespace
}  // namespace peri
