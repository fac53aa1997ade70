// Checkpoint and restart, in process, under MPI (registered at 1 and 2 ranks): a run continued
// from a checkpoint must end bit for bit where the uninterrupted run ends; damaged, foreign and
// mismatched checkpoints must be refused with a clear message.
#include <gtest/gtest.h>
#include <petscsys.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <memory>

#include <unistd.h>

#include "peri/io/checkpoint.hpp"
#include "peri/core/error.hpp"
#include "peri/core/resources.hpp"
#include "peri/io/restart.hpp"
#include "peri/stages/simulation.hpp"
#include "mpi_test.hpp"

namespace peri {
namespace {

// Small slit membrane that fractures within a few hundred steps, over two stages.
const char* kScene = R"(
name: small-slit
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 1.6}
bodies:
  sheet: {material: rubber, origin: [-0.01, -0.01, 0], size: [0.02, 0.02], thickness: 0.0005, spacing: 0.0005}
cracks:
  - {name: slit, from: [-0.003, 0, 0], to: [0.003, 0, 0]}
boundaries:
  - {name: top, region: {min: [-1, 0.0088, -1], max: [1, 1, 1]}, velocity: [0, 20, 0], ramp_time: 1.0e-5}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0088, 1]}, velocity: [0, -20, 0], ramp_time: 1.0e-5}
initial:
  displacement_gradient: [[0, 0, 0], [0, 0.1, 0], [0, 0, 0]]
  velocity_gradient: [[0, 0, 0], [0, 2000, 0], [0, 0, 0]]
  seed: {amplitude: 1.0e-6, wavelength: [0.004, 0.004]}
stages:
  - {name: pull, duration: 3.0e-5}
  - {name: hold, duration: 2.0e-5, safety_factor: 0.5}
output: {frames: 1, series_every: 10}
)";

/// A file name private to this test and rank, removed at the end of the test.
struct TempFile {
  std::string path;
  explicit TempFile(const std::string& stem)
      : path((std::filesystem::temp_directory_path() /
              (stem + "-" + std::to_string(::getpid()) + "-" + std::to_string(world_rank()) + ".h5"))
                 .string()) {}
  ~TempFile() {
    std::remove(path.c_str());
    std::remove(previous_checkpoint_path(path).c_str());
  }
};

/// Same path on every rank (rank 0's pid), for collective writes.
std::string shared_path(const std::string& stem) {
  long pid = ::getpid();
  MPI_Bcast(&pid, 1, MPI_LONG, 0, PETSC_COMM_WORLD);
  return (std::filesystem::temp_directory_path() / (stem + "-" + std::to_string(pid) + ".h5")).string();
}

RunOptions quiet() {
  RunOptions o;
  o.quiet = true;
  return o;
}

/// Runs `scene` for `steps` steps, checkpoints it to a shared file, and returns the run resumed
/// from that checkpoint and taken to its end; `inspect` sees the loaded checkpoint first.
std::unique_ptr<Simulation> resumed_run(const Scene& scene, std::int64_t steps, const std::string& stem,
                                        const std::function<void(const Checkpoint&)>& inspect = {}) {
  const std::string path = shared_path(stem);
  {
    Simulation first(scene, PETSC_COMM_WORLD, quiet());
    first.begin();
    first.advance(steps);
    store_checkpoint(path, first.make_checkpoint(), PETSC_COMM_WORLD);
  }
  RunOptions o = quiet();
  o.restart = load_checkpoint(path, PETSC_COMM_WORLD);
  if (inspect) inspect(*o.restart);
  auto second = std::make_unique<Simulation>(scene, PETSC_COMM_WORLD, o);
  second->run();
  if (world_rank() == 0) {
    std::remove(path.c_str());
    std::remove(previous_checkpoint_path(path).c_str());
  }
  return second;
}

/// Position and velocity values (natural order) in which two runs differ.
std::size_t differing_state(Simulation& a, Simulation& b) {
  const auto xa = a.natural_positions(), xb = b.natural_positions();
  const auto va = a.natural_velocities(), vb = b.natural_velocities();
  std::size_t differing = 0;
  for (std::size_t k = 0; k < xa.size(); ++k) differing += xa[k] != xb[k] || va[k] != vb[k];
  return differing;
}

