// Cutouts of grid bodies and point-cloud solids (docs/user/scene-reference.md, `cutouts` and
// `points`), run under MPI at 1 and 2 ranks:
//  - a plate with a circular hole: its node count against a count of the grid's cell centres
//    outside the circle made here, no node inside the circle, the removed area against pi r^2
//    within the band of cells the circle crosses; the cut body no longer fills its box (no grid
//    stencil, no coordinate bisection);
//  - the same plate stretched homogeneously: no net force where families are whole, a force
//    pointing away from the hole at its rim, the strain energy the hole removes against the
//    energy density times its area plus the surface deficit measured on the plate's own edges;
//  - a point cloud written from a grid solid's nodes (with and without a spherical cutout) gives
//    the grid's strain energy and forces under a homogeneous deformation to round-off;
//  - a fracturing plate with a hole: the same positions and broken bonds on 1 and 2 ranks.
#include <gtest/gtest.h>
#include <petscsys.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "mpi_test.hpp"
#include "peri/bonds/bonds.hpp"
#include "peri/core/format.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/partition/partition.hpp"
#include "peri/stages/simulation.hpp"

namespace peri {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A 20 mm square sheet (origin -10 mm), spacing 0.25 mm (80 x 80 cells), with a hole of radius
// 5 mm off the grid's symmetry (centre (1.1, -0.7) mm).
constexpr double kHalf = 0.01, kDx = 2.5e-4, kHoleX = 0.0011, kHoleY = -0.0007, kHoleR = 0.005;
constexpr double kThickness = 5e-4, kBulk = 8e8, kStrain = 1e-3;

// half: the plate's half width (kHalf unless given).
std::string plate_scene(bool hole, double half = kHalf) {
  const std::string h = number_text(half), w = number_text(2 * half);
  return std::string(R"(
name: plate-hole
materials:
  rubber: {model: membrane, density: 1200, bulk_modulus: 8.0e8}
bodies:
  plate:
    kind: membrane
    material: rubber
    origin: [-)") + h + ", -" + h + R"(, 0]
    size: [)" + w + ", " + w + R"(]
    thickness: 0.0005
    spacing: 0.00025
)" + (hole ? "    cutouts:\n      - {kind: circle, center: [0.0011, -0.0007], radius: 0.005}\n" : "") + R"(
initial:
  displacement_gradient: [[0.001, 0, 0], [0, 0.001, 0], [0, 0, 0]]
stages:
  - {name: still, steps: 1, dt: 1.0e-9}
output: {frames: 1, series_every: 1}
)";
}

// The grid's cell centres outside the hole, counted here from the scene's numbers alone.
std::int64_t cells_outside_hole() {
  const int n = static_cast<int>(std::lround(2 * kHalf / kDx));
  std::int64_t count = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = -kHalf + (i + 0.5) * kDx - kHoleX, y = -kHalf + (j + 0.5) * kDx - kHoleY;
      if (x * x + y * y > kHoleR * kHoleR) ++count;
    }
  return count;
}

