// Fibers (eq. 31) and long-range forces (eqs. 32-36): nodes along the path, the bar calibration
// against the discrete energy, eq. (37) from the bonds across a cut, and the long-range pair
// forces as the exact negative gradient of their energy, with the pair rules of eq. (34).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "peri/bonds/bonds.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/models/long_range.hpp"
#include "peri/stages/long_range_halo.hpp"
#include "peri/models/model.hpp"
#include "peri/scene/scene.hpp"

namespace peri {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A straight fiber from the origin along (1, 2, 2)/3 (off every grid axis) of length L, m
// spacings to the horizon.
Scene fiber_scene(const std::string& model, const std::string& stiffness, int m, double length = 60e-9) {
  const double ds = 0.5e-9;
  const double e[3] = {1.0 / 3, 2.0 / 3, 2.0 / 3};
  char text[1024];
  std::snprintf(text, sizeof text,
                "name: f\nmaterials:\n  p: {model: %s, density: 3000, %s}\n"
                "bodies:\n  fiber: {kind: fiber, material: p, path: [[0, 0, 0], [%.17g, %.17g, %.17g]], "
                "diameter: 1.0e-9, spacing: %.17g, horizon: %.17g, segment_length: 7.0e-9}\n"
                "stages:\n  - {name: r, steps: 1}\n",
                model.c_str(), stiffness.c_str(), length * e[0], length * e[1], length * e[2], ds, m * ds * (1 + 1e-9));
  return parse_scene(text, "fiber-test");
}

TEST(Fiber, NodesSitAlongThePathWithTheirMeasure) {
  const Scene scene = fiber_scene("membrane", "youngs_modulus: 40.0e9", 3, 60e-9);
  const Nodes nodes = discretize(scene);
  const BodyGeometry& g = nodes.bodies[0];
  ASSERT_EQ(nodes.size(), 120);
  EXPECT_NEAR(g.spacing, 0.5e-9, 1e-24);
  EXPECT_NEAR(g.area, kPi * 0.25e-18, 1e-33);
  for (std::int64_t k = 0; k < nodes.size(); ++k) {
    const double s = (k + 0.5) * g.spacing;  // arc length of node k
    EXPECT_NEAR(nodes.X[3 * k + 0], s / 3, 1e-20);
    EXPECT_NEAR(nodes.X[3 * k + 1], 2 * s / 3, 1e-20);
    EXPECT_NEAR(nodes.X[3 * k + 2], 2 * s / 3, 1e-20);
    EXPECT_DOUBLE_EQ(nodes.volume[k], g.area * g.spacing);
  }
  // A polyline: the nodes follow both legs, equally spaced by arc length.
  const Scene bent = parse_scene(
      "name: f\nmaterials:\n  p: {model: pmb, density: 3000, youngs_modulus: 1.5e9}\n"
      "bodies:\n  fiber: {kind: fiber, material: p, path: [[0, 0, 0], [4.0e-9, 0, 0], [4.0e-9, 3.0e-9, 0]], "
      "diameter: 1.0e-9, spacing: 1.0e-9}\nstages:\n  - {name: r, steps: 1}\n",
      "bent");
  const Nodes b = discretize(bent);
  ASSERT_EQ(b.size(), 7);
  EXPECT_NEAR(b.X[3 * 3 + 0], 3.5e-9, 1e-21);
  EXPECT_NEAR(b.X[3 * 4 + 1], 0.5e-9, 1e-21);
  EXPECT_NEAR(b.X[3 * 4 + 0], 4.0e-9, 1e-21);
}

// c from E (model.hpp): membrane law E = 8 A c delta, PMB E = A c delta^2 / 2 (g = 1); and the
// discrete energy of an interior node of the straight fiber under a small uniaxial stretch:
// exact for the membrane law (its w does not depend on |xi| at a given lambda), (m + 1)/m times
// the continuum for PMB (the sum of k ds over k = 1..m against the integral of xi to m ds).
// The bar's calibration is the continuum's (E = 8 A c R_0, A c R_1); an interior node of the
// discrete fiber (full weights, nodes ds apart, delta = m ds) holds the sum over k = 1..m of
// g(k ds) (k ds)^j ds against the integral: exact for the membrane law with g = 1, (m + 1)/m for
// PMB with g = 1, and with conical g (m - 1)/m (membrane law) and (m^2 - 1)/m^2 (PMB).
TEST(Fiber, BarCalibrationMatchesTheDiscreteEnergy) {
  for (int m : {3, 12})
    for (const bool conical : {false, true})
    for (const bool membrane : {true, false}) {
      const double E = membrane ? 40e9 : 1.5e9;
      const Scene scene = fiber_scene(membrane ? "membrane" : "pmb", "youngs_modulus: " + std::to_string(E) +
                                          (conical ? ", influence: conical" : ""), m);
      const Nodes nodes = discretize(scene);
      const BodyGeometry& g = nodes.bodies[0];
      const BondLaw law = calibrate(scene.materials[0], g, "t");
      const double delta = g.horizon, A = g.area;
      const double c = law.derived("micromodulus");
      const double c_expected = membrane ? E / ((conical ? 4 : 8) * A * delta) : (conical ? 6 : 2) * E / (A * delta * delta);
      EXPECT_NEAR(c, c_expected, c * 1e-12);
      EXPECT_NEAR(elastic_constants(law, g, 3000).c_longitudinal, std::sqrt(E / 3000), 1e-9);
      // Energy density of the middle node: W = 1/2 sum_j w V_j, stretched by 1 + e.
      const double e = 1e-5;
      const CellList cells(nodes, reach(g));
      std::vector<std::int64_t> ids;
      std::vector<double> w, xi2;
      const std::int64_t i = nodes.size() / 2;
      neighbours_of(nodes, cells, i, ids, w, &xi2);
      ASSERT_EQ(ids.size(), static_cast<std::size_t>(2 * m));
      double W = 0;
      for (std::size_t k = 0; k < ids.size(); ++k)
        W += 0.5 * law.energy(xi2[k], (1 + e) * (1 + e) * xi2[k]) * w[k] * nodes.volume[ids[k]];
      const double discrete = membrane ? (conical ? (m - 1.0) / m : 1.0) : (conical ? (m * m - 1.0) / (m * m) : (m + 1.0) / m);
      const double expected = 0.5 * E * e * e * discrete;
      EXPECT_NEAR(W / expected, 1.0, 2e-4) << (membrane ? "membrane" : "pmb") << (conical ? " conical" : "") << " m = " << m;
    }
}

// Eq. (37): G = A w0 delta^2 / 2 for the membrane law with constant lambda_0; the bonds across a
// cut of the discrete fiber give (m + 1)/m of it (m(m+1)/2 pairs of nodes ds apart).
TEST(Fiber, EnergyReleaseRateEq37) {
  for (int m : {3, 6, 24}) {
    Scene scene = fiber_scene("membrane", "youngs_modulus: 40.0e9, critical_stretch: 1.3", m);
    const Nodes nodes = discretize(scene);
    const BodyGeometry& g = nodes.bodies[0];
    const BondLaw law = calibrate(scene.materials[0], g, "t");
    const double l0 = 1.3, w0 = law.derived("micromodulus") * (l0 * l0 + 1 / (l0 * l0) - 2);
    const CellList cells(nodes, reach(g));
    std::vector<std::int64_t> ids;
    std::vector<double> w, xi2;
    const std::int64_t cut = nodes.size() / 2;  // between nodes cut - 1 and cut
    double G = 0;
    for (std::int64_t i = 0; i < cut; ++i) {
      neighbours_of(nodes, cells, i, ids, w, &xi2);
      for (std::size_t k = 0; k < ids.size(); ++k)
        if (ids[k] >= cut) G += law.energy(xi2[k], l0 * l0 * xi2[k]) * w[k] * nodes.volume[i] * nodes.volume[ids[k]] / g.area;
    }
    const double closed = g.area * w0 * g.horizon * g.horizon / 2;
    EXPECT_NEAR(G / closed, (m + 1.0) / m, 1e-6) << "m = " << m;
  }
}

// The network generator (example 7.6): every fiber starts within the start band of its family's
// low face, stays in the box, ends on the far face, steps `step` at a time (the last one shorter);
// the in-plane angles of its steps have the standard deviation asked for; the same seed gives the
// same paths, another seed others; fibers passing within a horizon are bonded (cross-links).
TEST(Fiber, NetworkPathsFollowTheirFamilies) {
  auto text = [](int seed) {
    return "name: n\nmaterials:\n  p: {model: pmb, density: 1200, youngs_modulus: 1.5e9}\n"
           "bodies:\n  net:\n    kind: fiber\n    material: p\n    network:\n"
           "      box: {min: [0, 0, 0], max: [200.0e-9, 200.0e-9, 5.0e-9]}\n"
           "      families: [{direction: x, count: 20}, {direction: y, count: 20}]\n"
           "      deviation: 0.15\n      step: 4.0e-9\n      start_band: 2.0e-9\n      seed: " +
           std::to_string(seed) + "\n    diameter: 2.0e-9\n    spacing: 1.0e-9\n"
           "stages:\n  - {name: r, steps: 1}\n";
  };
  const Scene scene = parse_scene(text(1), "network");
  const auto paths = fiber_paths(scene.bodies[0]);
  ASSERT_EQ(paths.size(), 40u);
  const double lo[3] = {0, 0, 0}, hi[3] = {200e-9, 200e-9, 5e-9}, step = 4e-9;
  double sum2 = 0;
  long steps = 0;
  for (std::size_t f = 0; f < paths.size(); ++f) {
    const int a = f < 20 ? 0 : 1, t = 1 - a;
    const auto& path = paths[f];
    EXPECT_LE(path.front()[a], lo[a] + 2e-9 + 1e-18) << "fiber " << f;
    EXPECT_DOUBLE_EQ(path.back()[a], hi[a]) << "fiber " << f;
    for (std::size_t k = 0; k < path.size(); ++k) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_GE(path[k][c], lo[c] - 1e-18);
        EXPECT_LE(path[k][c], hi[c] + 1e-18);
      }
      if (k == 0) continue;
      const double d[3] = {path[k][0] - path[k - 1][0], path[k][1] - path[k - 1][1], path[k][2] - path[k - 1][2]};
      const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      EXPECT_GT(d[a], 0.0);
      if (k + 1 < path.size()) {
        // Mirroring at a side face keeps the length only when it does not fold the step; in a
        // 200 nm wide box that is rare: all steps but the last are `step` long to 1e-9, or shorter.
        EXPECT_LE(len, step * (1 + 1e-9));
        const double theta = std::atan2(d[t], d[a]);
        sum2 += theta * theta;
        ++steps;
      }
    }
  }
  const double sigma = std::sqrt(sum2 / steps);
  EXPECT_GT(steps, 1500);
  EXPECT_NEAR(sigma, 0.15, 0.15 * 0.06) << steps << " steps";
  EXPECT_EQ(fiber_paths(parse_scene(text(1), "again").bodies[0]), paths);
  EXPECT_NE(fiber_paths(parse_scene(text(2), "other").bodies[0]), paths);
  // Nodes per path, and cross-links: bonds between nodes of different fibers.
  const Nodes nodes = discretize(scene);
  const BodyGeometry& g = nodes.bodies[0];
  ASSERT_EQ(g.path_first.size(), 41u);
  EXPECT_EQ(g.path_first.back(), nodes.size());
  const CellList cells(nodes, reach(g));
  std::vector<std::int64_t> ids;
  std::vector<double> w;
  std::vector<int> fiber_of(nodes.size());
  for (std::size_t f = 0; f + 1 < g.path_first.size(); ++f)
    for (std::int64_t k = g.path_first[f]; k < g.path_first[f + 1]; ++k) fiber_of[k] = static_cast<int>(f);
  long cross = 0;
  for (std::int64_t i = 0; i < nodes.size(); ++i) {
    neighbours_of(nodes, cells, i, ids, w);
    for (std::int64_t j : ids) cross += fiber_of[j] != fiber_of[i];
  }
  EXPECT_GT(cross, 100);  // 20 x 20 crossings, most within a horizon in a 5 nm thick box
  std::printf("network: %lld nodes, %ld ordered cross-link bonds, step angle sigma %.4f over %ld steps\n",
              static_cast<long long>(nodes.size()), cross, sigma, steps);
}

