// Work-precision: error against cost for three problems with known answers, at ladders of
// resolution. Prints a table and writes a CSV; asserts nothing.
//
//   (a) homogeneous stretch energy density vs eq. (19), lambda = (1.5, 1.2), interior nodes;
//   (b) longitudinal wave speed vs the continuum c_l = 1000 m/s (plane front in a plate, two
//       probes, half-amplitude arrival; the whole solver on all ranks of the job);
//   (c) energy release rate: the work to advance a crack slowly vs eq. (30) (fracture_energy.hpp).
// Ladders: "fixed_delta" (dx -> 0 at fixed horizon, m = delta/dx grows) and "fixed_m" (m = 3,
// delta and dx -> 0 together).
//
// usage: mpirun -n N work_precision [--quick] [--csv FILE]
// Wall times of (a) and (c) are medians of 3 runs (one rank); (b) is one run of the solver.
#include <petscsys.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "peri/models/fracture_energy.hpp"
#include "peri/stages/simulation.hpp"

namespace peri {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Result {
  std::string problem, ladder;
  double m, dx, delta;
  double nodes, bonds, seconds, value, exact;
  double error() const { return std::fabs(value / exact - 1.0); }
};

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

template <class F>
double median_time(int repeats, F&& f) {
  std::vector<double> t;
  for (int r = 0; r < repeats; ++r) {
    const double t0 = now();
    f();
    t.push_back(now() - t0);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

// A square membrane sheet of half-width `half` (a whole number of cells), spacing dx, horizon delta.
Scene sheet_scene(double half_x, double half_y, double dx, double delta) {
  char text[1024];
  std::snprintf(text, sizeof text, R"(
name: sheet
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2.0}
bodies:
  sheet: {material: rubber, origin: [%.17g, %.17g, 0], size: [%.17g, %.17g], thickness: 0.0005, spacing: %.17g, horizon: %.17g}
stages:
  - {name: none, steps: 1}
)", -half_x, -half_y, 2 * half_x, 2 * half_y, dx, delta);
  return parse_scene(text, "work-precision");
}

// (a) Mean energy density of the nodes within delta of the centre (complete families).
Result homogeneous_energy(const std::string& ladder, double delta, double m) {
  const double dx = delta / m, l1 = 1.5, l2 = 1.2;
  const double half = std::ceil(2.5 * delta / dx) * dx;
  Result r{"stretch_energy", ladder, m, dx, delta, 0, 0, 0, 0, 0};
  double W = 0;
  r.seconds = median_time(3, [&] {
    const Scene scene = sheet_scene(half, half, dx, delta);
    const Nodes nodes = discretize(scene);
    const CellList cells(nodes, reach(nodes.bodies[0]));
    const BondLaw law = calibrate(scene.materials[0], nodes.bodies[0], "sheet");
    std::vector<std::int64_t> ids;
    std::vector<double> w;
    double sum = 0, count = 0, bonds = 0;
    for (std::int64_t i = 0; i < nodes.size(); ++i) {
      const double* xi = &nodes.X[3 * i];
      if (std::max(std::fabs(xi[0]), std::fabs(xi[1])) > delta) continue;
      neighbours_of(nodes, cells, i, ids, w);
      double Wi = 0;
      for (std::size_t k = 0; k < ids.size(); ++k) {
        const double* xj = &nodes.X[3 * ids[k]];
        const double a = xj[0] - xi[0], b = xj[1] - xi[1];
        Wi += 0.5 * law.energy(a * a + b * b, l1 * l1 * a * a + l2 * l2 * b * b) * w[k] * nodes.volume[ids[k]];
      }
      sum += Wi;
      count += 1;
      bonds += ids.size();
    }
    W = sum / count;
    r.nodes = count;
    r.bonds = bonds;
    r.exact = kPi * scene.bodies[0].thickness * law.derived("micromodulus") * (delta * delta / 2) / 2 * (l1 * l1 + l2 * l2 + 2 / (l1 * l2) - 4);
  });
  r.value = W;
  return r;
}

// (c) Work to advance a straight crack by 4 delta (a whole number of cells) along y = 0, between
// node rows, its ends off any bond's crossing point.
Result release_rate(const std::string& ladder, double delta, double m) {
  const double dx = delta / m;
  const double advance = std::ceil(4 * delta / dx) * dx;
  const double half_x = std::ceil((0.5 * advance + 2 * delta) / dx) * dx, half_y = std::ceil(2 * delta / dx) * dx;
  Result r{"release_rate", ladder, m, dx, delta, 0, 0, 0, 0, 0};
  r.seconds = median_time(3, [&] {
    const Scene scene = sheet_scene(half_x, half_y, dx, delta);
    const Nodes nodes = discretize(scene);
    const CellList cells(nodes, reach(nodes.bodies[0]));
    const BondLaw law = calibrate(scene.materials[0], nodes.bodies[0], "sheet");
    Crack seg;
    seg.from = {-0.5 * advance + 0.3183098862 * dx, 0, 0};
    seg.to = {0.5 * advance + 0.3183098862 * dx, 0, 0};
    const CrackAdvanceEnergy e = crack_advance_energy(nodes, cells, law, 0, seg);
    r.value = e.release_rate;
    r.bonds = e.bonds;
    r.nodes = nodes.size();
    r.exact = eq30_release_rate(law, scene.bodies[0].thickness);
  });
  return r;
}

// (b) Plane longitudinal front from a driven edge band; arrival of half the driving velocity at
// two centre-line probes.
double half_crossing(const std::vector<double>& t, const std::vector<double>& v, double half) {
  for (std::size_t k = 1; k < v.size(); ++k)
    if (v[k - 1] < half && v[k] >= half) return t[k - 1] + (t[k] - t[k - 1]) * (half - v[k - 1]) / (v[k] - v[k - 1]);
  return NAN;
}
Result wave_speed(const std::string& ladder, double delta, double m) {
  const double dx = delta / m, c_l = 1000, ramp = 10 * delta / c_l, v0 = 0.1;
  const double length = 0.045, width = 0.07, x1 = 0.02, x2 = 0.035;
  char text[2048];
  std::snprintf(text, sizeof text, R"(
name: wave
materials:
  rubber: {model: membrane, density: 1200, wave_speed: %g}
bodies:
  plate: {material: rubber, origin: [0, %.17g, 0], size: [%.17g, %.17g], thickness: 0.0005, spacing: %.17g, horizon: %.17g}
boundaries:
  - {name: driver, region: {min: [-1, -1, -1], max: [%.17g, 1, 1]}, velocity: [%g, 0, 0], components: [x], ramp_time: %.17g}
stages:
  - {name: run, duration: %.17g}
output: {frames: 1, series_every: 100000}
)", c_l, -width / 2, length, width, dx, delta, delta, v0, ramp, (x2 + 2 * ramp * c_l) / c_l);
  Result r{"wave_speed", ladder, m, dx, delta, 0, 0, 0, 0, c_l};
  const double t0 = now();
  const Scene scene = parse_scene(text, "wave");
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(scene, PETSC_COMM_WORLD, quiet);
  sim.begin();
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
  sim.finish();
  r.seconds = now() - t0;
  r.value = s / (half_crossing(t, v2, v0 / 2) - half_crossing(t, v1, v0 / 2));
  r.nodes = sim.summary().nodes;
  r.bonds = double(sim.summary().ordered_bonds) / 2 * sim.summary().steps;  // bond updates
  return r;
}

}  // namespace
}  // namespace peri