TEST(Cutouts, PlateWithAHoleHasTheNodesOutsideTheCircle) {
  const Scene scene = parse_scene(plate_scene(true), "plate.yaml");
  ASSERT_EQ(scene.bodies.at(0).cutouts.size(), 1u);
  // The resolved scene reads back to the same text, cutouts included.
  const std::string resolved = emit_scene(scene);
  EXPECT_NE(resolved.find("cutouts:\n      - {kind: circle, center: [0.0011, -0.0007], radius: 0.005}"),
            std::string::npos)
      << resolved;
  EXPECT_EQ(emit_scene(parse_scene(resolved, "resolved.yaml")), resolved);

  const Nodes nodes = discretize(scene);
  const std::int64_t expected = cells_outside_hole();
  EXPECT_EQ(nodes.size(), expected);
  EXPECT_EQ(nodes.bodies.at(0).count, expected);
  double nearest = HUGE_VAL, area = 0;
  for (std::int64_t i = 0; i < nodes.size(); ++i) {
    nearest = std::min(nearest, std::hypot(nodes.X[3 * i] - kHoleX, nodes.X[3 * i + 1] - kHoleY));
    area += nodes.volume[i] / kThickness;
    EXPECT_GT(nodes.volume[i], 0.0);
  }
  EXPECT_GT(nearest, kHoleR);          // no node inside the circle (nor on it)
  EXPECT_LT(nearest, kHoleR + kDx);    // and the rim is there
  // The removed cells lie between the circles of radius r -+ dx / sqrt(2) (a cell whose centre
  // is inside reaches at most that far out, and every cell within r - dx/sqrt(2) has its centre
  // inside): |removed - pi r^2| <= pi ((r + dx/sqrt(2))^2 - r^2).
  const double removed = 4 * kHalf * kHalf - area, circle = kPi * kHoleR * kHoleR;
  const double band = kPi * (std::pow(kHoleR + kDx / std::sqrt(2.0), 2) - kHoleR * kHoleR);
  if (world_rank() == 0)
    std::printf("plate with a hole: %lld nodes (%lld counted here); removed area %.6e m^2, pi r^2 %.6e m^2: "
                "difference %.2f cells (bound %.1f)\n",
                static_cast<long long>(nodes.size()), static_cast<long long>(expected), removed, circle,
                (removed - circle) / (kDx * kDx), band / (kDx * kDx));
  EXPECT_LE(std::fabs(removed - circle), band);
  // A cut grid no longer fills its box: no shared stencil, the cell-graph partitioner.
  EXPECT_FALSE(fills_its_box(nodes));
  EXPECT_EQ(resolve_partition_method(PartitionMethod::Auto, nodes), PartitionMethod::Cells);
  const CellList cells(nodes, reach(nodes.bodies[0]));
  EXPECT_EQ(cells.stencil(0), nullptr);
  const Nodes whole = discretize(parse_scene(plate_scene(false), "plate.yaml"));
  EXPECT_TRUE(fills_its_box(whole));
}

struct Stretched {
  std::vector<double> X, f;  // natural order
  double strain = 0;
};

// The plate at rest under the homogeneous equibiaxial stretch e: forces and strain energy.
Stretched stretched(bool hole, double half = kHalf) {
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(parse_scene(plate_scene(hole, half), "plate.yaml"), PETSC_COMM_WORLD, quiet);
  sim.begin();
  std::vector<double> f(3 * static_cast<std::size_t>(sim.domain().owned));
  sim.internal_force(f.data());
  Stretched s;
  s.f = sim.gather_natural(f.data(), 3);
  s.X = discretize(parse_scene(plate_scene(hole, half), "plate.yaml")).X;  // reference positions, natural order
  s.strain = sim.energies().strain;
  return s;
}

