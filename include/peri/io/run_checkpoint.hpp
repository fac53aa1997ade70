// A run's checkpoints: what it holds of the run (nodes' state in natural order, broken bonds,
// each rank's energy ledger, where the run stands, the summary figures of stages before it,
// named extra arrays), when one is due (every output.checkpoint_every_steps or _seconds, and
// when a stop signal reaches a rank), and the checks and restores of a resumed run.
#pragma once
#include <mpi.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "peri/diagnostics/energies.hpp"
#include "peri/io/checkpoint.hpp"
#include "peri/io/summary.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"
#include "peri/state/state.hpp"

namespace peri {

/// Where a run stands: steps and simulated time so far, the current stage and the steps taken in it.
struct RunPosition {
  std::int64_t step = 0;
  double time = 0;
  std::size_t stage = 0;
  std::int64_t stage_step = 0;
};

/// Extra arrays stored in checkpoints by name (a diagnostic's history, the tools' friction).
class CheckpointExtras {
 public:
  /// `save` is called on every rank and rank 0's values are stored; on restart `restore` is
  /// called on every rank with the stored values, or nullptr when the checkpoint has none.
  void add(std::string name, std::function<std::vector<double>()> save,
           std::function<void(const std::vector<double>*)> restore);
  void save(Checkpoint& c, bool root) const;  // collective where the saves are
  void restore(const Checkpoint& c) const;

 private:
  struct Extra {
    std::string name;
    std::function<std::vector<double>()> save;
    std::function<void(const std::vector<double>*)> restore;
  };
  std::vector<Extra> extras_;
};

/// The run's state as a checkpoint: on every rank the metadata, on rank 0 the tallies and extras,
/// and each rank's part of the node and bond arrays, as write_checkpoint takes them: its block of
/// natural rows of displacement and velocity, the broken pairs and bond-history rows of that
/// block; with bond dashpots (`dashpot_velocity`, on every rank: 3 values per owned node in local
/// order, the velocity their last evaluation saw) that velocity's rows too. Nothing is gathered.
/// Collective.
Checkpoint make_checkpoint(const Scene& scene, const Domain& domain, State& state, const EnergyLedger& ledger,
                           const RunPosition& at, const RunSummary& summary, const CheckpointExtras& extras,
                           MPI_Comm comm, const std::vector<double>* dashpot_velocity = nullptr);
/// InputError unless `c` continues this scene: the same physics (only output.progress_seconds
/// and output.checkpoint_every_* may differ), nodes and bonds, and a stage and step that fit
/// the stages' step counts; and, where the checkpoint stores one, the same reference geometry
/// (`reference_hash`: reference_geometry_hash of this run).
void check_restart(const Checkpoint& c, const Scene& scene, std::int64_t nodes, std::int64_t ordered_bonds,
                   const std::vector<std::int64_t>& stage_steps, std::uint64_t reference_hash);
/// Displacements, velocities, broken bonds and bond history from the file `c` was read from (each
/// rank reads its block of natural rows and sends the owners their nodes' values; the broken
/// pairs and history rows are streamed, each rank keeping those of its nodes). InputError if the
/// file lists bonds this scene lacks; the caller's plans must then forget the flags they keep.
/// This rank's ledger:
/// its own when the ownership is the checkpoint's (the sums continue bit for bit), else the
/// totals on rank 0. With `dashpot_velocity`, the dashpots' velocity where the file has it (3
/// values per owned node, local order; left empty where it has not). Collective.
void restore_state(const Checkpoint& c, Domain& domain, State& state, EnergyLedger& ledger, MPI_Comm comm,
                   std::vector<double>* dashpot_velocity = nullptr);
/// The summary figures of the stages before the checkpoint: pre-cracked and released bonds, the
/// whole run's initial energy, each quasi-static stage's figures.
void restore_summary(const Checkpoint& c, const Scene& scene, RunSummary& summary);

/// When checkpoints are due, and whether a stop signal ended the run.
class CheckpointCadence {
 public:
  /// `enabled`: the run writes files (checkpoints are never due otherwise).
  CheckpointCadence(const Output& output, bool enabled, MPI_Comm comm);
  /// The clock of checkpoint_every_seconds starts now; a checkpoint at `step` needs none again.
  void start(std::int64_t step);
  /// Whether a checkpoint is due at `step`: every checkpoint_every_steps; at `poll` steps
  /// (collective) also every checkpoint_every_seconds on rank 0's clock, or when a stop signal
  /// reached any rank (stopped() is then true). Never twice for one step.
  bool due(std::int64_t step, bool poll);
  /// A checkpoint of `step` was written now.
  void written(std::int64_t step);
  bool stopped() const { return stopped_; }

 private:
  const Output& output_;
  bool enabled_;
  MPI_Comm comm_;
  int rank_ = 0;
  bool stopped_ = false;
  std::int64_t last_step_ = -1;
  std::chrono::steady_clock::time_point last_;
};

}  // namespace peri
