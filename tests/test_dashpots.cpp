// Kelvin-Voigt bond dashpots of the peridynamic laws (kernels/dashpots.hpp, the material key
// kelvin_viscosity) in whole runs, under MPI (registered at 1 and 2 ranks). The dashpot matrix is
// tau times the bonds' reference stiffness matrix, so every small-amplitude eigenmode of
// frequency omega obeys x'' + tau omega^2 x' + omega^2 x = 0 and loses its energy at the rate
// tau omega^2, with tau = rho nu / mu. The test measures omega on an undamped run and the decay
// on a damped one, and checks that the booked dissipation is the energy that went.
#include <gtest/gtest.h>
#include <petscsys.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "peri/geometry/discretization.hpp"
#include "peri/kernels/dashpots.hpp"
#include "peri/stages/simulation.hpp"
#include "mpi_test.hpp"

namespace peri {
namespace {

constexpr double kRho = 1000, kBulk = 1.0e6, kLength = 0.048;
constexpr double kMu = kBulk / 2;  // membranes: K = 2 mu

// A PMB membrane strip 48 mm x 6 mm (spacing 1 mm, horizon 3 mm) clamped at x = 0, free
// elsewhere, started with v_x = g x: a clamped-free bar whose first longitudinal mode holds 96 /
// pi^4 = 98.6% of the energy (mode n's share falls as (2n - 1)^-4).
std::string bar_scene(double nu) {
  char text[1024];
  std::snprintf(text, sizeof text, R"(
name: dashpot-bar
materials:
  film: {model: pmb, density: %g, bulk_modulus: %g, kelvin_viscosity: %g}
bodies:
  strip: {kind: membrane, material: film, origin: [0, 0, 0], size: [%g, 0.006], thickness: 0.001,
          spacing: 0.001, horizon_factor: 3}
boundaries:
  - {name: clamp, region: {min: [-1, -1, -1], max: [0.0011, 1, 1]}}
initial:
  velocity_gradient: [[0.02, 0, 0], [0, 0, 0], [0, 0, 0]]
stages:
  - {name: ring, duration: 0.02}
output: {frames: 1, series_every: 1000000}
)",
                kRho, kBulk, nu, kLength);
  return text;
}

struct Sampled {
  std::vector<double> t, kinetic, mechanical;
  EnergyRow first, last;
  double largest_change = 0;  // largest |E(t) - E(0)| of kinetic + strain + dissipated [J]
};

Sampled run_bar(double nu) {
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(parse_scene(bar_scene(nu), "dashpot-bar"), PETSC_COMM_WORLD, quiet);
  sim.begin();
  Sampled s;
  s.first = sim.energies();
  do {
    const EnergyRow e = sim.energies();
    s.t.push_back(e.time);
    s.kinetic.push_back(e.kinetic);
    s.mechanical.push_back(e.kinetic + e.strain);
    s.largest_change = std::max(s.largest_change, std::fabs(e.total() - s.first.total()));
  } while (sim.advance(1) > 0);
  s.last = sim.energies();
  return s;
}

// Interior local extrema of y (maxima if sign > 0), each refined by the parabola through its
// sample and the two beside it: their times.
std::vector<double> extrema(const Sampled& s, const std::vector<double>& y, int sign) {
  std::vector<double> out;
  for (std::size_t k = 1; k + 1 < y.size(); ++k) {
    const double a = sign * y[k - 1], b = sign * y[k], c = sign * y[k + 1];
    if (!(b > a && b >= c)) continue;
    const double h = s.t[k + 1] - s.t[k], shift = 0.5 * (a - c) / (a - 2 * b + c);
    out.push_back(s.t[k] + shift * h);
  }
  return out;
}

// The pass four rows at a time (AVX2 builds) against the row-by-row walk, on rows of 0 to 40
// random bonds (so lanes end at different slots), some broken, a coincident pair, rows in a
// shuffled order and a count that is not a multiple of four, with and without the rows' summary
// bytes: the same bits, and rows not asked for untouched.
TEST(Dashpots, FourRowsAtATimeAreTheBitsOfTheRowWalk) {
  constexpr std::int32_t n = 103;
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const std::int64_t stride = n + 5;
  std::vector<double> x(3 * stride), velocity(3 * n);
  for (std::int32_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      x[c * stride + i] = 1e-3 * unit(rng);
      velocity[3 * i + c] = 2.0 * unit(rng);
    }
  for (int c = 0; c < 3; ++c) x[c * stride + 8] = x[c * stride + 7];  // nodes 7 and 8 coincide
  std::vector<std::int64_t> offsets{0};
  std::vector<std::int32_t> neighbor;
  std::vector<std::uint8_t> broken, row_broken(n, 0);
  std::vector<double> coefficient;
  for (std::int32_t i = 0; i < n; ++i) {
    const int count = i == 7 ? 5 : static_cast<int>(rng() % 41);
    for (int k = 0; k < count; ++k) {
      std::int32_t j = i == 7 && k == 2 ? 8 : static_cast<std::int32_t>(rng() % n);
      if (j == i) j = (j + 1) % n;
      neighbor.push_back(j);
      const bool cut = i % 5 == 1 && rng() % 4 == 0;
      broken.push_back(cut ? kBrokenFlag : 0);
      row_broken[i] |= cut;
      coefficient.push_back(1e3 * (1.5 + unit(rng)));
    }
    offsets.push_back(static_cast<std::int64_t>(neighbor.size()));
  }
  std::vector<std::int32_t> rows(n);
  for (std::int32_t i = 0; i < n; ++i) rows[i] = i;
  std::shuffle(rows.begin(), rows.end(), rng);
  const std::int32_t skipped[2] = {rows[n - 2], rows[n - 1]};
  rows.resize(n - 2);  // 101 rows: the last group holds one
  BondView v;
  v.offsets = offsets.data();
  v.neighbor = neighbor.data();
  v.broken = broken.data();
  v.x = x.data();
  v.x_stride = stride;
  simd::AlignedVector<double> records(kDashpotRecord * n);
  dashpot_records(v, velocity.data(), n, records.data());
  for (std::uint8_t* summary : {row_broken.data(), static_cast<std::uint8_t*>(nullptr)}) {
    v.row_broken = summary;
    const double unset = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> fast(3 * n, unset), walk(3 * n, unset);
    bond_dashpots(v, records.data(), dashpot_lanes(v, coefficient.data(), rows.data(), rows.size()), rows.data(),
                  rows.size(), fast.data());
    bond_dashpots_portable(v, records.data(), coefficient.data(), rows.data(), rows.size(), walk.data());
    EXPECT_EQ(std::memcmp(fast.data(), walk.data(), fast.size() * sizeof(double)), 0)
        << (summary ? "with" : "without") << " the rows' summary bytes";
    for (std::int32_t i : rows) EXPECT_TRUE(std::isfinite(fast[3 * i]) && std::isfinite(fast[3 * i + 2])) << "row " << i;
    for (std::int32_t i : skipped) EXPECT_TRUE(std::isnan(fast[3 * i]) && std::isnan(fast[3 * i + 2])) << "row " << i;
  }
  // Row 7's bond to its coincident neighbour adds nothing: its force is that of its other bonds.
  v.row_broken = nullptr;
  double all[3 * n], without[3 * n];
  const std::int32_t seven = 7;
  bond_dashpots(v, records.data(), dashpot_lanes(v, coefficient.data(), &seven, 1), &seven, 1, all);
  coefficient[offsets[7] + 2] = 0;
  bond_dashpots(v, records.data(), dashpot_lanes(v, coefficient.data(), &seven, 1), &seven, 1, without);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(all[21 + c], without[21 + c]);
}

TEST(Dashpots, StableStepMeetsTheJuryBound) {
  const double dt0 = 2.0e-7;
  EXPECT_EQ(dashpot_stable_time_step(dt0, 0.0), dt0);
  for (double tau : {1e-9, 4e-8, 1e-6}) {
    const double dt = dashpot_stable_time_step(dt0, tau);
    EXPECT_LT(dt, dt0);
    // (omega dt)^2 / 4 + tau omega^2 dt / 2 = 1 at omega = 2 / dt0.
    EXPECT_NEAR(dt * dt / (dt0 * dt0) + 2 * tau * dt / (dt0 * dt0), 1.0, 1e-14) << tau;
  }
}

TEST(Dashpots, SizeEstimateCountsTheirConstants) {
  // The memory check's estimate: 12.5 more bytes per ordered bond (each bond's tau C w V and its
  // neighbour in the pass's vector groups, DashpotLanes, whose slots are 1.01-1.04 times the
  // bonds) and 112 per node (the dashpot force, the velocity they saw, the pass's node record)
  // than without dashpots.
  const SizeEstimate without = estimate_size(parse_scene(bar_scene(0.0), "bar")),
                     with = estimate_size(parse_scene(bar_scene(0.01), "bar"));
  EXPECT_EQ(with.bonds, without.bonds);
  EXPECT_NEAR(with.bytes - without.bytes, 12.5 * without.bonds + 112.0 * without.nodes, 1e-6 * with.bytes);
  EXPECT_GT(without.bonds, 0.0);
}

TEST(Dashpots, EachModeDecaysAtTauOmegaSquaredAndTheWorkIsBooked) {
  // omega of the first mode from the undamped run: kinetic energy ~ cos^2(omega t), its minima
  // pi / omega apart.
  const Sampled free = run_bar(0.0);
  const std::vector<double> minima = extrema(free, free.kinetic, -1);
  ASSERT_GE(minima.size(), 3u);
  const double omega = M_PI * static_cast<double>(minima.size() - 1) / (minima.back() - minima.front());
  const double c_bar = std::sqrt(8.0 * kMu / 3.0 / kRho);  // E = 8 mu / 3 of a membrane
  // Damped: nu such that tau omega = 0.04 (damping ratio 0.02).
  const double tau = 0.04 / omega, nu = tau * kMu / kRho;
  const Sampled damped = run_bar(nu);
  // The decay of kinetic + strain between kinetic-energy maxima a whole number of half periods
  // apart (the mean of 2 x kinetic over a half period is the energy), skipping the first half
  // period (the higher modes, 9 and more times faster to decay).
  const std::vector<double> maxima = extrema(damped, damped.kinetic, +1);
  ASSERT_GE(maxima.size(), 4u);
  auto mechanical_at = [&](double time) {
    std::size_t k = 0;
    while (k + 1 < damped.t.size() && damped.t[k + 1] <= time) ++k;
    const double w = (time - damped.t[k]) / (damped.t[k + 1] - damped.t[k]);
    return (1 - w) * damped.mechanical[k] + w * damped.mechanical[k + 1];
  };
  const double ta = maxima[1], tb = maxima.back();
  const double rate = std::log(mechanical_at(ta) / mechanical_at(tb)) / (tb - ta);
  const double e0 = damped.first.kinetic;
  if (world_rank() == 0)
    std::printf("dashpot bar: omega %.2f rad/s (bar closed form c pi / 2L = %.2f), tau %.3e s (nu %.4e m^2/s); "
                "energy decay rate %.3f 1/s against tau omega^2 = %.3f (ratio %.4f); dissipated %.4e J of %.4e J, "
                "largest |E - E0| / E0 %.2e\n",
                omega, c_bar * M_PI / (2 * kLength), tau, nu, rate, tau * omega * omega, rate / (tau * omega * omega),
                damped.last.dissipated, e0, damped.largest_change / e0);
  EXPECT_NEAR(rate / (tau * omega * omega), 1.0, 0.03);
  EXPECT_GT(damped.last.dissipated, 0.5 * e0);        // most of the energy went, into the dashpots
  EXPECT_LT(damped.largest_change / e0, 2e-3);        // and all of it is booked
  EXPECT_LT(free.largest_change / free.first.kinetic, 2e-3);
  EXPECT_EQ(free.last.dissipated, 0.0);
}

// A membrane sheet 10 mm x 10 mm (spacing 0.5 mm) pulled apart by its top and bottom bands at
// 5 m/s, ramped up over half the run: the dashpots of the bonds between a moving band and the
// free nodes work against the bands' reaction (external work) and dissipate that work too. Its
// energy balance error at safety factor sf, with the detector off (the unbooked share stopped
// nu >= 0.1 for "an unstable time step").
RunSummary pulled_sheet(double nu, double sf) {
  char text[1024];
  std::snprintf(text, sizeof text, R"(
name: dashpot-pull
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2.0, kelvin_viscosity: %g}
bodies:
  sheet: {kind: membrane, material: rubber, origin: [-0.005, -0.005, 0], size: [0.01, 0.01],
          thickness: 0.0005, spacing: 0.0005}
boundaries:
  - {name: top, region: {min: [-1, 0.0045, -1], max: [1, 1, 1]}, velocity: [0, 5, 0], ramp_time: 5.0e-6}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0045, 1]}, velocity: [0, -5, 0], ramp_time: 5.0e-6}
