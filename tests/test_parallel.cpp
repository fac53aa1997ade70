// Whole-simulation tests, run under MPI (registered at 1 and 2 ranks).
#include <gtest/gtest.h>
#include <petscsys.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "peri/partition/partition.hpp"
#include "peri/stages/simulation.hpp"
#include "mpi_test.hpp"

namespace peri {
namespace {

// A small slit membrane that fractures within a few hundred steps.
const char* kFractureScene = R"(
name: small-slit
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 1.6}
bodies:
  sheet: {material: rubber, origin: [-0.01, -0.01, 0], size: [0.02, 0.02], thickness: 0.0005, spacing: 0.0005}
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
  - {name: pull, duration: 6.0e-5}
output: {frames: 1, series_every: 10}
)";

// A small free PMB block (3D), the shape of benchmarks/compare_lammps.py.
const char* kBlockScene = R"(
name: small-block
materials:
  glass: {model: pmb, density: 2200, micromodulus: 1.0e19, critical_stretch: 0.0005}
bodies:
  block: {kind: solid, material: glass, origin: [0, 0, 0], size: [0.016, 0.016, 0.016], spacing: 0.001, horizon: 0.003015, quadrature: taper}
stages:
  - {name: still, steps: 1, dt: 1.0e-9}
output: {frames: 1, series_every: 1}
)";

// The coarse cell-graph partitioner (the default for scenes other than one body filling its box) against METIS on the full bond graph: every
// node in exactly one part, bonds balanced within 2%, edge cut within 1.35x of the full graph's.
// PETSc MatPartitioning on the same cell graph: every node once, balance within 10%.
TEST(Partitioner, CellGraphCoversBalancesAndCutsNearTheFullGraph) {
  for (const char* text : {kFractureScene, kBlockScene}) {
    const Scene scene = parse_scene(text, "partition-test");
    const Nodes nodes = discretize(scene);
    double max_reach = 0;
    for (const BodyGeometry& g : nodes.bodies) max_reach = std::max(max_reach, reach(g));
    const CellList cells(nodes, max_reach);
    const BondGraph graph = bond_graph(nodes, cells);
    for (int parts : {2, 4, 8}) {
      PartitionSettings bonds_settings, cells_settings, petsc_settings;
      bonds_settings.method = PartitionMethod::Bonds;
      cells_settings.method = PartitionMethod::Cells;
      petsc_settings.method = PartitionMethod::Petsc;
      const Partition full = partition_nodes(nodes, cells, parts, PETSC_COMM_WORLD, bonds_settings);
      const Partition coarse = partition_nodes(nodes, cells, parts, PETSC_COMM_WORLD, cells_settings);
      const Partition petsc = partition_nodes(nodes, cells, parts, PETSC_COMM_WORLD, petsc_settings);
      for (const Partition* p : {&full, &coarse, &petsc}) {
        ASSERT_EQ(p->part.size(), static_cast<std::size_t>(nodes.size()));
        std::vector<int> seen(nodes.size(), 0);
        for (std::int64_t i = 0; i < nodes.size(); ++i) {
          ASSERT_GE(p->part[i], 0);
          ASSERT_LT(p->part[i], parts);
          const std::int64_t g = p->natural_to_global[i];
          ASSERT_GE(g, p->part_begin[p->part[i]]);  // inside its part's global range
          ASSERT_LT(g, p->part_begin[p->part[i] + 1]);
          ++seen[g];
        }
        EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), nodes.size()) << p->method;
        // The figures reported are those of the parts.
        const PartitionQuality q = quality(graph, p->part, parts);
        EXPECT_EQ(q.edge_cut, p->edge_cut) << p->method;
        EXPECT_NEAR(q.balance, p->balance, 1e-12) << p->method;
      }
      if (world_rank() == 0)
        std::printf("%s, %d parts, %lld nodes: edge cut / balance: bonds %lld / %.4f, cells %lld / %.4f (%lld cells), "
                    "%s %lld / %.4f\n", scene.name.c_str(), parts, static_cast<long long>(nodes.size()),
                    static_cast<long long>(full.edge_cut), full.balance, static_cast<long long>(coarse.edge_cut),
                    coarse.balance, static_cast<long long>(coarse.graph_vertices), petsc.method.c_str(),
                    static_cast<long long>(petsc.edge_cut), petsc.balance);
      EXPECT_LE(coarse.balance, 1.02);
      EXPECT_LE(coarse.edge_cut, 1.35 * full.edge_cut);
      EXPECT_LT(coarse.graph_vertices, nodes.size());  // a coarser graph than the nodes'
      EXPECT_LE(petsc.balance, 1.10);
    }
  }
}

