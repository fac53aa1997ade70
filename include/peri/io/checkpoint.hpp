// Checkpoint: the file format of a resumable run state. File I/O only (no PETSc): written
// collectively with parallel HDF5 (MPI-IO), each rank its own rows of the node and bond arrays;
// read per rank (hyperslabs of the rows a rank needs). restart.hpp and run_checkpoint.hpp build a
// distributed run's parts and set a partition's state from them.
//
// Layout. One HDF5 file with a 512-byte user block in front, which HDF5 itself skips:
//   user block  "peridrive checkpoint\n" "format_version: 1\n" "file_bytes: N\n"
//               "fnv1a64: <16 hex digits>\n", padded with NUL bytes. The hash covers every byte
//               after the user block, so a truncated, bit-flipped or foreign file is refused
//               before HDF5 parses any of it.
//   /           attributes: format_version, peridrive_version, git_revision, scene_hash, nodes,
//               ordered_bonds, step, time, stage, stage_step, initial_total_energy, ranks,
//               reference_hash (reference_geometry_hash; absent in files written before it)
//   /scene      the resolved YAML, a scalar string dataset of any length (files written before
//               it could exceed 64 KB hold it as an attribute `scene` of /, still read)
//   /state      displacement [N,3], velocity [N,3] (natural node order: rank-independent);
//               with bond dashpots also dashpot_velocity [N,3], the velocity the last force
//               evaluation's dashpots saw (the half step's, which the step's end overwrites)
//   /bonds      broken [B,2]: every broken bond once as natural ids (i < j), sorted
//   /tallies    per writing rank: dissipated, damping_work, external_work, newly_broken, owner_hash
//   /extras     one 1-D double dataset per registered extra array (diagnostics' history);
//               bonds.history: rows (natural i, natural j, the law's history values) of every
//               ordered bond with a history not all zero, sorted by (i, j)
// Load-ramp state needs no field: boundary velocities are functions of the simulated time.
//
// Who writes what. Every rank makes the same metadata calls; rank 0 writes the attributes' data,
// the scene, the tallies and the extras; each rank writes with one collective call its rows of
// /state (its contiguous block of natural ids), of /bonds/broken and of /extras/bonds.history
// (the pairs and rows whose first natural id lies in its block, so that the rows of the ranks in
// rank order are the sorted whole). No rank holds more than its share of the node and bond
// arrays. Rank 0 then hashes the closed file in 1 MiB chunks and writes the header.
#pragma once
#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace peri {

inline constexpr int kCheckpointFormatVersion = 1;
inline constexpr std::size_t kCheckpointHeaderBytes = 512;

/// Everything needed to continue a run exactly.
struct Checkpoint {
  int format_version = kCheckpointFormatVersion;
  std::string peridrive_version, git_revision;
  std::string scene;               ///< resolved scene YAML (emit_scene, no derived comments)
  std::uint64_t scene_hash = 0;    ///< fnv1a64 of `scene`
  /// reference_geometry_hash of the run that wrote it (restart.hpp); `has_reference_hash` false
  /// for files written before it was stored, which a resume then does not compare.
  std::uint64_t reference_hash = 0;
  bool has_reference_hash = false;
  std::int64_t nodes = 0;          ///< N
  std::int64_t ordered_bonds = 0;  ///< bonds over all ranks (both directions)
  std::int64_t step = 0;           ///< steps taken in the whole run
  double time = 0;                 ///< simulated time [s]
  std::int64_t stage = 0;          ///< index of the current stage
  std::int64_t stage_step = 0;     ///< steps taken in it
  double initial_total_energy = 0; ///< E(0) of the energy balance [J]
  int ranks = 1;                   ///< ranks of the run that wrote it
  // Per writing rank (size `ranks`): cumulative tallies, so that sums continue bit for bit.
  std::vector<double> dissipated, damping_work, external_work;  ///< [J]
  std::vector<std::int64_t> newly_broken;         ///< ordered bonds broken so far
  std::vector<std::uint64_t> owner_hash;          ///< fnv1a64 of each rank's owned natural ids
  /// Natural order [m], [m/s]: 3 values per node of the rows node_first, node_first + 1, ...
  /// (all N rows when read by read_checkpoint; a rank's block when written collectively).
  std::vector<double> displacement, velocity;
  /// With bond dashpots: the velocity [m/s] their last evaluation saw, as displacement (the
  /// force at the checkpoint depends on it); empty without dashpots (and in older files).
  std::vector<double> dashpot_velocity;
  std::int64_t node_first = 0;
  std::vector<std::int64_t> broken;               ///< 2B: (i, j) pairs, i < j, sorted (or a rank's part)
  std::map<std::string, std::vector<double>> extras;  ///< named extra arrays