TEST(Restart, ContinuedRunIsBitForBitTheUninterruptedOne) {
  const Scene scene = parse_scene(kScene, "small-slit");
  Simulation whole(scene, PETSC_COMM_WORLD, quiet());
  whole.run();

  const std::int64_t checkpoint_step = whole.total_steps() / 2 + 7;  // inside the second stage, between series rows
  const auto resumed = resumed_run(scene, checkpoint_step, "restart-bits", [&](const Checkpoint& c) {
    EXPECT_EQ(c.step, checkpoint_step);
    EXPECT_EQ(c.stage, 1);
  });
  Simulation& second = *resumed;

  EXPECT_EQ(second.current_step(), whole.current_step());
  EXPECT_EQ(second.current_time(), whole.current_time());
  const auto xa = whole.natural_positions();
  const std::size_t differing = differing_state(whole, second);
  const auto ba = whole.broken_bonds(), bb = second.broken_bonds();
  const EnergyRow ea = whole.summary().final_energy, eb = second.summary().final_energy;
  if (world_rank() == 0)
    std::printf("restart at step %lld of %lld: %zu of %zu position/velocity values differ; broken bonds %zu vs %zu; "
                "dissipated %.17g vs %.17g\n",
                static_cast<long long>(checkpoint_step), static_cast<long long>(whole.total_steps()), differing,
                xa.size(), ba.size(), bb.size(), ea.dissipated, eb.dissipated);
  EXPECT_EQ(differing, 0u);
  EXPECT_EQ(ba, bb);
  EXPECT_GT(ba.size(), 100u);  // the crack ran: the flags were worth restoring
  // Same rank count: per-rank tallies continue, so the energy sums agree bit for bit too.
  EXPECT_EQ(ea.dissipated, eb.dissipated);
  EXPECT_EQ(ea.external_work, eb.external_work);
  EXPECT_EQ(ea.kinetic, eb.kinetic);
  EXPECT_EQ(ea.strain, eb.strain);
  EXPECT_EQ(ea.broken_bonds, eb.broken_bonds);
  EXPECT_EQ(whole.summary().energy_balance_error, second.summary().energy_balance_error);
}

// A rigid cylinder with friction pushed into the edge of a clamped PMB strip: contact forces and
// friction act at the checkpoint. The tool starts 0.5 mm clear of the strip (a tool may not start
// with nodes inside it) and reaches it after 25 us.
const char* kToolScene = R"(
name: tool
materials:
  film: {model: pmb, density: 1200, bulk_modulus: 3.0e8, critical_stretch: 0.03}
bodies:
  sheet: {material: film, origin: [0, 0, 0], size: [0.01, 0.008], thickness: 0.0002, spacing: 0.0004}
boundaries:
  - {name: lower, region: {min: [-1, -1, -1], max: [1, 0.0009, 1]}}
  - {name: upper, region: {min: [-1, 0.0071, -1], max: [1, 1, 1]}}
tools:
  - {name: rod, kind: cylinder, radius: 0.0015, center: [-0.0018, 0.004], velocity: [20, 0], friction: 0.5}
initial:
  seed: {amplitude: 1.0e-6, wavelength: [0.004, 0.004]}
stages:
  - {name: push, duration: 1.0e-4}
output: {frames: 1, series_every: 10}
)";

TEST(Restart, WithAFrictionalToolIsBitForBit) {
  const Scene scene = parse_scene(kToolScene, "tool");
  Simulation whole(scene, PETSC_COMM_WORLD, quiet());
  whole.run();
  const auto resumed = resumed_run(scene, whole.total_steps() / 2 + 3, "restart-tool");
  Simulation& second = *resumed;
  const auto xa = whole.natural_positions();
  const std::size_t differing = differing_state(whole, second);
  const EnergyRow ea = whole.summary().final_energy, eb = second.summary().final_energy;
  if (world_rank() == 0)
    std::printf("tool scene, %lld steps: %zu of %zu values differ after the restart; external work %.17g vs %.17g, "
                "dissipated (friction and bonds) %.17g, energy balance error %.3g\n",
                static_cast<long long>(whole.total_steps()), differing, xa.size(), ea.external_work, eb.external_work,
                ea.dissipated, whole.summary().energy_balance_error);
  EXPECT_EQ(differing, 0u);
  EXPECT_GT(ea.dissipated, 0.0);  // friction worked before and after the checkpoint
  EXPECT_EQ(ea.external_work, eb.external_work);
  EXPECT_EQ(ea.dissipated, eb.dissipated);
  EXPECT_EQ(ea.strain, eb.strain);
  // A violent, coarse case (20 m/s, 0.4 mm spacing); the balance at the scene's resolution is
  // checked by the ctest blunt_tool.
  EXPECT_LT(whole.summary().energy_balance_error, 0.05);
}