// A table of nodes of two fibers with segments, for the long-range kernel.
LongRangeTable random_table(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> U(0, 4e-9);
  LongRangeTable t;
  for (int k = 0; k < n; ++k) {
    t.natural.push_back(k);
    t.fiber.push_back(k < n / 2 ? 0 : 1);
    t.segment.push_back((k % (n / 2)) / 5);
    for (int c = 0; c < 3; ++c) t.X.push_back(U(rng));
    t.volume.push_back(3.9e-28 * (1 + 0.1 * (k % 3)));
  }
  return t;
}

LongRange long_range_spec() {
  LongRange lr;
  lr.length = 1e-9;
  lr.cutoff = 2.5e-9;
  lr.exclusion = 0;
  lr.pairs = {{{}, PairKind::AdjacentSegments, 2.6e35, 5.2e35},
              {{}, PairKind::DistantSegments, 0, -5.2e34},
              {{}, PairKind::OtherFibers, 1.0e35, 1.0e35},
              {{}, PairKind::OtherFibers, 9e99, 9e99}};  // never used: the first rule wins
  return lr;
}

// Forces are the exact negative gradient of the energy (finite differences, no pair near the
// cutoff), and sum to zero with the nodes' measures (eq. 34's symmetry conserves momentum).
TEST(LongRange, ForcesAreTheNegativeGradientAndConserveMomentum) {
  std::mt19937 rng(11);
  LongRangeTable t = random_table(40, rng);
  const PairLaw law(long_range_spec());
  std::vector<double> x = t.X;
  std::vector<std::int64_t> all(t.size());
  for (std::int64_t p = 0; p < t.size(); ++p) all[p] = p;
  // Keep the nodes apart (no pair closer than 0.8 a) and no pair within 1e-3 a of the cutoff.
  auto total_energy = [&](const std::vector<double>& pos, std::vector<double>* f) {
    std::vector<double> force(3 * t.size(), 0.0);
    LongRangeList list;
    const double E = long_range_forces(law, t, pos.data(), all, force.data(), list);
    if (f) *f = force;
    return E;
  };
  for (std::int64_t p = 0; p < t.size(); ++p)
    for (std::int64_t q = 0; q < p; ++q) {
      double d2 = 0;
      for (int c = 0; c < 3; ++c) d2 += std::pow(x[3 * p + c] - x[3 * q + c], 2);
      if (std::sqrt(d2) < 0.8e-9) x[3 * p] += 5e-9;  // move p away along x
    }
  std::vector<double> f;
  const double E0 = total_energy(x, &f);
  EXPECT_NE(E0, 0.0);
  double momentum[3] = {0, 0, 0}, scale = 0;
  for (std::int64_t p = 0; p < t.size(); ++p)
    for (int c = 0; c < 3; ++c) {
      momentum[c] += f[3 * p + c] * t.volume[p];
      scale += std::fabs(f[3 * p + c] * t.volume[p]);
    }
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::fabs(momentum[c]), 1e-12 * scale);
  ASSERT_GT(scale, 0);
  const double h = 1e-15;
  int checked = 0;
  for (std::int64_t p = 0; p < t.size(); p += 3)
    for (int c = 0; c < 3; ++c) {
      std::vector<double> xp = x, xm = x;
      xp[3 * p + c] += h;
      xm[3 * p + c] -= h;
      const double dE = (total_energy(xp, nullptr) - total_energy(xm, nullptr)) / (2 * h);
      const double force = f[3 * p + c] * t.volume[p];  // N
      if (std::fabs(force) < 1e-6 * scale / t.size()) continue;
      EXPECT_NEAR(-dE / force, 1.0, 1e-5) << "node " << p << " component " << c;
      ++checked;
    }
  EXPECT_GT(checked, 10);
}

