// Simulation: one run, built along DESIGN.md's data flow (scene -> nodes -> bonds -> partition
// -> state -> model -> stages -> diagnostics -> output). run() reads like the algorithm:
// initial conditions, then each stage's explicit velocity-Verlet loop.
#pragma once
#include <mpi.h>

#include <array>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "peri/loads/boundaries.hpp"
#include "peri/loads/pressure.hpp"
#include "peri/loads/tools.hpp"
#include "peri/diagnostics/crack_tip_monitor.hpp"
#include "peri/diagnostics/energies.hpp"
#include "peri/diagnostics/health.hpp"
#include "peri/kernels/forces.hpp"
#include "peri/models/long_range.hpp"
#include "peri/models/marder.hpp"
#include "peri/io/output.hpp"
#include "peri/io/run_checkpoint.hpp"
#include "peri/io/run_output.hpp"
#include "peri/io/summary.hpp"
#include "peri/stages/quasistatic.hpp"
#include "peri/state/state.hpp"

namespace peri {

struct Checkpoint;

struct RunOptions {
  std::string out_dir;   ///< empty: write no files (tests)
  bool quiet = false;    ///< no progress lines
  /// Continue from this checkpoint: begin() restores it instead of applying initial conditions,
  /// and the outputs in out_dir are continued (frames and series rows after it are dropped).
  std::shared_ptr<const Checkpoint> restart;
};

class Simulation : public EquilibriumModel {
 public:
  /// Builds everything and validates what needs the discretization (regions, time steps).
  /// Throws InputError before any file is written.
  Simulation(const Scene& scene, MPI_Comm comm, RunOptions options = {});
  ~Simulation();

  /// Apply initial conditions and run every stage: begin(), advance(all), finish(). Collective.
  void run();
  /// Initial conditions, first forces, frame 0 and series row 0.
  void begin();
  /// Advance up to n steps through the stages (fewer at the end). Returns steps taken.
  std::int64_t advance(std::int64_t n);
  /// Timings, energy balance, summary.json.
  void finish();
  std::int64_t total_steps() const { return total_steps_; }
  std::int64_t current_step() const { return step_; }
  double current_time() const { return time_; }

  const RunSummary& summary() const { return summary_; }
  const Domain& domain() const { return domain_; }
  /// Resolved scene YAML with derived constants as comments.
  const std::string& resolved_scene() const { return resolved_; }
  /// Derived constants as "key = value" lines.
  std::vector<std::string> derived_lines() const;

  /// Owned per-node field gathered in natural order onto every rank (tests; small runs).
  std::vector<double> gather_natural(const double* owned, int bs);
  std::vector<double> natural_positions();   ///< X + u, 3N
  std::vector<double> natural_velocities();  ///< 3N
  std::vector<double> natural_damage();      ///< N
  /// Broken bonds as (natural i < natural j) pairs, sorted, on every rank.
  std::vector<std::pair<std::int64_t, std::int64_t>> broken_bonds();
  /// Current energies (collective).
  EnergyRow energies();

  // EquilibriumModel (the quasi-static loader's view; also used by tests). Collective.
  void set_displacement(const double* u_owned) override;
  void get_displacement(double* u_owned) override;
  void internal_force(double* f_owned) override;
  void add_tangent(Mat J) override;
  std::int64_t break_bonds() override;
  /// Loader for quasi-static stage `s` (sized for this run's bonds).
  std::unique_ptr<QuasiStaticLoader> make_loader(const Stage& stage);
  /// Total linear and angular momentum about the origin (collective).
  std::array<double, 6> momentum();
  /// Crack tip histories (identical on every rank); nullptr when no material breaks.
  const CrackTipTracker* crack_tips() const { return tips_ ? &tips_->tracker() : nullptr; }

