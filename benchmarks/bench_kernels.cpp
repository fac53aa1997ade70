// Bond throughput of the force kernels and of the full explicit step. Prints figures (Google
// Benchmark counters); asserts nothing.
//   bond_updates/s : ordered bond evaluations per second (one rank, one core)
//   bytes_per_bond : bond storage (offsets + neighbour + flag + family patterns, and the plan's
//                    interleaved lists of free rows) per ordered bond
// Run: build/benchmarks/bench_kernels [--benchmark_repetitions=5 --benchmark_report_aggregates_only=true]
#include <benchmark/benchmark.h>
#include <petscsys.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#if defined(__AVX2__)
#include <immintrin.h>
#endif
#include <random>

#include "peri/models/model.hpp"
#include "peri/stages/simulation.hpp"
#include "jittered_nodes.hpp"

namespace peri {
namespace {

std::string membrane_scene(const char* model, int n, const char* quadrature, double critical_stretch) {
  char text[1024];
  const double dx = 1e-3;
  std::snprintf(text, sizeof text, R"(
name: bench
materials:
  m: {model: %s, density: 1200, bulk_modulus: 800.0e6, critical_stretch: %.17g}
bodies:
  sheet: {material: m, origin: [0, 0, 0], size: [%.17g, %.17g], thickness: 0.0005, spacing: %.17g, quadrature: %s}
stages:
  - {name: run, steps: 1000000}
output: {frames: 1, series_every: 1000000}
)", model, critical_stretch, n * dx, n * dx, dx, quadrature);
  return text;
}

// The N^3 PMB block of benchmarks/compare_lammps.py (dx = 1 mm, horizon 3.015 dx, LAMMPS' taper).
std::string solid_scene(int n, double critical_stretch, const char* quadrature = "taper") {
  char text[1024];
  std::snprintf(text, sizeof text, R"(
name: bench
materials:
  glass: {model: pmb, density: 2200, bulk_modulus: 14.9e9, critical_stretch: %.17g}
bodies:
  block: {kind: solid, material: glass, origin: [0, 0, 0], size: [%.17g, %.17g, %.17g], spacing: 0.001, horizon: 0.003015, quadrature: %s}
stages:
  - {name: run, steps: 1000000}
output: {frames: 1, series_every: 1000000}
)", critical_stretch, n * 1e-3, n * 1e-3, n * 1e-3, quadrature);
  return text;
}

// Irregular node sets of the grids' density (spacing 1 mm), written once into the temporary
// directory: `jittered_membrane_mesh(n)`, an n x n square of nodes each moved by up to `jitter`
// spacings along x and y, two triangles per square (a Gmsh .msh 2.2 file); and
// `jittered_cloud(n)`, an n^3 cube of points moved likewise in 3D, each with the volume of its cell
// (a point-cloud CSV). The same density and family sizes as membrane_full and pmb_block_full.
std::string jittered_membrane_mesh(int n, double jitter) {
  return fixtures::write_jittered_sheet("peri_bench_jittered_" + std::to_string(n) + ".msh", n, n, jitter, 7);
}

std::string jittered_cloud(int n, double jitter) {
  return fixtures::write_jittered_cloud("peri_bench_cloud_" + std::to_string(n) + ".csv", n, n, n, jitter, 7);
}

std::string mesh_membrane_scene(const std::string& mesh) {
  return R"(
name: bench
materials:
  m: {model: membrane, density: 1200, bulk_modulus: 800.0e6, critical_stretch: 5.0}
bodies:
  sheet: {material: m, mesh: ")" + mesh + R"(", thickness: 0.0005, spacing: 0.001}
stages:
  - {name: run, steps: 1000000}
output: {frames: 1, series_every: 1000000}
)";
}

std::string cloud_solid_scene(const std::string& cloud, const char* quadrature) {
  return R"(
name: bench
materials:
  glass: {model: pmb, density: 2200, bulk_modulus: 14.9e9, critical_stretch: 0.5}
bodies:
  block: {kind: solid, material: glass, points: ")" + cloud + R"(", spacing: 0.001, horizon: 0.003015, quadrature: )" +
         quadrature + R"(}
stages:
  - {name: run, steps: 1000000}
output: {frames: 1, series_every: 1000000}
)";
}

