// Restart: the collective side of checkpoints. Sorts a distributed run's broken bonds and bond
// history into the ranks' blocks of natural ids (what each rank writes of a checkpoint), reads a
// checkpoint's metadata on every rank with one verdict, sets the broken-bond flags and history of
// any partition from the stored rows, and turns SIGTERM/SIGINT into a stop request that the step
// loop polls collectively. (The gathers to rank 0 serve tests and tools, not checkpoints.)
#pragma once
#include <mpi.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "peri/io/checkpoint.hpp"
#include "peri/state/state.hpp"

namespace peri {

/// Exit status of a run stopped by SIGTERM/SIGINT after writing its final checkpoint.
inline constexpr int kExitStopped = 5;

/// Install SIGTERM and SIGINT handlers that record a stop request; a second signal ends the
/// process at once (default action). SIGXFSZ is ignored (a write past ulimit -f fails instead).
/// Call after PetscInitialize, which installs its own.
void install_stop_handlers();
/// The signal that requested a stop on this rank, or 0.
int stop_signal();

/// Under an MPI launcher (Open MPI's mpirun or orted, MPICH's Hydra proxy, a PMIx or PMI server:
/// told by its environment), have the kernel end this process with SIGKILL as soon as its parent
/// process, the launcher, dies: a rank orphaned by a killed mpirun writes nothing more (no frame,
/// checkpoint or summary.json). A run started without a launcher is left alone. Linux only; call
/// first in main, before MPI starts threads.
void end_with_launcher();

/// The first natural id of every rank's block (State::natural_begin()), and the total at the end:
/// ranks + 1 values. Collective.
std::vector<std::int64_t> natural_blocks(std::int64_t natural_begin, std::int64_t nodes, MPI_Comm comm);

/// The rank whose block of natural ids holds `id`.
int natural_block_of(const std::vector<std::int64_t>& blocks, std::int64_t id);

/// Broken bonds as sorted natural pairs (i < j), flattened: those whose i lies in this rank's
/// block of natural ids (`blocks`), so that the ranks' lists in rank order are the sorted whole.
/// Collective (one all-to-all); no rank holds more than the pairs of its block.
std::vector<std::int64_t> broken_pairs_of_block(const Domain& d, const std::vector<std::int64_t>& blocks,
                                                MPI_Comm comm);

/// The rows of gather_history_to_root whose i lies in this rank's block, sorted by (i, j).
/// Collective (one all-to-all).
std::vector<double> history_rows_of_block(const Domain& d, const std::vector<std::int64_t>& blocks, MPI_Comm comm);

/// Set this rank's broken flags to exactly `pairs` (sorted natural (i < j) pairs, flattened: all
/// of them, or at least those that touch this rank's owned nodes).
/// Returns how many of this rank's ordered bonds are in `pairs` (over all ranks: 2 per pair).
std::int64_t apply_broken_pairs(Domain& d, const std::vector<std::int64_t>& pairs);

/// The per-bond history (BondFamilies::history) of every ordered bond that has one not all zero,
/// on rank 0: rows (natural i, natural j, its history_stride values), sorted by (i, j); empty
/// elsewhere. Collective.
std::vector<double> gather_history_to_root(const Domain& d, MPI_Comm comm);

/// Sets the history of this rank's bonds from such rows (bonds not listed: zero); returns how
/// many rows it used. Throws InputError when the rows' width is not 2 + history_stride.
std::int64_t apply_history(Domain& d, const std::vector<double>& rows);

/// fnv1a64 of this rank's owned natural ids: equal on restart means equal ownership.
std::uint64_t ownership_hash(const Domain& d);

/// A hash of the reference geometry: over every node, its natural id, reference position and
/// measure (the bits), summed modulo 2^64 over the ranks, so the same on any rank count. A resume
/// compares it with the checkpoint's: a body read from a file (mesh, points, polyline) whose
/// nodes moved keeps its scene text and counts, but not this. Collective.
std::uint64_t reference_geometry_hash(const Domain& d, MPI_Comm comm);

/// Check a checkpoint (header and length on every rank, the hash of the whole file on rank 0,
/// streamed) and read its metadata on every rank (read_checkpoint_metadata: the node and bond
/// arrays stay in the file; restore_state reads each rank's rows). A failure on any rank raises
/// InputError on all of them (rank 0's message when it failed itself). Collective.
std::shared_ptr<const Checkpoint> load_checkpoint(const std::string& path, MPI_Comm comm);

/// Every rank writes its part of `c` (see write_checkpoint) into one file with parallel HDF5; a
/// failure raises RuntimeFailure on every rank, the partial file removed. Collective.
void store_checkpoint(const std::string& path, const Checkpoint& c, MPI_Comm comm);

/// The checkpoint that `--resume PATH` continues from: PATH itself if it is a file; else
/// PATH/checkpoint.h5, or PATH/checkpoint.prev.h5 when the former does not exist (a run killed
/// between the two renames of write_checkpoint).
std::string resolve_resume_path(const std::string& path);

}  // namespace peri
