// The run's figures as summary.json holds them: sizes, time step, timings and rates, memory per
// setup phase, partition, energies and their balance, quasi-static stages, crack tips, and the
// derived constants. summary.json is written last: its presence marks a complete run.
#pragma once
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "peri/diagnostics/energies.hpp"
#include "peri/stages/quasistatic.hpp"

namespace peri {

/// Figures of a finished (or running) simulation, as written to summary.json.
struct RunSummary {
  std::int64_t nodes = 0, ordered_bonds = 0, steps = 0, precrack_bonds = 0;
  /// Steps this process took and timed in step_seconds (after a resume: those after the
  /// checkpoint; the rates are steps_timed * ordered_bonds / step_seconds).
  std::int64_t steps_timed = 0;
  int ranks = 1, frames = 0;
  double dt = 0, dt_stable = 0, simulated_time = 0;
  double setup_seconds = 0, step_seconds = 0, output_seconds = 0, wall_seconds = 0;
  /// Of output_seconds, the checkpoints this process wrote (how many); the resume's restore of
  /// the state from its checkpoint (slowest rank each).
  double checkpoint_seconds = 0, resume_seconds = 0;
  std::int64_t checkpoints_written = 0;
  double bytes_per_bond = 0;
  double partition_seconds = 0;
  std::int64_t edge_cut = 0;
  std::string partition_method;  ///< cells, bonds or petsc (-partition_method)
  double partition_balance = 1;  ///< largest rank's ordered bonds / mean
  /// What each step's halo exchange carries, over the ranks (the terms of cluster/scaling_model.py,
  /// as peridrive-partition reports them for P parts): ghost nodes (24 bytes each per exchange),
  /// ranks exchanged with, owned ordered bonds and those of rows with a ghost neighbour (computed
  /// after the exchange; the others overlap it).
  struct Halo {
    std::int64_t max_ghosts = 0, max_neighbour_ranks = 0, max_owned_bonds = 0, max_boundary_bonds = 0;
    double mean_ghosts = 0, mean_neighbour_ranks = 0, mean_boundary_bonds = 0;
  } halo;
  /// Memory after each setup phase, summed over ranks: peak resident set (VmHWM) so far and
  /// current resident set (VmRSS), bytes.
  struct MemoryMark {
    std::string phase;
    double peak = 0, current = 0;
  };
  std::vector<MemoryMark> memory;
  EnergyRow final_energy;
  double initial_total_energy = 0;  ///< total at the start of the explicit part (after quasi-static stages)
  double energy_balance_error = 0;  ///< |E(t) - E(0)| / max(|E| scale) at the end
  /// The same over the whole run: from the total before the first stage, so that a quasi-static
  /// stage whose support work is not stored or dissipated shows here (equal to the above when
  /// the run has no quasi-static stage).
  double run_initial_total_energy = 0;
  double run_energy_balance_error = 0;
  /// Quasi-static stages run: (stage name, figures).
  std::vector<std::pair<std::string, QuasiStaticStats>> quasistatic;
  /// Per quasi-static stage: |W_reactions - (dU + D)| / W_reactions (trapezoidal work).
  std::vector<double> quasistatic_work_error;
  std::vector<std::pair<std::string, double>> derived;  ///< per-body constants (name, value)
  /// What a fresh run writes: frames, nodes per frame, bytes per frame, bytes in all (predicted).
  std::vector<std::pair<std::string, double>> output;
  /// Crack tips (scenes whose materials break): final tips and speeds, see crack_tips.hpp.
  bool crack_tracking = false;
  double max_crack_speed = 0, mean_crack_speed = 0, rayleigh_wave_speed = 0, crack_speed_window = 0;
  double crack_tip_seconds = 0;  ///< time spent finding and tracking tips (slowest rank)
  std::string crack_tips_json;  ///< JSON array, one object per track
  std::string to_json() const;
  /// The processes' largest resident memory over the setup and run phases (summed over ranks) per
  /// ordered bond: what a run really takes, beside bytes_per_bond, its bond arrays alone.
  double peak_bytes_per_bond() const {
    double peak = 0;
    for (const MemoryMark& m : memory) peak = std::max(peak, m.peak);
    return ordered_bonds > 0 ? peak / static_cast<double>(ordered_bonds) : 0.0;
  }
};

/// Appends the memory after `phase` to summary.memory: peak and current resident set, summed
/// over the ranks. Collective.
void mark_memory(RunSummary& summary, const char* phase, MPI_Comm comm);

/// The derived constants as "key = value" lines, headed by the version that derived them (the
/// resolved scene's comments).
std::vector<std::string> derived_lines(const RunSummary& summary);

}  // namespace peri
