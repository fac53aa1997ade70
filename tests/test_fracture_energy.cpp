// Energy release rate: the work to advance a crack slowly, on the solver's discretization, against
// eq. (30) (serial).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "peri/models/fracture_energy.hpp"
#include "peri/models/laws/membrane.hpp"
#include "peri/models/laws/pmb.hpp"

namespace peri {
namespace {

// Sheet around a straight advance of about 4 delta along y = 0 (between node rows), m = delta/dx.
struct Measured {
  double G, exact;
  std::int64_t bonds;
};
Measured measure(double delta, int m, const char* extra_material = "") {
  const double dx = delta / m;
  const double advance = std::ceil(4 * delta / dx) * dx;
  const double hx = std::ceil((0.5 * advance + 2 * delta) / dx) * dx, hy = std::ceil(2 * delta / dx) * dx;
  char text[1024];
  std::snprintf(text, sizeof text, R"(
name: sheet
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2.0%s}
bodies:
  sheet: {material: rubber, origin: [%.17g, %.17g, 0], size: [%.17g, %.17g], thickness: 0.0005, spacing: %.17g, horizon: %.17g}
stages:
  - {name: none, steps: 1}
)", extra_material, -hx, -hy, 2 * hx, 2 * hy, dx, delta);
  const Scene scene = parse_scene(text, "release-rate");
  const Nodes nodes = discretize(scene);
  const CellList cells(nodes, reach(nodes.bodies[0]));
  const BondLaw law = calibrate(scene.materials[0], nodes.bodies[0], "sheet");
  Crack seg;
  // Ends off the bonds' crossing points (which lie at rational fractions of dx).
  seg.from = {-0.5 * advance + 0.3183098862 * dx, 0, 0};
  seg.to = {0.5 * advance + 0.3183098862 * dx, 0, 0};
  const CrackAdvanceEnergy e = crack_advance_energy(nodes, cells, law, 0, seg);
  return {e.release_rate, eq30_release_rate(law, 0.0005), e.bonds};
}

// A PMB block around a square crack of side 4 delta in the plane x = 0 (between node layers),
// its edges off the nodes' columns, at least a horizon inside the block.
Measured measure_3d(double delta, int m) {
  const double dx = delta / m;
  const double side = std::ceil(3 * delta / dx) * dx;
  const double hx = std::ceil(1.2 * delta / dx) * dx, hyz = std::ceil((0.5 * side + 1.2 * delta) / dx) * dx;
  char text[1024];
  std::snprintf(text, sizeof text, R"(
name: block
materials:
  glass: {model: pmb, density: 2200, micromodulus: 1.0e19, critical_stretch: 0.0005}
bodies:
  block: {kind: solid, material: glass, origin: [%.17g, %.17g, %.17g], size: [%.17g, %.17g, %.17g], spacing: %.17g, horizon: %.17g}
stages:
  - {name: none, steps: 1}
)", -hx, -hyz, -hyz, 2 * hx, 2 * hyz, 2 * hyz, dx, delta);
  const Scene scene = parse_scene(text, "release-rate-3d");
  const Nodes nodes = discretize(scene);
  const CellList cells(nodes, reach(nodes.bodies[0]));
  const BondLaw law = calibrate(scene.materials[0], nodes.bodies[0], "block");
  const double a = -0.5 * side + 0.3183098862 * dx, b = 0.5 * side + 0.3183098862 * dx;
  Crack square;
  square.polygon = {{0, a, a}, {0, b, a}, {0, b, b}, {0, a, b}};
  const CrackAdvanceEnergy e = crack_advance_energy_3d(nodes, cells, law, 0, square);
  return {e.release_rate, release_rate_3d(law), e.bonds};
}

// The work to cut a plane of a PMB block, bond by bond, against pi c s_0^2 delta^5 / 10.
TEST(ReleaseRate, WorkToCutAPlaneOfABlockConvergesToThePmbClosedForm) {
  PmbLaw p;
  p.c = 2.0e19;
  p.horizon = 1e-3;
  p.failure = {true, 1.0005, 1.0005};  // lambda_0 = 1 + s_0
  const BondLaw pmb = make_bond_law("pmb", p);
  EXPECT_NEAR(release_rate_3d(pmb) / (M_PI * p.c * 25e-8 * std::pow(1e-3, 5) / 10), 1.0, 1e-9);
  const int ms[] = {2, 3, 4, 5};
  double err[4];
  for (int k = 0; k < 4; ++k) {
    const Measured r = measure_3d(1e-3, ms[k]);
    err[k] = std::fabs(r.G / r.exact - 1);
    std::printf("G (3D): m = %d: %lld crossing bonds, G_h = %.6g J/m^2, closed form %.6g, relative error %.3e\n", ms[k],
                static_cast<long long>(r.bonds), r.G, r.exact, err[k]);
  }
  std::printf("G (3D): observed order between m = 3 and 5: %.2f\n", std::log(err[1] / err[3]) / std::log(5.0 / 3.0));
  EXPECT_LT(err[3], 0.01);  // m = 5: within 1% (0.57% measured)
  for (int k = 1; k < 4; ++k) EXPECT_LT(err[k], err[k - 1]) << "error must decrease with refinement (m = " << ms[k] << ")";
}

TEST(ReleaseRate, Eq30ClosedFormForConstantInfluence) {
  MembraneLaw m;
  m.c = 3.0;
  m.horizon = 2e-3;
  m.failure = {true, 2.0, 2.0};
  const BondLaw law = make_bond_law("membrane", m);
  const double w0 = m.c * (4 + 0.25 - 2);  // eq. (26)
  EXPECT_NEAR(eq30_release_rate(law, 0.5e-3) / (2 * 0.5e-3 * w0 * std::pow(2e-3, 3) / 3), 1.0, 1e-12);
}

TEST(ReleaseRate, WorkToAdvanceACrackConvergesToEq30) {
  const double delta = 1e-3;
  const int ms[] = {3, 4, 6, 8, 12};
  double err[5];
  for (int k = 0; k < 5; ++k) {
    const Measured r = measure(delta, ms[k]);
    err[k] = std::fabs(r.G / r.exact - 1);
    std::printf("G: m = %2d: %lld crossing bonds, G_h = %.6g J/m^2, eq. (30) %.6g, relative error %.3e\n", ms[k],
                static_cast<long long>(r.bonds), r.G, r.exact, err[k]);
  }
  const double order = std::log(err[2] / err[4]) / std::log(2.0);
  std::printf("G: observed order between m = 6 and 12: %.2f\n", order);
  EXPECT_LT(err[4], 0.05);  // finest resolution of this test: within 5% of eq. (30)
  for (int k = 1; k < 5; ++k) EXPECT_LT(err[k], err[k - 1]) << "error must decrease with refinement (m = " << ms[k] << ")";
}

TEST(ReleaseRate, ScaleFreeAtFixedM) {
  // G / eq. (30) depends on m only: the ladder at fixed m is flat.
  const Measured a = measure(2e-3, 3), b = measure(0.5e-3, 3);
  EXPECT_NEAR(a.G / a.exact, b.G / b.exact, 1e-9);
}

TEST(ReleaseRate, LinearCriticalStretchAndConicalInfluence) {
  // Eq. (29) and g = 1 - xi/delta: the same measurement against the integral form of eq. (30).
  const Measured r = measure(1e-3, 12, ", critical_stretch_at_horizon: 1.5, influence: conical");
  std::printf("G (conical, lambda_0 2 -> 1.5): G_h = %.6g, eq. (30) %.6g, relative error %.3e\n", r.G, r.exact,
              std::fabs(r.G / r.exact - 1));
  EXPECT_NEAR(r.G / r.exact, 1.0, 0.05);
}

}  // namespace
}  // namespace peri