TEST(Cutouts, StretchedPlateFeelsTheHoleWithinTheHorizon) {
  const Stretched cut = stretched(true), full = stretched(false);
  const double delta = 3 * kDx, reach = delta + kDx / std::sqrt(2.0);
  // Forces: zero where a node's family is whole (beyond reach of the hole and of the edges), away
  // from the hole at its rim (the missing neighbours no longer pull towards it), none in total.
  double fmax = 0, interior = 0, sum[3] = {0, 0, 0};
  const std::size_t n = cut.f.size() / 3;
  for (std::size_t i = 0; i < n; ++i) {
    fmax = std::max(fmax, std::hypot(cut.f[3 * i], cut.f[3 * i + 1]));
    for (int c = 0; c < 3; ++c) sum[c] += cut.f[3 * i + c];
  }
  int rim = 0, outward = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = cut.X[3 * i], y = cut.X[3 * i + 1];
    const double rx = x - kHoleX, ry = y - kHoleY, r = std::hypot(rx, ry);
    const double edge = kHalf - std::max(std::fabs(x), std::fabs(y));
    const double fx = cut.f[3 * i], fy = cut.f[3 * i + 1];
    if (r > kHoleR + reach + 1e-9 && edge > reach + 1e-9) interior = std::max(interior, std::hypot(fx, fy));
    if (r < kHoleR + delta / 2) {
      ++rim;
      const double radial = (fx * rx + fy * ry) / r, tangential = std::fabs(fx * ry - fy * rx) / r;
      if (radial > 0 && tangential < radial) ++outward;
    }
  }
  // The energy the hole removes: the grid's energy density W over the removed area, plus the
  // bonds across the rim. Both come from whole plates of three widths L (same grid, no hole):
  // E(L) = W h (L^2 - 4 L L_s) + C, with L_s the deficit per unit length of a straight edge (the
  // bonds an edge node lacks) and C the corners'. The rim of the hole lacks the crossing bonds on
  // both sides, so it removes W h (A_removed + 2 pi r L_s) as far as the rim is straight.
  const double widths[3] = {kHalf, 1.5 * kHalf, 2 * kHalf};
  double m[3][4];
  for (int k = 0; k < 3; ++k) {
    const double L = 2 * widths[k];
    const double e = k == 0 ? full.strain : stretched(false, widths[k]).strain;
    m[k][0] = L * L * kThickness;
    m[k][1] = -4 * L * kThickness;
    m[k][2] = 1;
    m[k][3] = e;
  }
  for (int c = 0; c < 3; ++c)  // Gauss-Jordan elimination (3 x 3, well conditioned)
    for (int r = 0; r < 3; ++r) {
      if (r == c) continue;
      const double q = m[r][c] / m[c][c];
      for (int k = 0; k < 4; ++k) m[r][k] -= q * m[c][k];
    }
  const double W = m[0][3] / m[0][0], Ls = (m[1][3] / m[1][1]) / W;
  const double continuum = 2 * kBulk * kStrain * kStrain;
  const double removed_area = 4 * kHalf * kHalf - static_cast<double>(n) * kDx * kDx;
  const double ratio = (full.strain - cut.strain) / (W * kThickness * removed_area);
  const double predicted = 1 + 2 * kPi * kHoleR * Ls / removed_area;
  if (world_rank() == 0)
    std::printf("stretched plate: largest force %.3e N, in whole families %.3e N, total (%.1e, %.1e) N; %d of %d rim "
                "nodes pulled away from the hole; W = %.6f x 2 K e^2, edge deficit L_s = %.4f delta; energy removed by "
                "the hole %.5f x W h A_removed, %.5f predicted from L_s\n",
                fmax, interior, sum[0], sum[1], outward, rim, W / continuum, Ls / delta, ratio, predicted);
  EXPECT_LE(interior, 1e-10 * fmax);
  EXPECT_LE(std::hypot(sum[0], sum[1]), 1e-10 * fmax * static_cast<double>(n));
  EXPECT_GT(rim, 100);
  EXPECT_EQ(outward, rim);
  // The surface deficit is a fraction of the horizon; the hole's rim loses as much per unit
  // length as a straight edge, to the curvature's effect delta / r = 0.15 on the deficit (its
  // share of the ratio, predicted - 1, within 20%).
  EXPECT_NEAR(W / continuum, 1.0, 0.05);  // the grid's quadrature of the horizon (m = 3, partial areas)
  EXPECT_GT(Ls, 0.1 * delta);
  EXPECT_LT(Ls, 0.5 * delta);
  EXPECT_GT(ratio, 1.0);
  EXPECT_NEAR(ratio - 1, predicted - 1, 0.2 * (predicted - 1));
}

// ------------------------------------------------------------------------------------------------
// Point clouds.

const char* kBlock = R"(
name: block
materials:
  glass: {model: pmb, density: 2200, micromodulus: 1.0e19}
bodies:
  block: {kind: solid, material: glass, BODY, spacing: 0.001, horizon_factor: 3CUT}
initial:
  displacement_gradient: [[0.001, 0.0004, 0], [0, 0.002, -0.0003], [0.0002, 0, -0.0005]]
stages:
  - {name: still, steps: 1, dt: 1.0e-9}
output: {frames: 1, series_every: 1}
)";

std::string block_scene(const std::string& body, bool cut) {
  std::string s = kBlock;
  s.replace(s.find("BODY"), 4, body);
  s.replace(s.find("CUT"), 3, cut ? ", cutouts: [{kind: sphere, center: [0.004, 0.0041, 0.0039], radius: 0.0021}]" : "");
  return s;
}