// Bond dashpots make the force depend on the velocity they see: the half step's in a step, which
// the step's end overwrites; the checkpoint keeps it so that the resumed run's first force
// evaluation is the uninterrupted run's. Peridynamic dashpots (the tool scene) and the lattice's,
// on a lattice whose bonds break only in a box about the crack's line (the others carry an
// unbreakable bit beside the broken one, which the file must neither record as broken nor
// erase), in both breaking modes (the reversible one keeps the pre-crack's bonds cut by a bit of
// their own).
const char* kLatticeDashpotScene = R"(
name: lattice-dashpots
materials:
  rubber: {model: marder, density: 1000, mooney_rivlin_a: 1000, mooney_rivlin_b: 0.3, cutoff: 5.0e-5,
           fracture_separation: 0.002, kelvin_viscosity: 0.002, breaking: BREAKING}
bodies:
  strip: {kind: lattice, material: rubber, origin: [0, -0.010392305, 0], size: [0.04, 0.02078461], thickness: 0.001, spacing: 0.001,
          breakable: {min: [-1, -0.003, -1], max: [1, 0.003, 1]}}
cracks:
  - {name: seed, from: [-1, 0, 0], to: [0.012, 0, 0]}
boundaries:
  - {name: top, region: {min: [-1, 0.0095, -1], max: [1, 1, 1]}}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0095, 1]}}
initial:
  displacement_gradient: [[0.1, 0, 0], [0, 0.8, 0], [0, 0, 0]]
stages:
  - {name: run, steps: 600, safety_factor: 0.7}
output: {frames: 1, series_every: 10}
)";

TEST(Restart, WithBondDashpotsIsBitForBit) {
  std::string tool = kToolScene;
  tool.replace(tool.find("critical_stretch: 0.03}"), 23, "critical_stretch: 0.03, kelvin_viscosity: 0.01}");
  std::string irreversible = kLatticeDashpotScene, reversible = kLatticeDashpotScene;
  irreversible.replace(irreversible.find("BREAKING"), 8, "irreversible");
  reversible.replace(reversible.find("BREAKING"), 8, "reversible");
  for (const auto& [text, name] : {std::pair<std::string, std::string>{tool, "tool, peridynamic dashpots"},
                                   {irreversible, "lattice dashpots, breakable box"},
                                   {reversible, "lattice dashpots, breakable box, reversible"}}) {
    const Scene scene = parse_scene(text, name);
    Simulation whole(scene, PETSC_COMM_WORLD, quiet());
    whole.run();
    const auto resumed = resumed_run(scene, whole.total_steps() / 2 + 3, "restart-dashpots", [](const Checkpoint& c) {
      EXPECT_TRUE(c.has_dashpot_velocity);
    });
    Simulation& second = *resumed;
    const std::size_t values = whole.natural_positions().size(), differing = differing_state(whole, second);
    const EnergyRow ea = whole.summary().final_energy, eb = second.summary().final_energy;
    if (world_rank() == 0)
      std::printf("%s, %lld steps: %zu of %zu values differ after the restart; dissipated %.17g vs %.17g, "
                  "broken bonds %lld\n",
                  name.c_str(), static_cast<long long>(whole.total_steps()), differing, values, ea.dissipated,
                  eb.dissipated, static_cast<long long>(ea.broken_bonds));
    EXPECT_EQ(differing, 0u) << name;
    EXPECT_GT(ea.dissipated, 0.0) << name;  // the dashpots (and bonds) worked before and after the checkpoint
    EXPECT_EQ(ea.dissipated, eb.dissipated) << name;
    EXPECT_EQ(ea.external_work, eb.external_work) << name;
    EXPECT_EQ(ea.strain, eb.strain) << name;
    EXPECT_EQ(ea.broken_bonds, eb.broken_bonds) << name;
  }
}

// Quasi-static preload, release of a slit, a damped dynamic stage, then a pulled one.
const char* kStagedScene = R"(
name: staged
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2}
bodies:
  sheet: {material: rubber, origin: [-0.01, -0.01, 0], size: [0.02, 0.02], thickness: 0.0005, spacing: 0.0005}