  /// The run's state as a checkpoint, complete on rank 0 (collective).
  Checkpoint make_checkpoint();
  /// Write <out_dir>/checkpoint.h5 now, keeping the previous one as checkpoint.prev.h5 until the
  /// new one is complete (collective).
  void write_checkpoint();
  std::string checkpoint_path() const { return options_.out_dir + "/checkpoint.h5"; }
  /// True when SIGTERM/SIGINT stopped the run (after its final checkpoint); finish() was skipped.
  bool stopped() const { return cadence_.stopped(); }
  /// Store an extra array in checkpoints (e.g. a diagnostic's history). `save` is called on every
  /// rank and rank 0's values are stored; on restart `restore` is called on every rank with the
  /// stored values, or nullptr when the checkpoint has none under that name.
  void add_checkpoint_extra(std::string name, std::function<std::vector<double>()> save,
                            std::function<void(const std::vector<double>*)> restore);

 private:
  void apply_initial_conditions();
  void compute_forces(bool with_energy, bool intact = false);  // intact: laws that never break
  void start_stage();               // stage_: set its boundaries and step, or run it (no-time stages)
  void run_quasistatic(const Stage& stage);
  void run_release(const Stage& stage);
  // defer_kick: the free nodes' second half kick may wait for the next step's first pass
  // (kick_pending_; settle_kick() applies it, as every reader of the velocity does first).
  void step(bool with_energy, bool defer_kick = false);
  void settle_kick();
  void second_kick_free(double* v, double dt) const;  // the free runs' second half kick
  /// The bond loop's plans forget what they keep of the broken flags (RowBlocks::forget_broken):
  /// after flags are written other than by the loop (release stage, restart).
  void flags_changed();
  bool has_intact_bond(std::int32_t row) const;
  void check_health(std::int64_t step, double time);
  // Setup checks and warnings (src/stages/simulation_checks.cpp): derived quantities that the
  // scene's values would make absurd are refused there, naming the keys; all before any output.
  void stop_point();                              // collective: StopRequested on every rank after a signal
  void warn_large_families(const SizeEstimate& e) const;
  void warn_overlapping_boundaries(const std::vector<std::vector<std::int64_t>>& bc_nodes) const;
  void check_node_masses() const;                 // global node arrays (before they are freed)
  void check_stable_step(const std::vector<double>& dt_body);  // per body, collective
  void check_stage(std::size_t stage, double dt) const;  // step count, damping
  void check_initial_state();                     // initial conditions, boundaries, tools (collective)
  void write_frame();
  void write_series_row();
  /// Adds the loads' forces at time `t` to force_ (after compute_forces: positions_ of the owned
  /// nodes current); with `book`, their work goes to the ledger.
  void add_load_forces(double t, bool book);
  std::vector<double> energy_density_;  // owned: strain energy per unit volume (frames)
  // Whether energy_density_ holds the bond energies of the current state: written by the bond
  // loop in energy calls (compute_forces), so a frame needs no separate pass over the bonds.
  bool density_current_ = false;
  void update_energy_density();
  double kinetic_energy();
  void update_damage();                          // damage_ of every owned node from the flags
  BondView bond_view();                          // bond arrays of this rank (u filled by caller)
  /// |total - initial total| over the run's energy scale (at least energy_floor_), from the
  /// explicit part's initial total.
  double energy_balance_error(const EnergyRow& row) const;
  EnergyRow reduce_energies(double local_strain);  // global energies from this rank's strain
  void restore(const Checkpoint& c);              // state, flags, tallies, counters; forces
  // Marder lattice bodies (src/stages/simulation_lattice.cpp); nothing is built when there is none.
  void lattice_setup();
  void lattice_forces(const BondView& view, bool interior, bool with_energy, BondTally& tally,
                      const double* velocity);
  void lattice_reduce();
  double lattice_energy(const BondView& view);
  void lattice_derived(std::size_t body);
  void mark_memory(const char* phase);           // summary_.memory row (collective)