// Recursive coordinate bisection (the default for one body filling its box): its node weights are
// the bond counts neighbours_of finds; every node in one part; bonds balanced within 1% (the
// weights are exact; a cut moves to a grid line's end only where that costs at most 0.5%); on
// the cube no more cut bonds than METIS on the full bond graph plus 5% (elsewhere RCB keeps x
// lines whole where METIS, weighing every bond alike, cuts across them: figures printed); at two
// parts a flat cut that splits no x line.
TEST(Partitioner, CoordinateBisectionBalancesAndCutsFlat) {
  const char* kThin = R"(
name: thin-plate
materials:
  glass: {model: pmb, density: 2200, micromodulus: 1.0e19, critical_stretch: 0.0005}
bodies:
  plate: {kind: solid, material: glass, origin: [0, 0, 0], size: [0.020, 0.012, 0.003], spacing: 0.001, horizon: 0.003015}
stages:
  - {name: still, steps: 1, dt: 1.0e-9}
)";
  for (const char* text : {kFractureScene, kBlockScene, kThin}) {
    const Scene scene = parse_scene(text, "rcb-test");
    const Nodes nodes = discretize(scene);
    ASSERT_TRUE(fills_its_box(nodes)) << scene.name;
    EXPECT_EQ(resolve_partition_method(PartitionMethod::Auto, nodes), PartitionMethod::Rcb);
    EXPECT_EQ(resolve_partition_method(PartitionMethod::Cells, nodes), PartitionMethod::Cells);
    double max_reach = 0;
    for (const BodyGeometry& g : nodes.bodies) max_reach = std::max(max_reach, reach(g));
    const CellList cells(nodes, max_reach);
    const BondGraph graph = bond_graph(nodes, cells);
    const std::vector<std::int32_t> counts = grid_bond_counts(nodes);
    ASSERT_EQ(counts.size(), static_cast<std::size_t>(nodes.size()));
    for (std::int64_t i = 0; i < nodes.size(); ++i)
      ASSERT_EQ(counts[i], graph.offsets[i + 1] - graph.offsets[i]) << scene.name << " node " << i;
    for (int parts : {2, 3, 4, 8}) {
      PartitionSettings rcb, bonds;
      bonds.method = PartitionMethod::Bonds;
      const Partition p = partition_nodes(nodes, cells, parts, PETSC_COMM_WORLD, rcb);
      const Partition full = partition_nodes(nodes, cells, parts, PETSC_COMM_WORLD, bonds);
      EXPECT_EQ(p.method, "rcb-node-coordinates");
      EXPECT_EQ(p.edge_cut, -1);  // counted by the domains (Simulation)
      std::vector<int> seen(nodes.size(), 0);
      for (std::int64_t i = 0; i < nodes.size(); ++i) {
        ASSERT_GE(p.part[i], 0);
        ASSERT_LT(p.part[i], parts);
        ++seen[p.natural_to_global[i]];
      }
      EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), nodes.size());
      const PartitionQuality q = quality(graph, p.part, parts);
      if (world_rank() == 0)
        std::printf("%s, %d parts: rcb edge cut %lld balance %.4f; METIS bond graph %lld / %.4f\n", scene.name.c_str(),
                    parts, static_cast<long long>(q.edge_cut), q.balance, static_cast<long long>(full.edge_cut),
                    full.balance);
      EXPECT_LE(q.balance, 1.01) << scene.name << ", " << parts << " parts";
      if (text == kBlockScene) EXPECT_LE(q.edge_cut, 1.05 * full.edge_cut) << parts << " parts";
      if (parts == 2) {  // one flat cut across y or z: every x line (nodes of one y and z) whole
        std::map<std::pair<double, double>, int> line_parts;
        for (std::int64_t i = 0; i < nodes.size(); ++i) line_parts[{nodes.X[3 * i + 1], nodes.X[3 * i + 2]}] |= 1 << p.part[i];
        for (const auto& [line, mask] : line_parts) EXPECT_NE(mask, 3) << scene.name;
      }
    }
  }
  // Two bodies, or one with holes in its grid: the cell graph.
  const Scene two = parse_scene(R"(
name: two
materials:
  glass: {model: pmb, density: 2200, micromodulus: 1.0e19, critical_stretch: 0.0005}
bodies:
  a: {kind: solid, material: glass, origin: [0, 0, 0], size: [0.006, 0.006, 0.006], spacing: 0.001, horizon: 0.003015}
  b: {kind: solid, material: glass, origin: [0.01, 0, 0], size: [0.006, 0.006, 0.006], spacing: 0.001, horizon: 0.003015}
stages:
  - {name: still, steps: 1, dt: 1.0e-9}
)", "two");
  EXPECT_EQ(resolve_partition_method(PartitionMethod::Auto, discretize(two)), PartitionMethod::Cells);
}