cracks:
  - {name: slit, from: [-0.002, 0, 0], to: [0.002, 0, 0]}
boundaries:
  - {name: top, region: {min: [-1, 0.0088, -1], max: [1, 1, 1]}}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0088, 1]}}
initial:
  seed: {amplitude: 1.0e-6, wavelength: [0.005, 0.005]}
stages:
  - {name: preload, kind: quasistatic, displacements: {top: [0, 0.005, 0], bottom: [0, -0.005, 0]}, load_steps: 3}
  - {name: cut, kind: release, cracks: [slit]}
  - {name: settle, steps: 40, damping: 2.0e4, safety_factor: 0.35}
  - {name: pull, duration: 2.0e-5, safety_factor: 0.35, boundary_velocity: {top: [0, 5, 0], bottom: [0, -5, 0]}}
output: {frames: 1, series_every: 5}
)";

TEST(Restart, AfterQuasiStaticReleaseAndDampedStages) {
  const Scene scene = parse_scene(kStagedScene, "staged");
  Simulation whole(scene, PETSC_COMM_WORLD, quiet());
  whole.run();
  const auto resumed = resumed_run(scene, 25, "restart-staged", [](const Checkpoint& c) {  // inside the damped stage
    EXPECT_EQ(c.stage, 2);
    EXPECT_EQ(c.stage_step, 25);
  });
  Simulation& second = *resumed;
  const auto xa = whole.natural_positions(), xb = second.natural_positions();
  std::size_t differing = 0;
  for (std::size_t k = 0; k < xa.size(); ++k) differing += xa[k] != xb[k];
  const RunSummary &a = whole.summary(), &b = second.summary();
  if (world_rank() == 0)
    std::printf("staged restart: %zu of %zu positions differ; precrack+released bonds %lld vs %lld; "
                "quasi-static increments %zu vs %zu; dissipated (with damping) %.17g vs %.17g\n",
                differing, xa.size(), static_cast<long long>(a.precrack_bonds),
                static_cast<long long>(b.precrack_bonds), a.quasistatic.at(0).second.increments.size(),
                b.quasistatic.empty() ? 0 : b.quasistatic[0].second.increments.size(), a.final_energy.dissipated,
                b.final_energy.dissipated);
  EXPECT_EQ(differing, 0u);
  EXPECT_EQ(whole.broken_bonds(), second.broken_bonds());
  EXPECT_EQ(a.final_energy.dissipated, b.final_energy.dissipated);
  EXPECT_EQ(a.final_energy.external_work, b.final_energy.external_work);
  EXPECT_EQ(a.energy_balance_error, b.energy_balance_error);
  EXPECT_EQ(a.precrack_bonds, b.precrack_bonds);
  ASSERT_EQ(b.quasistatic.size(), 1u);
  EXPECT_EQ(b.quasistatic[0].first, "preload");
  EXPECT_EQ(b.quasistatic[0].second.increments.size(), a.quasistatic[0].second.increments.size());
  EXPECT_EQ(b.quasistatic[0].second.newton_iterations, a.quasistatic[0].second.newton_iterations);
  EXPECT_EQ(b.quasistatic_work_error, a.quasistatic_work_error);
}