struct Loaded {
  std::vector<double> X, f;
  double strain = 0;
  std::int64_t nodes = 0;
};

Loaded load(const std::string& text) {
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(parse_scene(text, "block.yaml"), PETSC_COMM_WORLD, quiet);
  sim.begin();
  std::vector<double> f(3 * static_cast<std::size_t>(sim.domain().owned));
  sim.internal_force(f.data());
  Loaded l;
  l.f = sim.gather_natural(f.data(), 3);
  l.X = sim.natural_positions();
  l.strain = sim.energies().strain;
  l.nodes = sim.summary().nodes;
  return l;
}

TEST(PointCloud, ReproducesTheGridSolid) {
  // The grid's nodes (8 mm cube, 1 mm spacing) written as a point cloud, shuffled rows would
  // change the natural order, so they keep the grid's: x fastest.
  const std::string grid = "origin: [0, 0, 0], size: [0.008, 0.008, 0.008]";
  const Nodes nodes = discretize(parse_scene(block_scene(grid, false), "block.yaml"));
  int size = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  const std::string file = "test_cutouts_cloud_np" + std::to_string(size) + ".csv";
  if (world_rank() == 0) {
    std::ofstream out(file);
    out << "# the nodes of an 8 mm cube at 1 mm spacing\nx,y,z,volume\n";
    char line[160];
    for (std::int64_t i = 0; i < nodes.size(); ++i) {
      std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,%.17g\n", nodes.X[3 * i], nodes.X[3 * i + 1],
                    nodes.X[3 * i + 2], nodes.volume[i]);
      out << line;
    }
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  const std::string cloud = "points: " + file;
  const Scene scene = parse_scene(block_scene(cloud, false), "block.yaml");
  EXPECT_EQ(scene.bodies.at(0).cloud.size(), static_cast<std::size_t>(nodes.size()));
  const std::string resolved = emit_scene(scene);
  EXPECT_EQ(emit_scene(parse_scene(resolved, "resolved.yaml")), resolved);
  const Nodes read = discretize(scene);
  EXPECT_FALSE(read.bodies.at(0).traits.grid);
  EXPECT_EQ(read.X, nodes.X);
  EXPECT_EQ(read.volume, nodes.volume);

  for (bool cut : {false, true}) {
    const Loaded a = load(block_scene(grid, cut)), b = load(block_scene(cloud, cut));
    ASSERT_EQ(a.nodes, b.nodes);
    ASSERT_EQ(a.f.size(), b.f.size());
    double fmax = 0, fdiff = 0, xdiff = 0;
    for (std::size_t k = 0; k < a.f.size(); ++k) {
      fmax = std::max(fmax, std::fabs(a.f[k]));
      fdiff = std::max(fdiff, std::fabs(a.f[k] - b.f[k]));
      xdiff = std::max(xdiff, std::fabs(a.X[k] - b.X[k]));
    }
    if (world_rank() == 0)
      std::printf("point cloud vs grid%s: %lld nodes, strain energy %.12e J vs %.12e J (relative %.1e), largest "
                  "force %.3e N, difference %.1e N\n",
                  cut ? " (sphere cut out)" : "", static_cast<long long>(a.nodes), a.strain, b.strain,
                  std::fabs(a.strain - b.strain) / a.strain, fmax, fdiff);
    EXPECT_EQ(xdiff, 0.0);
    // The grid snaps reference offsets to whole spacings; the cloud takes the differences of its
    // coordinates, which agree to a few ulps of the cube's size, and its rows (free: no family
    // patterns) do not round |xi|^2: a relative change of 1e-16 in a bond's length is one of
    // 1e-13 in its stretch (strains of 1e-3 here), 3e-12 of the energy as measured. Round-off only.
    EXPECT_NEAR(b.strain / a.strain, 1.0, 2e-11);
    EXPECT_LE(fdiff, 1e-9 * fmax);
    EXPECT_GT(a.strain, 0.0);
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  if (world_rank() == 0) std::remove(file.c_str());
}

// A point cloud as a spreadsheet saves it ("CSV UTF-8": a byte order mark first, CRLF line ends,
// the header capitalised) gives the same points as the plain file.
TEST(PointCloud, ReadsASpreadsheetsCsv) {
  int size = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  const std::string plain = "test_cutouts_plain_np" + std::to_string(size) + ".csv";
  const std::string sheet = "test_cutouts_sheet_np" + std::to_string(size) + ".csv";
  if (world_rank() == 0) {
    std::ofstream a(plain, std::ios::binary), b(sheet, std::ios::binary);
    a << "x,y,z,volume\n";
    b << "\xEF\xBB\xBFX,Y,Z,Volume\r\n";
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        char line[96];
        std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,1e-9", 0.001 * i, 0.001 * j, 0.0005 * (i + j));
        a << line << "\n";
        b << line << "\r\n";
      }
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  const Scene a = parse_scene(block_scene("points: " + plain, false), "block.yaml");
  const Scene b = parse_scene(block_scene("points: " + sheet, false), "block.yaml");
  ASSERT_EQ(a.bodies.at(0).cloud.size(), 16u);
  ASSERT_EQ(b.bodies.at(0).cloud.size(), 16u);
  for (std::size_t k = 0; k < 16; ++k) {
    EXPECT_EQ(a.bodies[0].cloud[k].x, b.bodies[0].cloud[k].x) << k;
    EXPECT_EQ(a.bodies[0].cloud[k].volume, b.bodies[0].cloud[k].volume) << k;
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  if (world_rank() == 0) std::remove(plain.c_str()), std::remove(sheet.c_str());
}

// ------------------------------------------------------------------------------------------------
// A sheet with a hole and a V-notch (a polygon) pulled apart until it tears: the same on 1 and 2
// ranks.

const char* kTearScene = R"(
name: holed-slit
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 1.6}
bodies:
  sheet:
    material: rubber
    origin: [-0.01, -0.01, 0]
    size: [0.02, 0.02]
    thickness: 0.0005
    spacing: 0.0005
    cutouts:
      - {kind: circle, center: [0.0021, 0.0003], radius: 0.003}
      - {kind: polygon, vertices: [[-0.0105, -0.0006], [-0.006, 0], [-0.0105, 0.0006]]}
boundaries:
  - {name: top, region: {min: [-1, 0.0088, -1], max: [1, 1, 1]}, velocity: [0, 20, 0]}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0088, 1]}, velocity: [0, -20, 0]}