int main(int argc, char** argv) {
  bool quick = false;
  std::string csv = "work_precision.csv";
  for (int k = 1; k < argc; ++k) {
    if (!std::strcmp(argv[k], "--quick")) quick = true;
    else if (!std::strcmp(argv[k], "--csv") && k + 1 < argc) csv = argv[++k];
  }
  if (PetscInitialize(&argc, &argv, nullptr, nullptr)) return 1;
  int rank;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  using namespace peri;
  std::vector<Result> rows;
  auto add = [&](const Result& r) {
    rows.push_back(r);
    if (rank == 0) {
      std::printf("%-15s %-11s m = %5.2f dx = %.4e delta = %.4e nodes %9.0f bonds %12.4g wall %8.3f s  value %.8g exact %.8g  error %.3e\n",
                  r.problem.c_str(), r.ladder.c_str(), r.m, r.dx, r.delta, r.nodes, r.bonds, r.seconds, r.value,
                  r.exact, r.error());
      std::fflush(stdout);
    }
  };
  const std::vector<double> ms_a = quick ? std::vector<double>{3, 6, 12} : std::vector<double>{3, 4, 6, 8, 12, 16, 24, 32};
  if (rank == 0) {
    for (double m : ms_a) add(homogeneous_energy("fixed_delta", 1e-3, m));
    for (double d : {4e-3, 2e-3, 1e-3, 0.5e-3}) add(homogeneous_energy("fixed_m", d, 3));
    for (double m : ms_a) add(release_rate("fixed_delta", 1e-3, m));
    for (double d : {4e-3, 2e-3, 1e-3, 0.5e-3}) add(release_rate("fixed_m", d, 3));
  }
  const std::vector<double> ms_b = quick ? std::vector<double>{2, 3} : std::vector<double>{2, 3, 4, 6};
  for (double m : ms_b) add(wave_speed("fixed_delta", 1.5e-3, m));
  for (double dx : quick ? std::vector<double>{1e-3, 0.5e-3} : std::vector<double>{1e-3, 0.5e-3, 0.25e-3})
    add(wave_speed("fixed_m", 3 * dx, 3));
  if (rank == 0) {
    std::ofstream out(csv);
    out << "problem,ladder,m,dx,delta,nodes,bonds,wall_seconds,value,exact,relative_error\n";
    out.precision(10);
    for (const Result& r : rows)
      out << r.problem << ',' << r.ladder << ',' << r.m << ',' << r.dx << ',' << r.delta << ',' << r.nodes << ','
          << r.bonds << ',' << r.seconds << ',' << r.value << ',' << r.exact << ',' << r.error() << '\n';
    std::printf("wrote %s (bonds: (a) ordered bonds of the measured nodes, (b) bond updates of the run, "
                "(c) bonds crossing the advance)\n", csv.c_str());
  }
  PetscFinalize();
  return 0;
}
