// Bond throughput of the force kernels and of the full explicit step. Prints figures (Google
// Benchmark counters); asserts nothing.
//   bond_updates/s : ordered bond evaluations per second (one rank, one core)
//   bytes_per_bond : bond storage (offsets + neighbour + flag + family patterns) per ordered bond
// Run: build/benchmarks/bench_kernels [--benchmark_repetitions=5 --benchmark_report_aggregates_only=true]
#include <benchmark/benchmark.h>
#include <petscsys.h>

#include <algorithm>
#include <cstdio>
#include <random>

#include "peri/simulation.hpp"

namespace peri {
namespace {

std::string membrane_scene(const char* model, int n, const char* quadrature) {
  char text[1024];
  const double dx = 1e-3;
  std::snprintf(text, sizeof text, R"(
name: bench
materials:
  m: {model: %s, density: 1200, bulk_modulus: 800.0e6, critical_stretch: %s}
bodies:
  sheet: {material: m, origin: [0, 0, 0], size: [%.17g, %.17g], thickness: 0.0005, spacing: %.17g, quadrature: %s}
stages:
  - {name: run, steps: 1000000}
output: {frames: 1, series_every: 1000000}
)", model, std::string(model) == "pmb" ? "0.5" : "5.0", n * dx, n * dx, dx, quadrature);
  return text;
}

// Kernel alone: the bond loop over every row of a one-rank domain, displacements random.
void kernel(benchmark::State& st, const char* model, const char* quadrature) {
  const int n = static_cast<int>(st.range(0));
  const Scene scene = parse_scene(membrane_scene(model, n, quadrature), "bench");
  const Nodes nodes = discretize(scene);
  CellList cells(nodes, reach(nodes.bodies[0]));
  const Partition part = partition_from_parts(std::vector<int>(nodes.size(), 0), 1);
  Domain d = build_domain(scene, nodes, cells, part, 0);
  const BondLaw law = calibrate(scene.materials[0], nodes.bodies[0], "bench");
  std::vector<double> u(3 * static_cast<std::size_t>(d.local()));
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> U(-1e-5, 1e-5);
  for (double& x : u) x = U(rng);
  std::vector<std::int32_t> rows(d.owned);
  for (std::int32_t i = 0; i < d.owned; ++i) rows[i] = i;
  std::vector<double> F(3 * static_cast<std::size_t>(d.owned));
  std::vector<double> x(3 * static_cast<std::size_t>(d.local()));
  current_positions(d.X.data(), u.data(), 0, d.local(), d.local(), x.data());
  BondView v{d.X.data(), u.data(), d.volume.data(), d.bonds.offsets.data(), d.bonds.neighbor.data(),
             d.bonds.broken.data(), &d.bonds.patterns, x.data(), d.local()};
  const RowBlocks plan = plan_rows(v, rows.data(), rows.size());
  BondTally t;
  for (auto _ : st) {
    bond_forces(law, v, plan, F.data(), false, t);
    benchmark::DoNotOptimize(F.data());
  }
  st.counters["nodes"] = d.owned;
  st.counters["bonds"] = static_cast<double>(d.bonds.size());
  st.counters["bond_updates/s"] = benchmark::Counter(static_cast<double>(d.bonds.size()), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["bytes_per_bond"] = d.bonds.bytes_per_bond();
  st.counters["block_rows"] = static_cast<double>(plan.run_rows()) / static_cast<double>(plan.rows());
  st.counters["rows_per_run"] = static_cast<double>(plan.run_rows()) / static_cast<double>(std::max<std::size_t>(1, plan.runs.size()));
}

// Full explicit step (halo exchange, kernel, Verlet update, boundary logic) through Simulation.
void full_step(benchmark::State& st, const char* model) {
  const int n = static_cast<int>(st.range(0));
  const Scene scene = parse_scene(membrane_scene(model, n, "partial_area"), "bench");
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(scene, PETSC_COMM_WORLD, quiet);
  sim.begin();
  for (auto _ : st) sim.advance(1);
  st.counters["bond_updates/s"] = benchmark::Counter(static_cast<double>(sim.summary().ordered_bonds), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["bonds"] = static_cast<double>(sim.summary().ordered_bonds);
}

BENCHMARK_CAPTURE(kernel, membrane_partial_area, "membrane", "partial_area")->Arg(100)->Arg(400)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(kernel, membrane_full, "membrane", "full")->Arg(400)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(kernel, pmb_partial_area, "pmb", "partial_area")->Arg(400)->Unit(benchmark::kMillisecond);
// A fixed iteration count: every rank must take the same number of (collective) steps.
BENCHMARK_CAPTURE(full_step, membrane, "membrane")->Arg(400)->Arg(500)->Iterations(40)->Unit(benchmark::kMillisecond);

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