  Scene scene_;
  MPI_Comm comm_;
  RunOptions options_;
  int rank_ = 0, ranks_ = 1;
  Nodes nodes_;  // after setup only nodes_.bodies: the node arrays live in domain_ per rank
  Partition partition_;
  Domain domain_;
  std::unique_ptr<State> state_;
  std::vector<BondLaw> laws_;           // per body
  std::vector<std::optional<MarderLaw>> marder_;  // per body: set for lattice bodies
  bool has_lattice_ = false;
  // Long-range forces (scene long_range): every rank holds the table of all fiber nodes and, each
  // force evaluation, their current positions (gathered); it evaluates the pairs of its own.
  struct LongRangeState {
    LongRangeState(PairLaw l, LongRangeTable t) : law(l), table(std::move(t)) {}
    PairLaw law;
    LongRangeTable table;
    std::vector<std::int64_t> mine;         // table indices of this rank's owned fiber nodes
    std::vector<std::int32_t> mine_local;   // their local (owned) indices
    std::vector<int> counts, displs;        // per rank: how many, where in the gathered order
    std::vector<std::int64_t> gathered;     // gathered order -> table index
    std::vector<double> send, recv, x, force;
    LongRangeList list;
  };
  std::optional<LongRangeState> long_range_;
  void long_range_setup();                          // before the global node arrays are freed
  void gather_fiber_positions(const double* u);  // every rank: current positions of all fiber nodes (lr.x)
  double add_long_range_forces(const double* u, bool with_energy);  // returns this rank's energy share
  std::vector<std::uint8_t> lattice_direction_;  // lattice direction of every owned-row bond
  bool has_kelvin_ = false;                 // some lattice body has bond dashpots (velocity halo)
  std::vector<double> viscous_;             // dashpot force densities, 3 * local (owned rows written)
  std::vector<BondLaw> intact_laws_;    // same, never breaking (quasi-static residuals, tangents)
  double damping_ = 0;                     // current stage's viscous damping [1/s]
  bool stage_started_ = false;
  std::vector<double> density_;         // per body
  std::vector<std::vector<std::int32_t>> interior_by_body_, boundary_by_body_;
  std::vector<RowBlocks> interior_plan_, boundary_plan_;  // the same rows grouped for the bond loop
  std::vector<double> inv_density_, mass_;  // per owned node
  std::vector<double> force_;               // force densities, 3 * owned
  double energy_floor_ = 0;                 // smallest energy scale of the balance (sum m c_l^2 1e-20)
  std::vector<double> positions_;           // current positions X + u, planes x, y, z of local() each (bond kernel input)
  std::int64_t position_stride_ = 0;        // doubles from one plane of positions_ to the next (position_plane_stride)
  std::optional<Boundaries> boundaries_;    // prescribed motion (after the domain)
  std::vector<std::unique_ptr<Load>> loads_;  // forces beside the bonds', in the order they add up
  Tools* tools_ = nullptr;                  // the tools among them (series columns), if any
  struct FreeRun {                          // owned nodes [begin, end) of one body, no boundary
    std::int32_t begin, end;
    int body;
  };
  std::vector<FreeRun> free_runs_;          // Verlet update streams (step(), without damping or dashpots)
  bool kick_pending_ = false;               // free runs' second half kick deferred (step(); dt_, force_)
  std::vector<double> damage_;
  std::vector<std::int64_t> stage_steps_;
  std::vector<double> stage_dt_;
  std::int64_t total_steps_ = 0, step_ = 0;
  double time_ = 0, dt_ = 0;
  EnergyLedger ledger_;        // this rank's energy accounts (diagnostics/energies.hpp)
  std::optional<HealthCheck> health_;  // after the domain
  std::size_t stage_ = 0;           // current stage
  std::int64_t stage_step_ = 0;     // steps taken in it
  std::chrono::steady_clock::time_point loop_start_;
  std::int64_t loop_start_step_ = 0;  ///< step_ at loop_start_ (a resumed run's checkpoint step)
  double output_seconds_at_loop_start_ = 0;  ///< output time spent before the loop (the first frame)
  std::optional<RunOutput> output_;  // after the stages' steps
  std::unique_ptr<CrackTipMonitor> tips_;    // nullptr: no material breaks
  std::string resolved_;
  RunSummary summary_;
  std::chrono::steady_clock::time_point start_, last_progress_;
  // Checkpoints and stop requests.
  CheckpointExtras extras_;
  CheckpointCadence cadence_{scene_.output, !options_.out_dir.empty(), comm_};
};

}  // namespace peri