// The message of the InputError that partition_settings_from_options throws ("" if none).
std::string settings_error() {
  try {
    partition_settings_from_options();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Cut bonds between cells of one x row weigh twice (kLineWeight): on a block 1.25 times longer
// in x than across, where a cut across x cuts the fewest bonds (and METIS takes it with every cut
// bond alike), the weighted graph is cut along the x lines, which the bond loop's stride-1 runs
// follow; -partition_line_weight sets the weight, within [1, 64].
TEST(Partitioner, LineWeightKeepsGridLinesWhole) {
  const Scene scene = parse_scene(
      "name: block\nmaterials:\n  m: {model: pmb, density: 2200, bulk_modulus: 1.49e10, critical_stretch: 0.005}\n"
      "bodies:\n  b: {kind: solid, material: m, origin: [0, 0, 0], size: [0.030, 0.024, 0.024], spacing: 0.001, "
      "horizon: 0.003015, quadrature: taper}\nstages:\n  - {name: r, steps: 1}\n",
      "block");
  const Nodes nodes = discretize(scene);
  const CellList cells(nodes, reach(nodes.bodies[0]));
  const CellGraph graph = cell_graph(nodes, cells, cell_size_for(nodes, 2, 64));
  // The x lines (nodes of one y and z) holding nodes of both parts.
  auto split_lines = [&](int line_weight) {
    const std::vector<int> cell_part = metis_kway(graph, 2, line_weight);
    std::map<std::pair<long, long>, int> line_parts;
    for (std::int64_t i = 0; i < nodes.size(); ++i) {
      const std::pair<long, long> line{std::lround(nodes.X[3 * i + 1] / 1e-3), std::lround(nodes.X[3 * i + 2] / 1e-3)};
      line_parts[line] |= 1 << cell_part[graph.cell_of[i]];
    }
    EXPECT_EQ(line_parts.size(), 24u * 24u);
    long split = 0;
    for (const auto& [line, parts] : line_parts) split += parts == 3;
    return split;
  };
  const long plain = split_lines(1), weighted = split_lines(kLineWeight);
  if (world_rank() == 0) std::printf("x lines split in two: %ld of 576 (every cut bond alike), %ld (line weight %d)\n", plain, weighted, kLineWeight);
  EXPECT_GT(plain, 288);
  EXPECT_LE(weighted, 72);  // at most an eighth: a staircase where the cut meets the cells
  PetscOptionsSetValue(nullptr, "-partition_line_weight", "5");
  EXPECT_EQ(partition_settings_from_options().line_weight, 5);
  PetscOptionsSetValue(nullptr, "-partition_line_weight", "0");
  const std::string message = settings_error();
  EXPECT_NE(message.find("-partition_line_weight 0: expected an integer in [1, 64]"), std::string::npos) << message;
  // Not integers: read as text, refused as input (PETSc's own reading ended in its error handler).
  for (const char* text : {"1.5", "nan", "abc", "5x", ""}) {
    PetscOptionsSetValue(nullptr, "-partition_line_weight", text);
    EXPECT_NE(settings_error().find("-partition_line_weight " + std::string(text) + ": expected an integer in [1, 64]"),
              std::string::npos) << text;
  }
  PetscOptionsClearValue(nullptr, "-partition_line_weight");
  PetscOptionsSetValue(nullptr, "-partition_mat_partitioning_type", "foo");
  const std::string type_message = settings_error();
  EXPECT_NE(type_message.find("-partition_mat_partitioning_type foo: not a partitioner of this PETSc build; expected "
                              "one of: current, average, square"),
            std::string::npos) << type_message;
  PetscOptionsClearValue(nullptr, "-partition_mat_partitioning_type");
  EXPECT_EQ(partition_settings_from_options().line_weight, kLineWeight);
}

TEST(Partitioner, MethodFromOptions) {
  EXPECT_EQ(partition_settings_from_options().method, PartitionMethod::Auto);  // the default
  const Scene scene = parse_scene(kBlockScene, "small-block");
  RunOptions quiet;
  quiet.quiet = true;
  {
    // auto on one body filling its box: rcb; the summary's edge cut (bonds to ghost nodes, over
    // the domains) is the bond graph's cut of those parts.
    Simulation sim(scene, PETSC_COMM_WORLD, quiet);
    EXPECT_EQ(sim.summary().partition_method, "rcb");
    const Nodes nodes = discretize(scene);
    const CellList cells(nodes, reach(nodes.bodies[0]));
    int ranks = 1;
    MPI_Comm_size(PETSC_COMM_WORLD, &ranks);
    const PartitionQuality q = quality(bond_graph(nodes, cells), rcb_parts(nodes, ranks), ranks);
    EXPECT_EQ(sim.summary().edge_cut, q.edge_cut);
    if (ranks > 1) EXPECT_GT(q.edge_cut, 0);
  }
  PetscOptionsSetValue(nullptr, "-partition_method", "bonds");
  EXPECT_EQ(partition_settings_from_options().method, PartitionMethod::Bonds);
  {
    Simulation sim(scene, PETSC_COMM_WORLD, quiet);
    EXPECT_EQ(sim.summary().partition_method, "bonds");
    EXPECT_FALSE(sim.summary().memory.empty());
  }
  PetscOptionsSetValue(nullptr, "-partition_method", "metis");
  const std::string message = settings_error();
  EXPECT_NE(message.find("-partition_method metis: expected auto"), std::string::npos) << message;
  PetscOptionsClearValue(nullptr, "-partition_method");
}

TEST(Decomposition, SameResultOnOneAndManyRanks) {
  const Scene scene = parse_scene(kFractureScene, "small-slit");
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
    std::printf("decomposition: %d ranks vs 1: max position difference %.3e (relative %.3e), broken bonds %zu vs %zu\n",
                many.summary().ranks, diff, diff / scale, ba.size(), bb.size());
  EXPECT_LE(diff / scale, 1e-12);
  EXPECT_EQ(ba, bb);
  // The run must actually fracture: the crack breaks hundreds of bonds beyond the slit's.
  EXPECT_GT(one.summary().final_energy.broken_bonds, 500);
  EXPECT_EQ(static_cast<std::int64_t>(bb.size()),
            one.summary().precrack_bonds + one.summary().final_energy.broken_bonds);
  // Crack tip histories: the same tracks, sample times, positions and speeds on any rank count.
  ASSERT_TRUE(many.crack_tips() && one.crack_tips());
  const auto& ta = many.crack_tips()->tracks();
  const auto& tb = one.crack_tips()->tracks();
  ASSERT_EQ(ta.size(), tb.size());
  double tip_diff = 0, speed_diff = 0, travel = 0;
  for (std::size_t k = 0; k < ta.size(); ++k) {
    ASSERT_EQ(ta[k].time, tb[k].time);
    for (std::size_t n = 0; n < ta[k].time.size(); ++n) {
      for (int c = 0; c < 3; ++c) tip_diff = std::max(tip_diff, std::fabs(ta[k].position[n][c] - tb[k].position[n][c]));
      if (std::isfinite(tb[k].speed[n])) speed_diff = std::max(speed_diff, std::fabs(ta[k].speed[n] - tb[k].speed[n]));
      else EXPECT_TRUE(std::isnan(ta[k].speed[n]));
    }
    travel = std::max(travel, std::fabs(tb[k].position.back()[0] - tb[k].position.front()[0]));
  }
  if (world_rank() == 0)
    std::printf("crack tips: %zu tracks, largest travel %.2f mm, max speed %.1f m/s; %d ranks vs 1: position "
                "difference %.3e m, speed difference %.3e m/s\n",
                tb.size(), travel * 1e3, one.crack_tips()->max_speed(), many.summary().ranks, tip_diff, speed_diff);
  EXPECT_GE(tb.size(), 2u);
  EXPECT_GT(travel, 0.002);  // the tips ran
  EXPECT_LE(tip_diff, 1e-15);
  EXPECT_LE(speed_diff, 1e-9);
}

// A body at rest holds only round-off energy (about 1e-24 J here); the energy-balance detector
// must judge it against a physical scale, not stop the run for a relative error of round-off.
TEST(StabilityDetectors, BodyAtRestIsNotAnEnergyError) {
  const char* text = R"(
name: at-rest
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000}
bodies:
  sheet: {material: rubber, origin: [0, 0, 0], size: [0.02, 0.02], thickness: 0.0005, spacing: 0.0005}
stages:
  - {name: rest, steps: 400}
output: {frames: 1, series_every: 10}
)";
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(parse_scene(text, "at-rest"), PETSC_COMM_WORLD, quiet);
  EXPECT_NO_THROW(sim.run());
  EXPECT_LT(sim.summary().energy_balance_error, 1e-3);
}