// Which pairs interact and with which coefficients: one segment never; adjacent and distant
// segments and other fibers by their rule; none closer than the exclusion in the reference
// configuration; none beyond the cutoff; the energy shifted to zero at the cutoff.
// The contact step of a rule with a well (pair_contact_steps): with the cutoff between the well's
// bottom a and hypot(sigma, ds), one partner node counts, at the potential's zero sigma =
// a 2^(-1/6) (alpha = beta / 2), and dt = sqrt(2 rho / (114 beta^2 / (alpha sigma^2) V)),
// V = pi d^2 / 4 ds. A repulsive rule and a well beyond its cutoff give none.
TEST(LongRange, ContactStepOfARuleWithAWell) {
  const Scene scene = parse_scene(
      "name: c\nmaterials:\n  p: {model: pmb, density: 3000, youngs_modulus: 1.0e9}\n"
      "bodies:\n  fiber: {kind: fiber, material: p, path: [[0, 0, 0], [20.0e-9, 0, 0]], diameter: 1.0e-9, "
      "spacing: 0.5e-9, segment_length: 7.0e-9}\n"
      "long_range:\n  length: 1.0e-9\n  cutoff: 1.01e-9\n  pairs:\n"
      "    - {between: adjacent_segments, alpha: 0, beta: -1.0e30}\n"
      "    - {between: distant_segments, alpha: 1.0e30, beta: 2.0e30, cutoff: 0.99e-9}\n"
      "    - {between: other_fibers, alpha: 1.0e30, beta: 2.0e30}\n"
      "stages:\n  - {name: r, steps: 1}\n",
      "contact");
  const std::vector<PairContactStep> steps = pair_contact_steps(scene);
  ASSERT_EQ(steps.size(), 1u);
  EXPECT_EQ(steps[0].rule, 2);
  EXPECT_EQ(steps[0].body, "fiber");
  const double sigma = 1.0e-9 * std::pow(0.5, 1.0 / 6.0), volume = 0.25 * kPi * 1e-18 * 0.5e-9;
  EXPECT_NEAR(steps[0].sigma, sigma, 1e-12 * sigma);
  const double k = 114.0 * 2.0e30 * 2.0e30 / (1.0e30 * sigma * sigma);
  EXPECT_NEAR(k, LennardJonesPair({1.0e30, 2.0e30, 1.0e-9}).stiffness(sigma), 1e-10 * k);
  const double dt = std::sqrt(2.0 * 3000 / (k * volume));
  EXPECT_NEAR(steps[0].dt, dt, 1e-12 * dt);
  // With the bonds' bound equal to it, the two allow dt / sqrt(2); a step of more than half of
  // that is flagged, and a contact far softer than the bonds never is.
  EXPECT_NEAR(steps[0].with_bonds(dt), dt / std::sqrt(2.0), 1e-12 * dt);
  EXPECT_TRUE(steps[0].exceeded_by(0.36 * dt, dt));
  EXPECT_FALSE(steps[0].exceeded_by(0.35 * dt, dt));
  EXPECT_FALSE(steps[0].exceeded_by(0.99e-3 * dt, 1e-3 * dt));
}