// A run that a stability detector stops, resumed from its last checkpoint, must stop at the same
// step with the same message: the energy check's count of steps above its tolerance goes into
// the checkpoint, and no checkpoint is written before the state is checked (a node noted as
// moving too far was once lost: the resumed run went on).
TEST(Restart, ResumedRunStopsWhereTheUninterruptedOneStops) {
  struct Case {
    const char* name;
    std::vector<Override> set;
    const char* message;  // what the stop must say
  };
  const std::vector<Case> cases{
      // Above a tolerance below round-off from the first row on: stops at the 10th step after it;
      // the last checkpoint (every 4 steps) lies inside that window.
      {"energy", {{"stability.energy_error", "1e-15"}, {"output.series_every", "1"}, {"output.checkpoint_every_steps", "4"}},
       "exceeds stability.energy_error"},
      // Twice the stable step: a node moves too far within a few steps; checkpoints every 3
      // steps, checks (series rows, frames) far apart.
      {"motion",
       {{"stages.0.dt", "1.2e-6"}, {"stages.0.allow_unstable_dt", "true"}, {"stability.energy_error", "0"},
        {"output.series_every", "100"}, {"output.checkpoint_every_steps", "3"}},
       "unstable explicit integration"}};
  auto stop_of = [](Simulation& sim) -> std::string {
    try {
      sim.run();
    } catch (const RuntimeFailure& e) {
      return e.what();
    }
    return "(no stop)";
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const Scene scene = parse_scene(kScene, "small-slit", c.set);
    RunOptions o = quiet();
    o.out_dir = shared_path(std::string("restart-stop-") + c.name);
    std::string whole_stop, resumed_stop;
    std::int64_t stopped_at = 0;
    {
      Simulation whole(scene, PETSC_COMM_WORLD, o);
      whole_stop = stop_of(whole);
      stopped_at = whole.current_step();
    }
    const Checkpoint last = read_checkpoint(o.out_dir + "/checkpoint.h5");
    {
      RunOptions r = quiet();
      r.restart = load_checkpoint(o.out_dir + "/checkpoint.h5", PETSC_COMM_WORLD);
      Simulation resumed(scene, PETSC_COMM_WORLD, r);
      resumed_stop = stop_of(resumed);
    }
    MPI_Barrier(PETSC_COMM_WORLD);
    if (world_rank() == 0) {
      std::filesystem::remove_all(o.out_dir);
      std::printf("%s: stopped at step %lld, last checkpoint at step %lld: %.90s\n", c.name,
                  static_cast<long long>(stopped_at), static_cast<long long>(last.step), whole_stop.c_str());
    }
    EXPECT_NE(whole_stop.find(c.message), std::string::npos) << whole_stop;
    EXPECT_LT(last.step, stopped_at);
    EXPECT_EQ(resumed_stop, whole_stop);
  }
}

TEST(Restart, ExtraArraysRoundTrip) {
  const Scene scene = parse_scene(kScene, "small-slit");
  const std::string path = shared_path("restart-extras");
  {
    Simulation sim(scene, PETSC_COMM_WORLD, quiet());
    sim.add_checkpoint_extra("tip_history", [] { return std::vector<double>{1.5, -2.25, 3e-300}; },
                             [](const std::vector<double>*) {});
    sim.begin();
    sim.advance(5);
    store_checkpoint(path, sim.make_checkpoint(), PETSC_COMM_WORLD);
  }
  RunOptions o = quiet();
  o.restart = load_checkpoint(path, PETSC_COMM_WORLD);
  Simulation sim(scene, PETSC_COMM_WORLD, o);
  std::vector<double> got;
  bool missing_seen = false;
  sim.add_checkpoint_extra("tip_history", [] { return std::vector<double>{}; },
                           [&](const std::vector<double>* v) { got = v ? *v : std::vector<double>{}; });
  sim.add_checkpoint_extra("not_stored", [] { return std::vector<double>{}; },
                           [&](const std::vector<double>* v) { missing_seen = v == nullptr; });
  sim.begin();
  if (world_rank() == 0) {
    std::remove(path.c_str());
    std::remove(previous_checkpoint_path(path).c_str());
  }
  EXPECT_EQ(got, (std::vector<double>{1.5, -2.25, 3e-300}));
  EXPECT_TRUE(missing_seen);
  EXPECT_EQ(sim.current_step(), 5);
}

TEST(Restart, RefusesAnotherScene) {
  const Scene scene = parse_scene(kScene, "small-slit");
  const std::string path = shared_path("restart-scene");
  {
    Simulation sim(scene, PETSC_COMM_WORLD, quiet());
    sim.begin();
    sim.advance(3);
    store_checkpoint(path, sim.make_checkpoint(), PETSC_COMM_WORLD);
  }
  RunOptions o = quiet();
  o.restart = load_checkpoint(path, PETSC_COMM_WORLD);
  const Scene other = parse_scene(kScene, "small-slit", {{"materials.rubber.density", "1300"}});
  std::string message;
  try {
    Simulation sim(other, PETSC_COMM_WORLD, o);
  } catch (const InputError& e) {
    message = e.what();
  }
  // Only the cadence of checkpoints and progress lines may change.
  const Scene cadence = parse_scene(kScene, "small-slit", {{"output.checkpoint_every_steps", "7"}});
  EXPECT_NO_THROW(Simulation(cadence, PETSC_COMM_WORLD, o));
  if (world_rank() == 0) std::remove(path.c_str());
  EXPECT_NE(message.find("was written by a different scene"), std::string::npos) << message;
  EXPECT_NE(message.find("density: 1200"), std::string::npos) << message;
  EXPECT_NE(message.find("density: 1300"), std::string::npos) << message;
}

