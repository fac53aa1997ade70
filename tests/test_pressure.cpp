// The follower pressure on a sphere's triangles (loads/pressure.cpp): on a closed surface the
// forces sum to zero and their moment sum_i F_i . x_i is 3 p times the enclosed volume (the
// divergence theorem: the closed-surface integral of x . n is 3 V); a node whose bonds are all
// broken takes its triangles' shares from every corner, so the forces then sum to minus p times
// the opening's area vector; and each triangle's three shares are one vector, the same bits.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "peri/bonds/bonds.hpp"
#include "peri/diagnostics/energies.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/loads/pressure.hpp"
#include "peri/partition/domain.hpp"
#include "peri/partition/partition.hpp"
#include "peri/scene/scene.hpp"

namespace peri {
namespace {

constexpr double kPressure = 2.5e5;

struct Balloon {
  Scene scene;
  Nodes nodes;
  Domain d;
  std::vector<double> x;  // current positions, planes x, y, z (the reference ones)
  Balloon() {
    scene = parse_scene(
        "name: p\nmaterials:\n  m: {model: membrane, density: 1200, bulk_modulus: 8.0e8, critical_stretch: 1.75}\n"
        "bodies:\n  b: {kind: sphere, material: m, center: [0.01, -0.02, 0.03], radius: 0.1, thickness: 0.001,"
        " spacing: 0.02, pressure: 2.5e5}\n"
        "stages:\n  - {name: r, steps: 1}\n",
        "pressure-test");
    nodes = discretize(scene);
    const CellList cells(nodes, reach(nodes.bodies[0]));
    const Partition part = partition_from_parts(nodes, std::vector<int>(nodes.size(), 0), 1);
    d = build_domain(scene, nodes, cells, part, 0);
    const std::int64_t n = d.local();
    x.resize(3 * n);
    for (std::int64_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) x[c * n + i] = d.X[3 * i + c];
  }
  // The pressure's force [N] on each owned node (force density times measure).
  std::vector<double> forces() {
    Pressure pressure(scene, nodes.bodies, d);
    std::vector<double> density(3 * static_cast<std::size_t>(d.owned), 0.0);
    LoadTarget target{x.data(), d.local(), density.data(), 1e-7};
    EnergyLedger ledger;
    pressure.add_forces(1.0, target, false, ledger);
    for (std::int32_t i = 0; i < d.owned; ++i)
      for (int c = 0; c < 3; ++c) density[3 * i + c] *= d.volume[i];
    return density;
  }
  std::array<double, 3> at(std::int64_t natural) const {
    for (std::int32_t i = 0; i < d.local(); ++i)
      if (d.natural[i] == natural) return {d.X[3 * i], d.X[3 * i + 1], d.X[3 * i + 2]};
    return {NAN, NAN, NAN};
  }
};

std::array<double, 3> cross(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
std::array<double, 3> minus(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}

TEST(Pressure, ClosedSphereNetForceZeroAndMomentThreePressureTimesVolume) {
  Balloon s;
  const std::vector<double> f = s.forces();
  ASSERT_EQ(s.d.owned, s.nodes.size());
  double net[3] = {0, 0, 0}, moment = 0, scale = 0;
  for (std::int32_t i = 0; i < s.d.owned; ++i)
    for (int c = 0; c < 3; ++c) {
      net[c] += f[3 * i + c];
      moment += f[3 * i + c] * s.d.X[3 * i + c];
      scale += std::abs(f[3 * i + c]);
    }
  // The polyhedron's volume from its triangles (each a tetrahedron with the origin).
  double volume = 0;
  for (const auto& t : s.nodes.bodies[0].triangles) {
    const auto a = s.at(t[0]), b = s.at(t[1]), c = s.at(t[2]);
    const auto bc = cross(b, c);
    volume += (a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2]) / 6.0;
  }
  ASSERT_GT(volume, 0.9 * 4.0 / 3.0 * M_PI * 1e-3);  // counter-clockwise from outside
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(net[c]), 1e-13 * scale) << "component " << c;
  EXPECT_NEAR(moment, 3.0 * kPressure * volume, 1e-12 * 3.0 * kPressure * volume);
}

TEST(Pressure, NodeWithAllBondsBrokenOpensItsTrianglesForEveryCorner) {
  Balloon s;
  const std::int32_t hole = 7;  // a local node; break its bonds both ways
  for (std::int32_t i = 0; i < s.d.owned; ++i)
    for (std::int64_t q = s.d.bonds.offsets[i]; q < s.d.bonds.offsets[i + 1]; ++q)
      if (i == hole || s.d.bonds.neighbor[q] == hole) {
        s.d.bonds.broken[q] |= 1;
        s.d.bonds.row_broken[i] = 1;
      }
  const std::vector<double> f = s.forces();
  for (int c = 0; c < 3; ++c) EXPECT_EQ(f[3 * hole + c], 0.0);
  // The opening: p times the area vectors of the triangles about the node, missing from the sum.
  std::array<double, 3> opening{0, 0, 0};
  int around = 0;
  for (const auto& t : s.nodes.bodies[0].triangles) {
    if (t[0] != s.d.natural[hole] && t[1] != s.d.natural[hole] && t[2] != s.d.natural[hole]) continue;
    const auto a = s.at(t[0]), b = s.at(t[1]), c = s.at(t[2]);
    const auto n = cross(minus(b, a), minus(c, a));
    for (int k = 0; k < 3; ++k) opening[k] += 0.5 * kPressure * n[k];
    ++around;
  }
  ASSERT_GE(around, 5);
  const double size = std::hypot(opening[0], opening[1], opening[2]);
  double net[3] = {0, 0, 0};
  for (std::int32_t i = 0; i < s.d.owned; ++i)
    for (int c = 0; c < 3; ++c) net[c] += f[3 * i + c];
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(net[c], -opening[c], 1e-10 * size) << "component " << c;
}

TEST(Pressure, ATrianglesThreeSharesAreTheSameBits) {
  // Break every bond but those of one triangle's edges: each corner then keeps that triangle
  // alone (its other triangles lose an edge at that corner), and the three get one force. Every
  // triangle of the sphere in turn.
  const std::size_t triangles = Balloon().nodes.bodies[0].triangles.size();
  ASSERT_GT(triangles, 100u);
  for (std::size_t t = 0; t < triangles; ++t) {
    Balloon s;
    const auto& tri = s.nodes.bodies[0].triangles[t];
    std::array<std::int32_t, 3> local{-1, -1, -1};
    for (std::int32_t i = 0; i < s.d.local(); ++i)
      for (int k = 0; k < 3; ++k)
        if (s.d.natural[i] == tri[k]) local[k] = i;
    auto corner = [&](std::int32_t i) { return i == local[0] || i == local[1] || i == local[2]; };
    for (std::int32_t i = 0; i < s.d.owned; ++i) {
      for (std::int64_t q = s.d.bonds.offsets[i]; q < s.d.bonds.offsets[i + 1]; ++q)
        if (!(corner(i) && corner(s.d.bonds.neighbor[q]))) s.d.bonds.broken[q] |= 1;
      s.d.bonds.row_broken[i] = 1;
      s.d.volume[i] = 1.0;  // force density = force: the bits the sum gave
    }
    const std::vector<double> f = s.forces();
    const auto a = s.at(tri[0]), b = s.at(tri[1]), c = s.at(tri[2]);
    const auto n = cross(minus(b, a), minus(c, a));
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(f[3 * local[1] + k], f[3 * local[0] + k]) << "triangle " << t;
      ASSERT_EQ(f[3 * local[2] + k], f[3 * local[0] + k]) << "triangle " << t;
      ASSERT_NEAR(f[3 * local[0] + k], kPressure * n[k] / 6.0, 1e-12 * kPressure * std::hypot(n[0], n[1], n[2]));
    }
    int loaded = 0;
    for (std::int32_t i = 0; i < s.d.owned; ++i) loaded += f[3 * i] != 0 || f[3 * i + 1] != 0 || f[3 * i + 2] != 0;
    ASSERT_EQ(loaded, 3) << "triangle " << t;
  }
}

}  // namespace
}  // namespace peri