TEST(LongRange, PairRules) {
  LongRangeTable t;
  auto add = [&](int body, int segment, double x, double X) {
    t.natural.push_back(t.size());
    t.fiber.push_back(body);
    t.segment.push_back(segment);
    t.X.insert(t.X.end(), {X, 0, 0});
    t.volume.push_back(1e-27);
    return std::vector<double>{x, 0.0, 0.0};
  };
  const LongRange spec = long_range_spec();
  const PairLaw law(spec);
  const double y = 1.3e-9;
  struct Case {
    int body_q, segment_q;
    double X_q;
    int kind;  // expected PairKind, -1: no force
  } cases[] = {{0, 0, 5e-9, -1},                                     // same segment
               {0, 1, 5e-9, int(PairKind::AdjacentSegments)},  // adjacent
               {0, 3, 5e-9, int(PairKind::DistantSegments)},   // distant
               {1, 0, 5e-9, int(PairKind::OtherFibers)},       // another fiber
               {1, 0, 0.5e-9, -1}};                                  // within the exclusion (set below)
  for (const Case& k : cases) {
    t = LongRangeTable{};
    std::vector<double> x = add(0, 0, 0.0, 0.0);
    const std::vector<double> xq = add(k.body_q, k.segment_q, y, k.X_q);
    x.insert(x.end(), xq.begin(), xq.end());
    LongRange s = spec;
    s.exclusion = 1e-9;
    const PairLaw l(s);
    std::vector<double> f(6, 0.0);
    LongRangeList list;
    const double E = long_range_forces(l, t, x.data(), {0, 1}, f.data(), list);
    if (k.kind < 0) {
      EXPECT_EQ(f[0], 0.0);
      EXPECT_EQ(E, 0.0);
      continue;
    }
    const PairKind pk = static_cast<PairKind>(k.kind);
    EXPECT_NEAR(f[0], law.force(pk, y) * 1e-27, 1e-12 * std::fabs(law.force(pk, y) * 1e-27));
    EXPECT_EQ(f[3], -f[0]);
    EXPECT_NEAR(E, (law.energy(pk, y) - law.energy(pk, spec.cutoff)) * 1e-54,
                1e-12 * std::fabs(law.energy(pk, y) * 1e-54));
  }
  // Beyond the cutoff: nothing.
  t = LongRangeTable{};
  std::vector<double> x = add(0, 0, 0.0, 0.0);
  const std::vector<double> xq = add(0, 1, 2.6e-9, 5e-9);
  x.insert(x.end(), xq.begin(), xq.end());
  std::vector<double> f(6, 0.0);
  LongRangeList list;
  EXPECT_EQ(long_range_forces(law, t, x.data(), {0, 1}, f.data(), list), 0.0);
  EXPECT_EQ(f[0], 0.0);
  // eq. (35): w2'(y) = -12 alpha/a (a/y)^13 + 6 beta/a (a/y)^7, zero at y = (2 alpha/beta)^(1/6) a.
  EXPECT_NEAR(law.force(PairKind::AdjacentSegments, 1e-9), 0.0, 1e-6 * 12 * 2.6e35 / 1e-9);
  EXPECT_GT(law.force(PairKind::AdjacentSegments, 1.5e-9), 0.0);  // attracts beyond the minimum
  EXPECT_LT(law.force(PairKind::DistantSegments, 1.5e-9), 0.0);   // negative beta: repels
}