  // Read by read_checkpoint_metadata, which leaves displacement, velocity, broken and
  // extras["bonds.history"] empty: where they are and how large they are.
  std::string path;                 ///< the file read (empty: built in memory)
  std::uint64_t file_bytes = 0;     ///< its size
  bool arrays = true;               ///< false: the arrays above are in the file, not here
  std::int64_t broken_pairs = 0;    ///< rows of /bonds/broken
  std::int64_t history_values = 0;  ///< values of /extras/bonds.history (0: none stored)
  bool has_dashpot_velocity = false;  ///< dashpot_velocity is written / is in the file
};

/// The extra array that holds the per-bond history (its rows are read per rank, not by
/// read_checkpoint_metadata).
inline constexpr const char* kBondHistoryExtra = "bonds.history";

/// 64-bit FNV-1a hash (continues from `h`).
std::uint64_t fnv1a64(const void* data, std::size_t bytes, std::uint64_t h = 14695981039346656037ull);

/// The file name a previous checkpoint is kept under: "a/checkpoint.h5" -> "a/checkpoint.prev.h5".
std::string previous_checkpoint_path(const std::string& path);

/// Write `c` to `path` atomically: a temporary file is written, flushed to disk and closed; the
/// existing `path` (if any) is renamed to previous_checkpoint_path(path); then the temporary is
/// renamed to `path`. At every moment one complete checkpoint exists. Collective over `comm`:
/// every rank passes the same metadata, tallies and extras (the data of those is rank 0's) and
/// its own part of the node rows (displacement and velocity from row node_first; dashpot_velocity
/// too on every rank or on none), of the broken
/// pairs and of extras["bonds.history"]; the parts in rank order must be the sorted whole. A
/// failure on any rank throws Error on every rank (the temporary removed, the checkpoints before
/// kept); no rank is left waiting.
void write_checkpoint(const std::string& path, const Checkpoint& c, MPI_Comm comm = MPI_COMM_SELF);

/// Check the header and the file's length; with `hash`, also the FNV-1a hash of every byte after
/// the header (streamed in 1 MiB chunks). Returns the file's size. InputError as read_checkpoint.
std::uint64_t check_checkpoint_file(const std::string& path, bool hash);

/// Read and check a checkpoint whole. Throws InputError naming the file and what is wrong (not a
/// checkpoint, other format version, truncated, damaged, inconsistent) and never crashes on a
/// hostile file. Checks the header and the hash before HDF5 reads anything.
Checkpoint read_checkpoint(const std::string& path);

/// Everything but the node and bond arrays (displacement, velocity, broken pairs, bond history),
/// whose types and shapes are checked and whose sizes are recorded (arrays = false). Call after
/// check_checkpoint_file(path, ...) returned `file_bytes`.
Checkpoint read_checkpoint_metadata(const std::string& path, std::uint64_t file_bytes);

/// Rows [first, first + count) of /state/displacement and /state/velocity (3 values a row), and
/// of /state/dashpot_velocity into `w` where the file has it (else `w` is left empty), checked
/// finite. InputError on failure.
void read_checkpoint_nodes(const Checkpoint& meta, std::int64_t first, std::int64_t count, std::vector<double>& u,
                           std::vector<double>& v, std::vector<double>* w = nullptr);

/// The broken pairs (i, j) for which keep(i, j), flattened, in the file's order. Streams the whole
/// list in chunks (memory: one chunk and the pairs kept) and checks every pair (i < j < nodes,
/// sorted, unique).
std::vector<std::int64_t> read_checkpoint_broken(const Checkpoint& meta,
                                                 const std::function<bool(std::int64_t, std::int64_t)>& keep);

/// The rows (i, j, width - 2 values) of the bond history for which keep(i), in the file's order;
/// streamed in chunks like read_checkpoint_broken. InputError unless the stored values are whole
/// rows of `width`, sorted by (i, j), with natural ids in range.
std::vector<double> read_checkpoint_history(const Checkpoint& meta, std::size_t width,
                                            const std::function<bool(std::int64_t)>& keep);

}  // namespace peri