// Kernel alone: the bond loop over every row of a one-rank domain (spacing 1 mm), displacements
// random, uniform in +-`noise` (m), plus a uniform strain `strain` along x: a nearest-neighbour
// bond strains up to 2 noise / spacing (+ strain). One call before the timed ones breaks what
// breaks, so those run the damaged state.
void kernel_of(benchmark::State& st, const std::string& text, double noise, double strain) {
  const Scene scene = parse_scene(text, "bench");
  const Nodes nodes = discretize(scene);
  CellList cells(nodes, reach(nodes.bodies[0]));
  const Partition part = partition_from_parts(nodes, std::vector<int>(nodes.size(), 0), 1);
  Domain d = build_domain(scene, nodes, cells, part, 0);
  const BondLaw law = calibrate(scene.materials[0], nodes.bodies[0], "bench");
  std::vector<double> u(3 * static_cast<std::size_t>(d.local()));
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> U(-noise, noise);
  for (double& x : u) x = U(rng);
  for (std::int32_t i = 0; i < d.local(); ++i) u[3 * static_cast<std::size_t>(i)] += strain * d.X[3 * static_cast<std::size_t>(i)];
  std::vector<std::int32_t> rows(d.owned);
  for (std::int32_t i = 0; i < d.owned; ++i) rows[i] = i;
  std::vector<double> F(3 * static_cast<std::size_t>(d.owned));
  const std::int64_t stride = position_plane_stride(d.local());
  std::vector<double> x(3 * static_cast<std::size_t>(stride));
  current_positions(d.X.data(), u.data(), 0, d.local(), stride, x.data());
  BondView v{d.X.data(), u.data(), d.volume.data(), d.bonds.offsets.data(), d.bonds.neighbor.data(),
             d.bonds.broken.data(), &d.bonds.patterns, x.data(), stride, d.bonds.row_broken.data()};
  const RowBlocks plan = plan_rows(v, rows.data(), rows.size());
  BondTally t;
  bond_forces(law, v, plan, F.data(), false, t);
  std::int64_t broken = 0;
  for (std::uint8_t f : d.bonds.broken) broken += f != 0;
  for (auto _ : st) {
    bond_forces(law, v, plan, F.data(), false, t);
    benchmark::DoNotOptimize(F.data());
  }
  st.counters["nodes"] = d.owned;
  st.counters["broken_share"] = static_cast<double>(broken) / static_cast<double>(d.bonds.size());
  st.counters["bonds"] = static_cast<double>(d.bonds.size());
  st.counters["bond_updates/s"] = benchmark::Counter(static_cast<double>(d.bonds.size()), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["bytes_per_bond"] = d.bonds.bytes_per_bond() + static_cast<double>(plan.extra_bytes()) / static_cast<double>(d.bonds.size());
  st.counters["block_rows"] = static_cast<double>(plan.run_rows()) / static_cast<double>(plan.rows());
  st.counters["rows_per_run"] = static_cast<double>(plan.run_rows()) / static_cast<double>(std::max<std::size_t>(1, plan.runs.size()));
  if (!plan.free.empty()) {
    // The free rows' lane use: their bonds over the slots their vector groups walk (each group of
    // W consecutive rows runs as long as its longest family).
#if defined(PERI_AVX2)
    constexpr std::size_t W = simd::Wide::W;
#else
    constexpr std::size_t W = 1;  // the portable walk: one row at a time
#endif
    std::int64_t bonds = 0, walked = 0;
    for (std::size_t r = 0; r < plan.free.size(); r += W) {
      std::int64_t longest = 0;
      for (std::size_t l = r; l < std::min(r + W, plan.free.size()); ++l) {
        const std::int64_t n = d.bonds.offsets[plan.free[l] + 1] - d.bonds.offsets[plan.free[l]];
        bonds += n;
        longest = std::max(longest, n);
      }
      walked += static_cast<std::int64_t>(W) * longest;
    }
    st.counters["free_lane_use"] = static_cast<double>(bonds) / static_cast<double>(std::max<std::int64_t>(1, walked));
  }
}

void kernel(benchmark::State& st, const char* model, const char* quadrature, double critical_stretch, double noise) {
  kernel_of(st, membrane_scene(model, static_cast<int>(st.range(0)), quadrature, critical_stretch), noise, 0.0);
}

// The 3D block: intact (s_0 = 0.5), or with s_0 = 0.0005 under a strain of 0.002 along x, which
// breaks half its bonds (as late in compare_lammps.py's run, where a third break).
void kernel_solid(benchmark::State& st, double critical_stretch, double strain) {
  kernel_of(st, solid_scene(static_cast<int>(st.range(0)), critical_stretch), 1e-7, strain);
}

// The intact 3D block with whole weights (the point cloud's quadrature), for kernel_cloud.
void kernel_solid_full(benchmark::State& st) {
  kernel_of(st, solid_scene(static_cast<int>(st.range(0)), 0.5, "full"), 1e-7, 0.0);
}

// Irregular node sets (no grid, no shared families) beside the grid cases of the same density:
// the jittered membrane mesh (nodes moved up to 0.3 spacings) against membrane_full, and the
// jittered point cloud against pmb_block_full (with whole weights, and with the point cloud's
// default partial-volume weights, kept per bond).
void kernel_mesh_membrane(benchmark::State& st) {
  kernel_of(st, mesh_membrane_scene(jittered_membrane_mesh(static_cast<int>(st.range(0)), 0.3)), 1e-5, 0.0);
}
void kernel_cloud(benchmark::State& st, const char* quadrature) {
  kernel_of(st, cloud_solid_scene(jittered_cloud(static_cast<int>(st.range(0)), 0.3), quadrature), 1e-7, 0.0);
}

// The ceiling a PMB bond loop cannot pass on this core: 1/|y| for four lanes as a square root and
// a division (what the loop does per four bonds, AVX2 having no double-precision reciprocal square
// root), nothing else. Counter: lanes per second (one lane = one bond).
void pmb_divider_ceiling(benchmark::State& st) {
  std::vector<double> y2(1024);
  for (std::size_t i = 0; i < y2.size(); ++i) y2[i] = 1e-6 * (1.0 + 1e-3 * static_cast<double>(i));
#if defined(__AVX2__)
  __m256d sum = _mm256_setzero_pd();
  for (auto _ : st) {
    for (std::size_t i = 0; i < y2.size(); i += 4)
      sum = _mm256_add_pd(sum, _mm256_div_pd(_mm256_set1_pd(1.0), _mm256_sqrt_pd(_mm256_loadu_pd(&y2[i]))));
    benchmark::DoNotOptimize(sum);
  }
#else
  double sum = 0;
  for (auto _ : st) {
    for (double v : y2) sum += 1.0 / std::sqrt(v);
    benchmark::DoNotOptimize(sum);
  }
#endif
  st.counters["lanes/s"] = benchmark::Counter(static_cast<double>(y2.size()), benchmark::Counter::kIsIterationInvariantRate);
}

// Full explicit step (halo exchange, kernel, Verlet update, boundary logic) through Simulation.
void full_step(benchmark::State& st, const char* model) {
  const int n = static_cast<int>(st.range(0));
  const Scene scene = parse_scene(membrane_scene(model, n, "partial_area", 5.0), "bench");
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(scene, PETSC_COMM_WORLD, quiet);
  sim.begin();
  for (auto _ : st) sim.advance(1);
  st.counters["bond_updates/s"] = benchmark::Counter(static_cast<double>(sim.summary().ordered_bonds), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["bonds"] = static_cast<double>(sim.summary().ordered_bonds);
}

// Random displacements up to 1e-5 m (strains up to 2%); nothing breaks (lambda_0 = 5, s_0 = 0.5).
BENCHMARK_CAPTURE(kernel, membrane_partial_area, "membrane", "partial_area", 5.0, 1e-5)->Arg(100)->Arg(400)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(kernel, membrane_full, "membrane", "full", 5.0, 1e-5)->Arg(200)->Arg(400)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(kernel, pmb_partial_area, "pmb", "partial_area", 0.5, 1e-5)->Arg(400)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(kernel_solid, pmb_block_intact, 0.5, 0.0)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(kernel_solid, pmb_block_half_broken, 0.0005, 0.002)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK(kernel_solid_full)->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK(kernel_mesh_membrane)->Arg(200)->Arg(400)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(kernel_cloud, full, "full")->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(kernel_cloud, partial_area, "partial_area")->Arg(64)->Unit(benchmark::kMillisecond);
BENCHMARK(pmb_divider_ceiling);
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
