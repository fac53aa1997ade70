// Simulation: one run. The setup builds its problem along DESIGN.md's data flow (stages/problem.hpp:
// domain, state, force model, loads, the stages' time steps); run() then reads like the
// algorithm: initial conditions, then the stages in order, those that take no time (quasi-static
// preload, release: quasistatic_stage.hpp, release.hpp) changing the state at once, the dynamic
// ones stepping it by velocity Verlet (explicit.hpp), each step checked (diagnostics/health.hpp)
// before its series row, frame or checkpoint is written (io/).
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

#include "peri/diagnostics/crack_tip_monitor.hpp"
#include "peri/diagnostics/energies.hpp"
#include "peri/diagnostics/health.hpp"
#include "peri/io/run_checkpoint.hpp"
#include "peri/io/run_output.hpp"
#include "peri/io/summary.hpp"
#include "peri/stages/explicit.hpp"
#include "peri/stages/problem.hpp"
#include "peri/stages/quasistatic.hpp"
#include "peri/stages/quasistatic_stage.hpp"
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
  const std::string& resolved_scene() const;
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
  bool load_force(double* f_owned) override;
  void set_load_level(double level) override;
  std::string load_text(double level) const override;
  void add_tangent(Mat J, const DofLayout& layout) override;
  std::int64_t break_bonds() override;
  /// Loader for quasi-static stage `s` (sized for this run's bonds).
  std::unique_ptr<QuasiStaticLoader> make_loader(const Stage& stage);
  /// Total linear and angular momentum about the origin (collective).
  std::array<double, 6> momentum();
  /// The scene's rigid tools; nullptr when it has none.
  const Tools* tools() const { return p_->tools; }
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
  void explicit_step();                      // one step of the explicit stage, its checks and output
  void run_timeless_stage(const Stage& stage);  // a quasi-static or release stage
  void run_quasistatic(const Stage& stage);
  void run_release(const Stage& stage);
  void check_tools_clear(const Stage& stage);  // after a quasi-static stage: no tool may touch
  void start_loop_clock();                   // the steps timed from here
  void check_health(std::int64_t step, double time);
  void write_frame();
  /// One row of series.csv, checked by the energy detector; `new_reference`: the row is the
  /// energy balance's new reference (after a quasi-static stage), set before the check.
  void write_series_row(bool new_reference = false);
  /// |total - initial total| over the run's energy scale (at least the problem's floor), from
  /// the explicit part's initial total.
  double energy_balance_error(const EnergyRow& row) const;
  EnergyRow reduce_energies(double local_strain);  // global energies from this rank's strain
  void restore(const Checkpoint& c);              // state, flags, tallies, counters; forces

  RunOptions options_;
  RunSummary summary_;  // the setup's figures first (build_problem)
  std::chrono::steady_clock::time_point start_, last_progress_;
  std::unique_ptr<Problem> p_;  // what the setup built (stages/problem.hpp)
  // Its parts that the run reads throughout.
  const Scene& scene_;
  MPI_Comm comm_;
  int rank_ = 0, ranks_ = 1;
  Domain& domain_;
  State& state_;
  Forces& forces_;
  std::int64_t total_steps_ = 0;
  // Where the run stands.
  std::int64_t step_ = 0;
  double time_ = 0;
  std::size_t stage_ = 0;         // current stage
  std::int64_t stage_step_ = 0;   // steps taken in it
  bool stage_started_ = false;    // its start (time step, damping, boundaries) made
  // The run's last frame when stages that take no time follow the last step: written after them,
  // so that it shows the state they leave.
  bool final_frame_deferred_ = false;
  // Diagnostics and the stages.
  EnergyLedger ledger_;           // this rank's energy accounts (diagnostics/energies.hpp)
  HealthCheck health_;
  Verlet verlet_;                 // the explicit stage (stages/explicit.hpp)
  ProblemEquilibrium equilibrium_;  // the quasi-static stages' model (stages/quasistatic_stage.hpp)
  std::unique_ptr<CrackTipMonitor> tips_;  // nullptr: no material breaks
  std::chrono::steady_clock::time_point loop_start_;
  std::int64_t loop_start_step_ = 0;  ///< step_ at loop_start_ (a resumed run's checkpoint step)
  double output_seconds_at_loop_start_ = 0;  ///< output time spent before the loop (the first frame)
  // Output, checkpoints and stop requests.
  RunOutput output_;
  CheckpointExtras extras_;
  CheckpointCadence cadence_;
};

}  // namespace peri