stages:
  - {name: pull, duration: 1.0e-5, safety_factor: %g}
stability: {energy_error: 0}
output: {frames: 1}
)",
                nu, sf);
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(parse_scene(text, "dashpot-pull"), PETSC_COMM_WORLD, quiet);
  sim.run();
  return sim.summary();
}

TEST(Dashpots, WorkAgainstMovingBoundariesIsBookedAsDissipated) {
  // Without the prescribed nodes' share of the dissipation the error was 3.3e-3 (nu = 0.01) and
  // 3.7e-2 (nu = 0.1) at both step sizes; booked, it is the integrator's own (7.3e-5 and 1.3e-5
  // at 0.35, undamped 8.9e-5), second order in dt (5.9e-6 and 1.1e-6 at 0.1).
  const RunSummary undamped = pulled_sheet(0.0, 0.35);
  for (double nu : {0.01, 0.1}) {
    const RunSummary coarse = pulled_sheet(nu, 0.35), fine = pulled_sheet(nu, 0.1);
    if (world_rank() == 0)
      std::printf("pulled sheet, nu %g m^2/s: dissipated %.4e J of external work %.4e J; energy balance error "
                  "%.3e at safety factor 0.35, %.3e at 0.1 (undamped %.3e)\n",
                  nu, coarse.final_energy.dissipated, coarse.final_energy.external_work, coarse.energy_balance_error,
                  fine.energy_balance_error, undamped.energy_balance_error);
    EXPECT_GT(coarse.final_energy.dissipated, 5e-3 * coarse.final_energy.external_work) << nu;
    EXPECT_LT(coarse.energy_balance_error, 2.0 * undamped.energy_balance_error) << nu;
    EXPECT_LT(fine.energy_balance_error, coarse.energy_balance_error / 5) << nu;  // (0.35 / 0.1)^2 = 12
  }
}

}  // namespace
}  // namespace peri