// Nodes flung apart by a failing run (1e300 m, 1e309 cutoffs across) still get their cells: the
// cell counts do not overflow, and the pair within the cutoff is found beside them.
TEST(LongRange, CellsHoldNodesFarApart) {
  LongRangeTable t;
  for (int k = 0; k < 4; ++k) {
    t.natural.push_back(k);
    t.fiber.push_back(k);  // other fibers: every pair within the cutoff interacts
    t.segment.push_back(0);
    t.X.insert(t.X.end(), {1e-8 * k, 0, 0});
    t.volume.push_back(1e-27);
  }
  const PairLaw law(long_range_spec());
  const double y = 1.3e-9;
  const std::vector<double> x = {-1e300, 0, 0, 0, 0, 0, y, 0, 0, 0, 1e300, -1e300};
  std::vector<double> f(12, 0.0);
  LongRangeList list;
  long_range_forces(law, t, x.data(), {0, 1, 2, 3}, f.data(), list);
  EXPECT_EQ(list.begin, (std::vector<std::int64_t>{0, 0, 1, 2, 2}));
  const double expected = law.force(PairKind::OtherFibers, y) * 1e-27;
  EXPECT_NEAR(f[3], expected, 1e-12 * std::fabs(expected));
  EXPECT_EQ(f[6], -f[3]);
  EXPECT_EQ(f[0], 0.0);
  EXPECT_EQ(f[9], 0.0);
}

