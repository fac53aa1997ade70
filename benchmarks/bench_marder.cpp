// Throughput of Marder's lattice: the two- and three-body kernel alone, and the full explicit step
// (halo, kernel, reverse ghost update of the force slots, Verlet). Prints figures (Google
// Benchmark counters); asserts nothing.
//   node_updates/s : lattice nodes whose node-centred term (6 pair + 15 unordered three-body
//                    terms) and forces are evaluated per second (one rank, one core)
// Run: build/benchmarks/bench_marder [--benchmark_repetitions=5 --benchmark_report_aggregates_only=true]
#include <benchmark/benchmark.h>
#include <petscsys.h>

#include <cstdio>
#include <random>

#include "peri/stages/simulation.hpp"

namespace peri {
namespace {

// An N x N lattice (Delta = 1 mm), stretched (1.1, 1.8), clamped along its top and bottom rows.
std::string lattice_scene(int n) {
  char text[1024];
  const double D = 1e-3, dy = D * 0.8660254037844386;
  std::snprintf(text, sizeof text, R"(
name: bench
materials:
  m: {model: marder, density: 1000, mooney_rivlin_a: 1000, mooney_rivlin_b: 0.4, cutoff: 5.0e-5,
      fracture_separation: 0.002}
bodies:
  strip: {kind: lattice, material: m, origin: [0, 0, 0], size: [%.17g, %.17g], thickness: 0.001, spacing: %.17g}
boundaries:
  - {name: top, region: {min: [-1, %.17g, -1], max: [1, 1, 1]}}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, %.17g, 1]}}
initial:
  displacement_gradient: [[0.1, 0, 0], [0, 0.8, 0], [0, 0, 0]]
stages:
  - {name: run, steps: 1000000}
output: {frames: 1, series_every: 1000000}
)", n * D, n * dy, D, (n - 1) * dy, dy);
  return text;
}

// Kernel alone: every row of a one-rank domain, displacements = stretch + random jitter.
void kernel(benchmark::State& st) {
  const int n = static_cast<int>(st.range(0));
  const Scene scene = parse_scene(lattice_scene(n), "bench");
  const Nodes nodes = discretize(scene);
  CellList cells(nodes, reach(nodes.bodies[0]));
  const Partition part = partition_from_parts(nodes, std::vector<int>(nodes.size(), 0), 1);
  Domain d = build_domain(scene, nodes, cells, part, 0);
  const MarderParams& p = *scene.materials[0].marder;
  const BodyGeometry& g = nodes.bodies[0];
  const MarderLaw law = marder_law(p.a, p.b, g.spacing, p.cutoff, p.fracture_separation,
                                   1000 * g.cell_area * g.thickness, false);
  std::vector<double> u(3 * static_cast<std::size_t>(d.local()));
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> U(-1e-5, 1e-5);
  for (std::int32_t i = 0; i < d.local(); ++i) {
    u[3 * i] = 0.1 * d.X[3 * i] + U(rng);
    u[3 * i + 1] = 0.8 * d.X[3 * i + 1] + U(rng);
  }
  std::vector<std::int32_t> rows(d.owned);
  for (std::int32_t i = 0; i < d.owned; ++i) rows[i] = i;
  BondView v{d.X.data(), u.data(), d.volume.data(), d.bonds.offsets.data(), d.bonds.neighbor.data(),
             d.bonds.broken.data(), nullptr};
  const std::vector<std::uint8_t> dir = marder_directions(v, d.owned);
  std::vector<double> slots(3 * kMarderSlots * static_cast<std::size_t>(d.local())), F(3 * static_cast<std::size_t>(d.owned));
  BondTally t;
  for (auto _ : st) {
    std::fill(slots.begin(), slots.end(), 0.0);
    marder_forces(law, v, rows.data(), rows.size(), dir.data(), slots.data(), false, t);
    marder_sum_slots(slots.data(), rows.data(), rows.size(), F.data());
    benchmark::DoNotOptimize(F.data());
  }
  st.counters["nodes"] = d.owned;
  st.counters["node_updates/s"] = benchmark::Counter(d.owned, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["three_body_terms/s"] =
      benchmark::Counter(15.0 * d.owned, benchmark::Counter::kIsIterationInvariantRate);
}

// Full explicit step through Simulation (every rank takes the same number of collective steps).
void full_step(benchmark::State& st) {
  const int n = static_cast<int>(st.range(0));
  const Scene scene = parse_scene(lattice_scene(n), "bench");
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(scene, PETSC_COMM_WORLD, quiet);
  sim.begin();
  for (auto _ : st) sim.advance(1);
  int ranks = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &ranks);
  st.counters["nodes"] = static_cast<double>(sim.summary().nodes);
  st.counters["node_updates/s"] = benchmark::Counter(static_cast<double>(sim.summary().nodes), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["node_updates/s/rank"] =
      benchmark::Counter(static_cast<double>(sim.summary().nodes) / ranks, benchmark::Counter::kIsIterationInvariantRate);
}

BENCHMARK(kernel)->Arg(100)->Arg(400)->Unit(benchmark::kMillisecond);
BENCHMARK(full_step)->Arg(400)->Iterations(40)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace peri

int main(int argc, char** argv) {
  if (PetscInitialize(&argc, &argv, nullptr, nullptr)) return 1;
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  PetscFinalize();
  return 0;
}