TEST(FreeFlight, ConservesMomentumAndEnergy) {
  // A spinning, gently stretching, slightly wrinkled membrane: no boundary, no damage.
  const char* text = R"(
name: free-flight
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000}
bodies:
  sheet: {material: rubber, origin: [-0.006, -0.006, 0], size: [0.012, 0.012], thickness: 0.0005, spacing: 0.0005}
initial:
  velocity_gradient: [[200, -1000, 0], [1000, 100, 0], [0, 0, 0]]
  seed: {amplitude: 2.0e-6, wavelength: [0.006, 0.006]}
stages:
  - {name: fly, steps: 10000}
output: {frames: 1, series_every: 1000000}
)";
  const Scene scene = parse_scene(text, "free-flight");
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(scene, PETSC_COMM_WORLD, quiet);
  sim.begin();
  const auto p0 = sim.momentum();
  const EnergyRow e0 = sim.energies();
  const double E0 = e0.kinetic + e0.strain;
  double pscale = 0;  // sum of m |v|
  for (double c : sim.natural_velocities()) pscale += std::fabs(c);
  pscale *= 1200 * 0.0005 * 0.0005 * 0.0005;
  double drift = 0, max_strain = 0;
  while (sim.advance(500) > 0) {
    const EnergyRow e = sim.energies();
    drift = std::max(drift, std::fabs(e.kinetic + e.strain - E0) / E0);
    max_strain = std::max(max_strain, e.strain);
  }
  const auto p1 = sim.momentum();
  double dp = 0, dl = 0;
  for (int c = 0; c < 3; ++c) dp = std::max(dp, std::fabs(p1[c] - p0[c]));
  for (int c = 3; c < 6; ++c) dl = std::max(dl, std::fabs(p1[c] - p0[c]));
  const double lscale = pscale * 0.012;  // sum m |v| |x|
  if (world_rank() == 0)
    std::printf("free flight, %lld steps: max energy deviation %.3e (strain energy up to %.1f%% of E), "
                "linear momentum change %.3e (rel %.3e), angular %.3e (rel %.3e)\n",
                static_cast<long long>(sim.current_step()), drift, 100 * max_strain / E0, dp, dp / pscale, dl,
                dl / lscale);
  EXPECT_EQ(sim.current_step(), 10000);
  EXPECT_LT(drift, 1e-4);
  EXPECT_LT(dp / pscale, 1e-12);
  EXPECT_LT(dl / lscale, 1e-11);
  EXPECT_GT(max_strain, 0.01 * E0);  // the run exchanges kinetic and strain energy
}