// A segments rule selects exactly its pair of segments of one fiber, in either order, whatever
// its place among the rules (it overrides the adjacent or distant rule for that pair and nothing
// else, never across fibers); its own cutoff holds for its pairs, the section's for the others;
// the energy is shifted by w2 at the rule's own cutoff; the neighbour list reaches the largest.
TEST(LongRange, SegmentsRuleOverridesTheKindRuleForItsPairOnly) {
  LongRange spec = long_range_spec();
  spec.pairs.resize(3);  // adjacent, distant, other fibers: cutoff 2.5 nm
  PairRule ends{{}, PairKind::Segments, 1.0e36, 3.0e36};
  ends.segments[0] = 3;
  ends.segments[1] = 0;
  ends.cutoff = 8e-9;
  PairRule near{{}, PairKind::Segments, 4.0e35, 7.0e35};  // an adjacent pair, default cutoff
  near.segments[0] = 2;
  near.segments[1] = 3;
  PairRule later = ends;  // the same pair again: the first rule wins
  later.alpha = later.beta = 9e99;
  spec.pairs.insert(spec.pairs.begin(), ends);  // before the kind rules
  spec.pairs.push_back(near);
  spec.pairs.push_back(later);
  const PairLaw law(spec);
  ASSERT_EQ(law.rules(), 5);  // three kinds, two pairs of segments
  EXPECT_EQ(law.reach, 8e-9);
  EXPECT_EQ(law.cutoffs[0], 2.5e-9);

  LongRangeTable t;
  auto two_nodes = [&](int fiber_q, int segment_p, int segment_q) {
    t = LongRangeTable{};
    t.natural = {0, 1};
    t.fiber = {0, fiber_q};
    t.segment = {segment_p, segment_q};
    t.X = {0, 0, 0, 20e-9, 0, 0};  // far apart in the reference configuration: no exclusion
    t.volume = {1e-27, 1e-27};
  };
  // Which rule: the ends' rule for (0, 3) and (3, 0) only; the adjacent pair (2, 3) by its rule.
  two_nodes(0, 0, 3);
  const int ends_rule = law.rule_of(t, 0, 1);
  EXPECT_GE(ends_rule, 3);
  EXPECT_EQ(law.rule_of(t, 1, 0), ends_rule);
  EXPECT_EQ(law.potentials[ends_rule].alpha, 1.0e36);
  two_nodes(0, 3, 0);
  EXPECT_EQ(law.rule_of(t, 0, 1), ends_rule);
  two_nodes(0, 1, 3);
  EXPECT_EQ(law.rule_of(t, 0, 1), int(PairKind::DistantSegments));
  two_nodes(0, 0, 4);
  EXPECT_EQ(law.rule_of(t, 0, 1), int(PairKind::DistantSegments));
  two_nodes(0, 0, 1);
  EXPECT_EQ(law.rule_of(t, 0, 1), int(PairKind::AdjacentSegments));
  two_nodes(0, 3, 4);
  EXPECT_EQ(law.rule_of(t, 0, 1), int(PairKind::AdjacentSegments));
  two_nodes(0, 2, 3);
  const int near_rule = law.rule_of(t, 0, 1);
  EXPECT_GE(near_rule, 3);
  EXPECT_NE(near_rule, ends_rule);
  EXPECT_EQ(law.potentials[near_rule].beta, 7.0e35);
  two_nodes(1, 0, 3);  // segments 0 and 3 of two fibers: the other-fibers rule
  EXPECT_EQ(law.rule_of(t, 0, 1), int(PairKind::OtherFibers));
  two_nodes(0, 3, 3);
  EXPECT_EQ(law.rule_of(t, 0, 1), -1);

  // Forces and energies through the kernel, against eq. (35) and the shifted eq. (33).
  struct Case {
    int segment_p, segment_q;
    double y;
    int rule;  // expected, -1: no force
  } cases[] = {{0, 3, 1.3e-9, ends_rule}, {3, 0, 6.0e-9, ends_rule},  // beyond 2.5 nm, within 8 nm
               {0, 3, 8.1e-9, -1},                                     // beyond the rule's cutoff
               {1, 3, 1.3e-9, int(PairKind::DistantSegments)},
               {1, 3, 6.0e-9, -1},                                     // beyond the section's cutoff
               {2, 3, 1.3e-9, near_rule},
               {2, 3, 2.6e-9, -1}};
  for (const Case& k : cases) {
    two_nodes(0, k.segment_p, k.segment_q);
    const std::vector<double> x = {0, 0, 0, k.y, 0, 0};
    std::vector<double> f(6, 0.0);
    LongRangeList list;
    const double E = long_range_forces(law, t, x.data(), {0, 1}, f.data(), list);
    if (k.rule < 0) {
      EXPECT_EQ(f[0], 0.0) << k.segment_p << " " << k.segment_q << " at " << k.y;
      EXPECT_EQ(E, 0.0);
      continue;
    }
    const LennardJonesPair w = law.potentials[k.rule];
    const double cut = law.cutoffs[k.rule];
    EXPECT_NEAR(f[0], w.force(k.y) * 1e-27, 1e-12 * std::fabs(w.force(k.y) * 1e-27));
    EXPECT_EQ(f[3], -f[0]);
    EXPECT_NEAR(E, (w.energy(k.y) - w.energy(cut)) * 1e-54, 1e-12 * std::fabs(w.energy(k.y) * 1e-54));
  }
  // The Verlet list reaches the rule's cutoff: nodes of segments 0 and 3 that start 10 nm apart
  // and close to 6 nm are found after the rebuild.
  two_nodes(0, 0, 3);
  LongRangeList list;
  std::vector<double> f(6, 0.0), x = {0, 0, 0, 10e-9, 0, 0};
  EXPECT_EQ(long_range_forces(law, t, x.data(), {0, 1}, f.data(), list), 0.0);
  x[3] = 6e-9;
  f.assign(6, 0.0);
  EXPECT_LT(long_range_forces(law, t, x.data(), {0, 1}, f.data(), list), 0.0);
  EXPECT_GT(f[0], 0.0);  // attracts: node 0 pulled towards +x
  EXPECT_EQ(list.builds, 2);
}