TEST(Restart, CheckpointCadence) {
  // By steps: the last checkpoint is at the last multiple of 7. By wall time (1 ns): at every
  // collective check (each 20 steps and the last step).
  for (const char* mode : {"steps", "seconds"}) {
    const bool by_steps = std::string(mode) == "steps";
    const Scene scene = parse_scene(kScene, "small-slit",
                                    {{"output.checkpoint_every_steps", by_steps ? "7" : "0"},
                                     {"output.checkpoint_every_seconds", by_steps ? "0" : "1e-9"}});
    RunOptions o = quiet();
    o.out_dir = shared_path(std::string("restart-cadence-") + mode);
    std::int64_t total = 0;
    {
      Simulation sim(scene, PETSC_COMM_WORLD, o);
      sim.run();
      total = sim.total_steps();
    }
    const Checkpoint last = read_checkpoint(o.out_dir + "/checkpoint.h5");
    const Checkpoint prev = read_checkpoint(o.out_dir + "/checkpoint.prev.h5");
    MPI_Barrier(PETSC_COMM_WORLD);
    if (world_rank() == 0) std::filesystem::remove_all(o.out_dir);
    if (by_steps) {
      EXPECT_EQ(last.step, total / 7 * 7);
      EXPECT_EQ(prev.step, total / 7 * 7 - 7);
    } else {
      EXPECT_EQ(last.step, total);
      EXPECT_EQ(prev.step, (total - 1) / 20 * 20);
    }
    EXPECT_FALSE(std::filesystem::exists(o.out_dir + "/checkpoint.h5.tmp"));
  }
}

// ------------------------------------------------------------------------------------------------
// Damaged files: every rank works on its own copy (read_checkpoint is serial).

Checkpoint small_checkpoint() {
  Checkpoint c;
  c.peridrive_version = "test";
  c.git_revision = "none";
  c.scene = "name: x\n";
  c.scene_hash = fnv1a64(c.scene.data(), c.scene.size());
  c.nodes = 4;
  c.ordered_bonds = 12;
  c.step = 10;
  c.time = 1e-6;
  c.stage = 0;
  c.stage_step = 10;
  c.initial_total_energy = 1.0;
  c.ranks = 2;
  c.dissipated = {0.5, 0.25};
  c.damping_work = {0.125, 0.0};
  c.external_work = {1.0, 2.0};
  c.newly_broken = {2, 2};
  c.owner_hash = {1, 2};
  for (int k = 0; k < 12; ++k) {
    c.displacement.push_back(1e-3 * k);
    c.velocity.push_back(-0.5 * k);
  }
  c.broken = {0, 1, 2, 3};
  c.extras["history"] = {1, 2, 3};
  return c;
}

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void put_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
}

