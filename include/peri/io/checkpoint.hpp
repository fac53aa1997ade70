// Checkpoint: the file format of a resumable run state. Pure file I/O (serial HDF5, no MPI, no
// PETSc): restart.hpp gathers a distributed run into a Checkpoint and scatters it back.
//
// Layout. One HDF5 file with a 512-byte user block in front, which HDF5 itself skips:
//   user block  "peridrive checkpoint\n" "format_version: 1\n" "file_bytes: N\n"
//               "fnv1a64: <16 hex digits>\n", padded with NUL bytes. The hash covers every byte
//               after the user block, so a truncated, bit-flipped or foreign file is refused
//               before HDF5 parses any of it.
//   /           attributes: format_version, peridrive_version, git_revision, scene_hash, nodes,
//               ordered_bonds, step, time, stage, stage_step, initial_total_energy, ranks
//   /scene      the resolved YAML, a scalar string dataset of any length (files written before
//               it could exceed 64 KB hold it as an attribute `scene` of /, still read)
//   /state      displacement [N,3], velocity [N,3] (natural node order: rank-independent)
//   /bonds      broken [B,2]: every broken bond once as natural ids (i < j), sorted
//   /tallies    per writing rank: dissipated, damping_work, external_work, newly_broken, owner_hash
//   /extras     one 1-D double dataset per registered extra array (diagnostics' history)
// Load-ramp state needs no field: boundary velocities are functions of the simulated time.
#pragma once
#include <cstddef>
#include <cstdint>
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
  std::vector<double> displacement, velocity;     ///< 3N each, natural order [m], [m/s]
  std::vector<std::int64_t> broken;               ///< 2B: (i, j) pairs, i < j, sorted
  std::map<std::string, std::vector<double>> extras;  ///< named extra arrays
};

/// 64-bit FNV-1a hash (continues from `h`).
std::uint64_t fnv1a64(const void* data, std::size_t bytes, std::uint64_t h = 14695981039346656037ull);

/// The file name a previous checkpoint is kept under: "a/checkpoint.h5" -> "a/checkpoint.prev.h5".
std::string previous_checkpoint_path(const std::string& path);

/// Write `c` to `path` atomically: a temporary file is written, flushed to disk and closed; the
/// existing `path` (if any) is renamed to previous_checkpoint_path(path); then the temporary is
/// renamed to `path`. At every moment one complete checkpoint exists. Throws Error on failure.
void write_checkpoint(const std::string& path, const Checkpoint& c);

/// Read and check a checkpoint. Throws InputError naming the file and what is wrong (not a
/// checkpoint, other format version, truncated, damaged, inconsistent) and never crashes on a
/// hostile file. Checks the header and the hash before HDF5 reads anything.
Checkpoint read_checkpoint(const std::string& path);

}  // namespace peri