// Segment indices are checked against the fibers' segment counts at setup.
TEST(LongRange, SegmentsRuleIndicesWithinTheFiber) {
  LongRangeTable t;
  for (int k = 0; k < 20; ++k) {
    t.natural.push_back(k);
    t.fiber.push_back(0);
    t.segment.push_back(k / 4);  // 5 segments
    t.X.insert(t.X.end(), {k * 1e-9, 0, 0});
    t.volume.push_back(1e-27);
  }
  LongRange spec = long_range_spec();
  PairRule r{{"scene.yaml", 12}, PairKind::Segments, 1, 1};
  r.segments[0] = 0;
  r.segments[1] = 4;
  r.segments_where = {"scene.yaml", 12};
  r.segments_key = "long_range.pairs.4.segments";
  spec.pairs.push_back(r);
  EXPECT_NO_THROW(check_segment_rules(spec, t));
  spec.pairs.back().segments[1] = 5;
  try {
    check_segment_rules(spec, t);
    ADD_FAILURE() << "index 5 of a fiber of 5 segments accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "scene.yaml:12: long_range.pairs.4.segments: expected segment indices 0 to 4 (the fiber "
                           "has 5 segments), got [0, 5]");
  }
}

// An exclusion that holds every pair a rule applies to is refused at setup, naming the rule; one
// pair at the exclusion or beyond lets the rule act.
TEST(LongRange, ExclusionThatHoldsEveryPairOfARule) {
  LongRangeTable t;
  for (int k = 0; k < 40; ++k) {  // fiber 0 along x, fiber 1 parallel 100 nm away; segments of 4 nodes
    t.natural.push_back(k);
    t.fiber.push_back(k / 20);
    t.segment.push_back((k % 20) / 4);
    t.X.insert(t.X.end(), {(k % 20) * 1e-9, k < 20 ? 0.0 : 1e-7, 0});
    t.volume.push_back(1e-27);
  }
  LongRange spec = long_range_spec();
  spec.where = {"scene.yaml", 3};
  spec.exclusion = 6.9e-9;  // adjacent segments' nodes lie up to 7 nm apart
  EXPECT_NO_THROW(check_pair_rules(spec, PairLaw(spec), t));
  spec.exclusion = 7.1e-9;
  spec.exclusion_where = {"scene.yaml", 5};
  try {
    check_pair_rules(spec, PairLaw(spec), t);
    ADD_FAILURE() << "an adjacent_segments rule that never acts accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "scene.yaml:5: long_range.exclusion: every pair of nodes that long_range.pairs.0 "
                           "(between: adjacent_segments) applies to lies closer than the exclusion, 7.1e-09 m, "
                           "in the reference configuration, so the rule never acts; expected an exclusion shorter "
                           "than the distance between the nodes it should pull or push (about the fibers' horizon)");
  }
  // A segments rule: segments 0 and 1 (7 nm apart at most) under the default exclusion.
  spec.pairs.erase(spec.pairs.begin());
  PairRule r{{"scene.yaml", 9}, PairKind::Segments, 1, 1};
  r.segments[0] = 1;
  r.segments[1] = 0;
  spec.pairs.push_back(r);
  spec.exclusion_where = {};
  try {
    check_pair_rules(spec, PairLaw(spec), t);
    ADD_FAILURE() << "a segments rule that never acts accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("scene.yaml:3: long_range.exclusion: every pair of nodes that long_range.pairs.3 (between: "
                         "segments [1, 0], scene.yaml:9) applies to lies closer than the exclusion, 7.1e-09 m (the "
                         "default: the largest fiber horizon)", 0), 0u) << what;
  }
  spec.pairs.back().segments[1] = 3;  // 1 and 3: up to 11 nm apart, it acts
  EXPECT_NO_THROW(check_pair_rules(spec, PairLaw(spec), t));
  spec.exclusion = 1e-6;  // every rule's pairs, the other fibers' included
  EXPECT_THROW(check_pair_rules(spec, PairLaw(spec), t), InputError);
}