std::string refusal(const std::string& path) {
  try {
    read_checkpoint(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(CheckpointFile, RoundTripKeepsEveryField) {
  TempFile f("ckpt-roundtrip");
  const Checkpoint c = small_checkpoint();
  write_checkpoint(f.path, c);
  write_checkpoint(f.path, c);  // a second write keeps the first as the previous checkpoint
  EXPECT_TRUE(std::filesystem::exists(previous_checkpoint_path(f.path)));
  EXPECT_FALSE(std::filesystem::exists(f.path + ".tmp"));
  const Checkpoint r = read_checkpoint(f.path);
  EXPECT_EQ(r.scene, c.scene);
  EXPECT_EQ(r.nodes, c.nodes);
  EXPECT_EQ(r.step, c.step);
  EXPECT_EQ(r.time, c.time);
  EXPECT_EQ(r.stage_step, c.stage_step);
  EXPECT_EQ(r.ranks, c.ranks);
  EXPECT_EQ(r.dissipated, c.dissipated);
  EXPECT_EQ(r.damping_work, c.damping_work);
  EXPECT_EQ(r.external_work, c.external_work);
  EXPECT_EQ(r.newly_broken, c.newly_broken);
  EXPECT_EQ(r.owner_hash, c.owner_hash);
  EXPECT_EQ(r.displacement, c.displacement);
  EXPECT_EQ(r.velocity, c.velocity);
  EXPECT_EQ(r.broken, c.broken);
  EXPECT_EQ(r.extras, c.extras);
  EXPECT_FALSE(r.has_dashpot_velocity);
  EXPECT_TRUE(r.dashpot_velocity.empty());
  // With bond dashpots: the velocity they last saw, a third node array.
  Checkpoint d = c;
  d.has_dashpot_velocity = true;
  d.dashpot_velocity = c.velocity;
  for (double& x : d.dashpot_velocity) x = 0.5 * x - 1.25;
  write_checkpoint(f.path, d);
  const Checkpoint rd = read_checkpoint(f.path);
  EXPECT_TRUE(rd.has_dashpot_velocity);
  EXPECT_EQ(rd.dashpot_velocity, d.dashpot_velocity);
  EXPECT_EQ(rd.velocity, c.velocity);
}

TEST(CheckpointFile, RefusesDamagedForeignAndOtherVersions) {
  TempFile f("ckpt-damaged"), g("ckpt-copy");
  write_checkpoint(f.path, small_checkpoint());
  const std::string good = bytes_of(f.path);
  ASSERT_GT(good.size(), 2000u);
  auto refused = [&](const std::string& bytes) {
    put_bytes(g.path, bytes);
    return refusal(g.path);
  };
  const auto has = [](const std::string& msg, const char* want) { return msg.find(want) != std::string::npos; };

  std::string m = refused(good.substr(0, good.size() - 100));
  EXPECT_TRUE(has(m, "truncated")) << m;
  m = refused(good.substr(0, 300));
  EXPECT_TRUE(has(m, "truncated")) << m;
  m = refused("");
  EXPECT_TRUE(has(m, "not a peridrive checkpoint")) << m;

  std::string flipped = good;
  flipped[good.size() / 2] ^= 0x10;  // one bit in the data
  m = refused(flipped);
  EXPECT_TRUE(has(m, "checksum mismatch")) << m;
  flipped = good;
  flipped[1] ^= 0x01;  // one bit in the magic
  m = refused(flipped);
  EXPECT_TRUE(has(m, "not a peridrive checkpoint")) << m;
  flipped = good;
  flipped[good.find("file_bytes: ") + 12] ^= 0x01;  // one bit in the recorded length
  m = refused(flipped);
  EXPECT_TRUE(has(m, "the header says")) << m;

  std::string version = good;
  version.replace(good.find("format_version: 1"), 17, "format_version: 7");
  m = refused(version);
  EXPECT_TRUE(has(m, "format version 7; this peridrive reads version 1")) << m;

  // A foreign HDF5 file (no checkpoint header) and a text file.
  m = refused(std::string("\x89HDF\r\n\x1a\n", 8) + std::string(4000, '\0'));
  EXPECT_TRUE(has(m, "not a peridrive checkpoint")) << m;
  m = refused("name: a scene, not a checkpoint\n");
  EXPECT_TRUE(has(m, "not a peridrive checkpoint")) << m;
  m = refusal(f.path + ".missing");
  EXPECT_TRUE(has(m, "no such file")) << m;
  m = refusal(std::filesystem::temp_directory_path().string());
  EXPECT_TRUE(has(m, "not a regular file")) << m;
  EXPECT_EQ(m.rfind("checkpoint '", 0), 0u) << m;  // every message names the file
}

TEST(CheckpointFile, EveryRankRefusesTogether) {
  // One rank's file is damaged: load_checkpoint must raise on all ranks (no rank left waiting).
  TempFile f("ckpt-collective");
  write_checkpoint(f.path, small_checkpoint());
  if (world_rank() == 0) {
    std::string bytes = bytes_of(f.path);
    bytes[bytes.size() - 1] ^= 0x40;
    put_bytes(f.path, bytes);
  }
  std::string message;
  try {
    load_checkpoint(f.path, PETSC_COMM_WORLD);
  } catch (const InputError& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("checksum mismatch"), std::string::npos) << message;
}

TEST(Resources, MemoryModelAndRefusal) {
  SizeEstimate e;
  e.nodes = 1e6;
  e.bonds = 4e7;
  e.bytes = 9 * e.bonds + 200 * e.nodes;
  const MemoryNeed one = memory_need(e, 1, true), two = memory_need(e, 2, true), cells = memory_need(e, 2);
  EXPECT_DOUBLE_EQ(one.per_rank, e.bytes + 72 * e.nodes);
  EXPECT_DOUBLE_EQ(one.rank0, one.per_rank);  // no partitioner graph on one rank
  EXPECT_DOUBLE_EQ(two.per_rank, e.bytes / 2 + 72 * e.nodes);
  EXPECT_DOUBLE_EQ(two.rank0, two.per_rank + 24 * e.bonds);  // the full bond graph on rank 0
  EXPECT_DOUBLE_EQ(cells.rank0, cells.per_rank);  // the cell graph is O(cells)
  EXPECT_GT(available_memory(), 1e8);  // /proc/meminfo is readable here

  EXPECT_NO_THROW(check_fits(parse_scene(kScene, "small-slit"), PETSC_COMM_WORLD));
  std::string message;
  try {
    check_fits(parse_scene(kScene, "small-slit", {{"bodies.sheet.spacing", "1e-7"}}), PETSC_COMM_WORLD);
  } catch (const InputError& err) {
    message = err.what();
  }
  EXPECT_NE(message.find("small-slit: the scene cannot fit in memory: about 4e+10 nodes"), std::string::npos)
      << message;
}

// ------------------------------------------------------------------------------------------------
// Memory: no rank gathers the state while a checkpoint is written (2 ranks).

/// VmRSS and VmHWM of this process [bytes].
std::pair<double, double> rss_and_peak() {
  std::ifstream status("/proc/self/status");
  double rss = -1, hwm = -1;
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmRSS:", 0) == 0) rss = std::stod(line.substr(6)) * 1024.0;
    if (line.rfind("VmHWM:", 0) == 0) hwm = std::stod(line.substr(6)) * 1024.0;
  }
  return {rss, hwm};
}

TEST(CheckpointMemory, RankZeroHoldsNoMoreThanItsShare) {
  int ranks = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &ranks);
  if (ranks != 2) GTEST_SKIP() << "a 2-rank test";
  // About 4.9e5 nodes: the state is 23 MB in natural order (displacement and velocity).
  const Scene scene = parse_scene(kScene, "small-slit", {{"bodies.sheet.spacing", "2.857e-5"}});
  Simulation sim(scene, PETSC_COMM_WORLD, quiet());
  sim.begin();
  sim.advance(1);
  const std::string path = shared_path("ckpt-memory");
  // The peak from here on: Linux resets VmHWM to VmRSS on writing 5 to clear_refs.
  MPI_Barrier(PETSC_COMM_WORLD);
  int reset = 0, all_reset = 0;
  {
    std::ofstream clear("/proc/self/clear_refs");
    clear << "5";
    clear.flush();
    reset = clear.good() ? 1 : 0;
  }
  MPI_Allreduce(&reset, &all_reset, 1, MPI_INT, MPI_MIN, PETSC_COMM_WORLD);
  if (!all_reset) GTEST_SKIP() << "cannot reset the peak resident set (/proc/self/clear_refs)";
  const double before = rss_and_peak().first;
  store_checkpoint(path, sim.make_checkpoint(), PETSC_COMM_WORLD);
  const double peak = rss_and_peak().second;
  double mine[2] = {before, peak}, all[4] = {0, 0, 0, 0};
  MPI_Gather(mine, 2, MPI_DOUBLE, all, 2, MPI_DOUBLE, 0, PETSC_COMM_WORLD);
  const double nodes = static_cast<double>(sim.domain().global_nodes);
  if (world_rank() == 0) {
    std::remove(path.c_str());
    std::remove(previous_checkpoint_path(path).c_str());
    const double extra0 = all[1] - all[0], extra1 = all[3] - all[2];
    std::printf("checkpoint of %.0f nodes on 2 ranks: resident before %.1f / %.1f MB, peak during %.1f / %.1f MB "
                "(rank 0 / rank 1; ratio %.3f), growth %.1f / %.1f MB; the whole state is %.1f MB\n",
                nodes, all[0] / 1e6, all[2] / 1e6, all[1] / 1e6, all[3] / 1e6, all[1] / all[3], extra0 / 1e6,
                extra1 / 1e6, 48 * nodes / 1e6);
    // The issue's bound: rank 0's peak within 10% of the other rank's.
    EXPECT_LE(all[1], 1.10 * all[3]);
    // And what the checkpoint adds on rank 0 is no more than on rank 1 plus a third of the
    // whole state (a gather to rank 0 adds all of it, 48 bytes per node, there alone).
    EXPECT_LE(extra0, extra1 + 16 * nodes) << "rank 0 grew by " << extra0 / 1e6 << " MB, rank 1 by " << extra1 / 1e6;
  }
}

}  // namespace
}  // namespace peri