initial:
  displacement_gradient: [[0, 0, 0], [0, 0.1, 0], [0, 0, 0]]
  velocity_gradient: [[0, 0, 0], [0, 2000, 0], [0, 0, 0]]
stages:
  - {name: pull, duration: 6.0e-5}
output: {frames: 1, series_every: 10}
)";

TEST(Cutouts, SameResultOnOneAndManyRanks) {
  const Scene scene = parse_scene(kTearScene, "holed-slit");
  RunOptions quiet;
  quiet.quiet = true;
  Simulation many(scene, PETSC_COMM_WORLD, quiet);
  many.run();
  Simulation one(scene, PETSC_COMM_SELF, quiet);
  one.run();
  const std::vector<double> xa = many.natural_positions(), xb = one.natural_positions();
  ASSERT_EQ(xa.size(), xb.size());
  double diff = 0, scale = 0;
  for (std::size_t k = 0; k < xa.size(); ++k) {
    diff = std::max(diff, std::fabs(xa[k] - xb[k]));
    scale = std::max(scale, std::fabs(xb[k]));
  }
  const auto ba = many.broken_bonds(), bb = one.broken_bonds();
  if (world_rank() == 0)
    std::printf("holed sheet: %lld nodes; %d ranks vs 1: max position difference %.3e (relative %.3e), broken "
                "bonds %zu vs %zu\n",
                static_cast<long long>(one.summary().nodes), many.summary().ranks, diff, diff / scale, ba.size(),
                bb.size());
  EXPECT_LE(diff / scale, 1e-12);
  EXPECT_EQ(ba, bb);
  EXPECT_GT(bb.size(), 100u);  // it tore
}

}  // namespace
}  // namespace peri