// Rules that reach no pair: a section none of whose rules applies to any pair is refused, naming
// each rule and why; one that applies to nothing beside others that act, and a rule an earlier
// one shadows, are warned about, one line each.
TEST(LongRange, RulesThatReachNoPair) {
  LongRangeTable t;
  for (int k = 0; k < 20; ++k) {  // one fiber along x, one segment
    t.natural.push_back(k);
    t.fiber.push_back(0);
    t.segment.push_back(0);
    t.X.insert(t.X.end(), {k * 1e-9, 0, 0});
    t.volume.push_back(1e-27);
  }
  LongRange spec = long_range_spec();  // adjacent, distant, other fibers (twice)
  spec.where = {"scene.yaml", 3};
  try {
    check_pair_rules(spec, PairLaw(spec), t);
    ADD_FAILURE() << "a section that reaches no pair accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "scene.yaml:3: long_range: no rule applies to any pair of nodes, so the section never acts: "
                 "long_range.pairs.0 (between: adjacent_segments) applies to no pair of the scene's fiber nodes: "
                 "each fiber is one segment (a fiber body's segment_length is 0, the default, or not shorter than "
                 "its fiber); long_range.pairs.1 (between: distant_segments) applies to no pair of the scene's "
                 "fiber nodes: each fiber is one segment (a fiber body's segment_length is 0, the default, or not "
                 "shorter than its fiber); long_range.pairs.2 (between: other_fibers) applies to no pair of the "
                 "scene's fiber nodes: the scene has one fiber; expected a rule for the scene's pairs "
                 "(adjacent_segments and distant_segments need fibers cut into segments by segment_length, "
                 "other_fibers two fibers)");
  }
  for (int k = 0; k < 20; ++k) t.segment[static_cast<std::size_t>(k)] = k / 10;  // two segments
  const std::vector<std::string> w = check_pair_rules(spec, PairLaw(spec), t);
  ASSERT_EQ(w.size(), 3u);
  EXPECT_EQ(w[0], "long_range.pairs.1 (between: distant_segments) applies to no pair of the scene's fiber nodes: "
                  "no fiber has more than two segments (a fiber body's segment_length is 0, the default, or not "
                  "shorter than its fiber)");
  EXPECT_EQ(w[1], "long_range.pairs.2 (between: other_fibers) applies to no pair of the scene's fiber nodes: the "
                  "scene has one fiber");
  EXPECT_EQ(w[2], "long_range.pairs.3 (between: other_fibers) is never used: long_range.pairs.2 (between: "
                  "other_fibers) comes first for the same pairs, and the first rule wins");
  for (int k = 0; k < 20; ++k) t.segment[static_cast<std::size_t>(k)] = k / 4;  // five segments
  spec.pairs.pop_back();
  for (int k = 10; k < 20; ++k) t.fiber[static_cast<std::size_t>(k)] = 1;  // and two fibers
  EXPECT_TRUE(check_pair_rules(spec, PairLaw(spec), t).empty());
}

}  // namespace
}  // namespace peri

namespace peri {

// The long-range halo's boxes (stages/long_range_halo.hpp): every point lies in one of them, at
// most kBoxes are used, and points in two far clusters get boxes that leave the gap between them
// out (one bounding box would send the whole gap's nodes); no point, no box.
TEST(LongRangeHalo, BoxesHoldEveryPointAndLeaveGapsOut) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(0, 1e-8);
  std::vector<double> x;
  for (int k = 0; k < 1000; ++k) {
    const double shift = k % 2 ? 1e-6 : 0.0;  // two clusters 1 um apart along x, 10 nm wide
    x.insert(x.end(), {U(rng) + shift, U(rng), U(rng)});
  }
  const auto boxes = LongRangeHalo::boxes_of(x.data(), 1000);
  int used = 0;
  double volume = 0;
  for (const LongRangeHalo::Box& b : boxes) {
    if (b.lo[0] > b.hi[0]) continue;
    ++used;
    volume += (b.hi[0] - b.lo[0]) * (b.hi[1] - b.lo[1]) * (b.hi[2] - b.lo[2]);
  }
  EXPECT_EQ(used, LongRangeHalo::kBoxes);
  EXPECT_LT(volume, 2 * 1e-24);  // the two clusters' volume, not the 1 um x 10 nm x 10 nm hull's
  for (int k = 0; k < 1000; ++k) {
    bool inside = false;
    for (const LongRangeHalo::Box& b : boxes) {
      bool in = true;
      for (int d = 0; d < 3; ++d) in = in && b.lo[d] <= x[3 * k + d] && x[3 * k + d] <= b.hi[d];
      inside = inside || in;
    }
    EXPECT_TRUE(inside) << "point " << k;
  }
  for (const LongRangeHalo::Box& b : LongRangeHalo::boxes_of(nullptr, 0)) EXPECT_GT(b.lo[0], b.hi[0]);
  const auto one = LongRangeHalo::boxes_of(x.data(), 1);
  EXPECT_EQ(one[0].lo[1], x[1]);
  EXPECT_EQ(one[0].hi[1], x[1]);
  EXPECT_GT(one[1].lo[0], one[1].hi[0]);
}

}  // namespace peri