// Time at which the probe's x-velocity first crosses half the driving velocity.
double half_crossing(const std::vector<double>& t, const std::vector<double>& v, double half) {
  for (std::size_t k = 1; k < v.size(); ++k)
    if (v[k - 1] < half && v[k] >= half) return t[k - 1] + (t[k] - t[k - 1]) * (half - v[k - 1]) / (v[k] - v[k - 1]);
  return NAN;
}

// Calibration: a plane longitudinal front, driven smoothly from one edge of a wide plate, runs at
// c_l. Measured between two probes on the centre line before edge waves can reach them.
double measured_wave_speed(double dx) {
  const double c_l = 1000, delta = 3 * dx, ramp = 10 * delta / c_l, v0 = 0.1;
  const double length = 0.045, width = 0.07, x1 = 0.02, x2 = 0.035;
  char text[2048];
  std::snprintf(text, sizeof text, R"(
name: wave
materials:
  rubber: {model: membrane, density: 1200, wave_speed: %g}
bodies:
  plate: {material: rubber, origin: [0, %.17g, 0], size: [%.17g, %.17g], thickness: 0.0005, spacing: %.17g}
boundaries:
  - {name: driver, region: {min: [-1, -1, -1], max: [%.17g, 1, 1]}, velocity: [%g, 0, 0], components: [x], ramp_time: %.17g}
stages:
  - {name: run, duration: %.17g}
output: {frames: 1, series_every: 100000}
)", c_l, -width / 2, length, width, dx, delta, v0, ramp, (x2 + 2 * ramp * c_l) / c_l);
  const Scene scene = parse_scene(text, "wave");
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(scene, PETSC_COMM_WORLD, quiet);
  sim.begin();
  // Probes: nodes nearest (x1 + delta, 0) and (x2 + delta, 0), measured from the driven band.
  const auto X = sim.natural_positions();
  auto nearest = [&](double x) {
    std::size_t best = 0;
    double d = 1e9;
    for (std::size_t i = 0; i < X.size() / 3; ++i) {
      const double e = std::hypot(X[3 * i] - x, X[3 * i + 1]);
      if (e < d) d = e, best = i;
    }
    return best;
  };
  const std::size_t p1 = nearest(x1 + delta), p2 = nearest(x2 + delta);
  const double s = X[3 * p2] - X[3 * p1];
  std::vector<double> t, v1, v2;
  while (sim.advance(1) == 1) {
    const auto v = sim.natural_velocities();
    t.push_back(sim.current_time());
    v1.push_back(v[3 * p1]);
    v2.push_back(v[3 * p2]);
  }
  return s / (half_crossing(t, v2, v0 / 2) - half_crossing(t, v1, v0 / 2));
}

TEST(Calibration, LongitudinalWaveSpeedInAPlate) {
  const double coarse = measured_wave_speed(0.5e-3), fine = measured_wave_speed(0.25e-3);
  if (world_rank() == 0)
    std::printf("longitudinal wave speed (c_l = 1000 m/s): dx = 0.5 mm: %.2f m/s (%.2f%%), dx = 0.25 mm: %.2f m/s (%.2f%%)\n",
                coarse, (coarse / 1000 - 1) * 100, fine, (fine / 1000 - 1) * 100);
  EXPECT_NEAR(fine / 1000, 1.0, 0.02);
}

}  // namespace
}  // namespace peri
