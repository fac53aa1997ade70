// Output: one parallel HDF5 file per run (collective writes, natural node order, one group per
// frame), an XDMF sidecar rewritten after every complete frame so ParaView/VisIt open the
// series directly, a CSV energy series and a JSON summary (rank 0). summary.json is written
// last: its presence marks a complete run.
#pragma once
#include <hdf5.h>
#include <mpi.h>

#include <array>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "peri/core/hdf5.hpp"
#include "peri/diagnostics/energies.hpp"
#include "peri/scene/scene.hpp"
#include "peri/state/state.hpp"

namespace peri {

/// Create `dir` (and parents) on rank 0; InputError naming it if that fails. Collective.
void make_output_dir(const std::string& dir, MPI_Comm comm);

/// Whether a frame writer has abandoned its file after writes that failed (see FrameWriter): the
/// process must then end without MPI_Finalize, at which HDF5 would close that file and may crash.
bool abandoned_output_files();
/// Record that a writer (a frame writer, a checkpoint) has abandoned such a file.
void mark_output_file_abandoned();

/// Write a small text file atomically (temporary name, then rename). Rank 0 only.
void write_text_file(const std::string& path, const std::string& text);

/// About how many bytes a frame of `nodes` nodes with the output's fields adds to a file.
double frame_bytes(const Output& output, std::int64_t nodes);
/// About how many bytes the mesh of `nodes` frame nodes takes (positions, body, volume, cells)
/// with `triangles` mesh-membrane triangles.
double mesh_bytes(const Output& output, std::int64_t nodes, std::int64_t triangles = 0);

/// About how many bytes a run writes: `frames` frames of `frame_nodes` nodes, the mesh (`mesh`,
/// with `triangles` mesh-membrane triangles), and checkpoints by step count of `nodes` nodes
/// (their displacement and velocity); `parts` receives these in words.
double output_bytes(const Output& output, std::int64_t frames, std::int64_t frame_nodes, std::int64_t nodes, bool mesh,
                    std::int64_t triangles = 0, std::string* parts = nullptr);
/// Frames a run of total_steps steps writes: output.frames, at most one per step.
std::int64_t output_frames(const Output& output, std::int64_t total_steps);

class FrameWriter {
 public:
  /// The frames of <dir>/<stem>.h5 with the output's fields, nodes and precision (scene
  /// `output`): which of the domain's nodes they hold is settled here (collective); nothing is
  /// written until start().
  FrameWriter(const std::string& dir, const std::string& stem, const Domain& domain, State& state,
              const Output& output);
  /// Opens <dir>/<stem>.h5 collectively and writes the mesh (reference positions, body, volume;
  /// with a node selection their natural ids). With resume_step >= 0 the existing file is
  /// continued instead: frames after that step are deleted and the XDMF rewritten; a file holding
  /// a partly written frame is rebuilt from its whole frames up to that step, and one that cannot
  /// be opened is replaced (each with a note).
  void start(const std::string& resolved_scene, std::int64_t resume_step = -1);
  /// The triangles of the mesh membranes (natural node ids, the files' orientation), which start()
  /// writes as /mesh/triangles (T x 3 int64) so that pictures draw the surface the mesh gave;
  /// none: no dataset. The same on every rank; set before start().
  void set_triangles(std::vector<std::array<std::int64_t, 3>> triangles) { triangles_ = std::move(triangles); }
  /// Nodes a frame holds (all ranks).
  std::int64_t frame_nodes() const { return sel_total_; }
  /// Triangles /mesh/triangles holds (set_triangles).
  std::int64_t triangles() const { return static_cast<std::int64_t>(triangles_.size()); }
  /// About how many bytes a frame adds to the file.
  double frame_bytes() const;
  ~FrameWriter();
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;
  /// Write one frame (owned arrays in local order), flush, and rewrite the XDMF. Collective.
  /// energy_density: strain energy per unit volume of each node (bonds, and long-range pairs).
  void write(std::int64_t step, double time, const double* u, const double* v, const double* damage,
             const double* energy_density);
  int frames() const { return static_cast<int>(times_.size()); }

 private:
  /// This rank's frame nodes of a field given on its natural slice (State::to_natural), bs values
  /// per node, as doubles (or floats, `single`) in the writer's buffer.
  const void* select(const double* natural_slice, int bs, bool single);
  /// A dataset of the frame nodes, this rank's `data` (its selected nodes, bs values each) at
  /// their place. Collective.
  void write_dataset(hid_t group, const char* name, const void* data, int bs, hid_t mem_type = H5T_NATIVE_DOUBLE,
                     hid_t file_type = H5T_NATIVE_DOUBLE);
  void write_connectivity(hid_t mesh);  ///< /mesh/connectivity: 0..N-1, collective
  /// Collective: throws RuntimeFailure on every rank, naming the file, `what` and the free space,
  /// when `ok` is false on any rank.
  void agree(bool ok, const std::string& what);
  /// This rank's reason for a failed write that the free space does not show, or "".
  std::string local_reason() const;
  /// <stem>.xdmf (the nodes as vertices), and with mesh membranes' triangles and every node in the
  /// frames, <stem>_surface.xdmf (the same frames over the triangles), listing every frame written.
  /// Unless `always`, past kXdmfEveryFrame frames only when kXdmfSeconds of wall time have passed
  /// since the last rewrite (each rewrite writes every frame's entry: rewriting after every frame
  /// made a run of N frames write O(N^2) bytes); the destructor and the failure paths write what
  /// is left. Rank 0.
  void write_xdmf(bool always) const;
  /// The frames the XDMF does not list yet, listed now (rank 0), where the run ends or fails;
  /// a failure to write it is printed as a warning if `warn`, else left to the run's own message.
  void list_unlisted_frames(bool warn) const noexcept;
  void write_xdmf_file(const std::string& name, bool surface) const;
  /// Frame k's <Grid> entry of the XDMF (surface: over the mesh membranes' triangles).
  std::string xdmf_grid(std::size_t k, bool surface) const;
  static constexpr std::size_t kXdmfEveryFrame = 256;
  static constexpr double kXdmfSeconds = 1.0;
  bool reopen(const std::string& path, hid_t fapl, std::int64_t resume_step);  // collective
  /// When reopen() fails: the file's readable frames up to resume_step copied into a new file
  /// that replaces it (false if it cannot be opened at all). Collective.
  bool salvage(const std::string& path, hid_t fapl, std::int64_t resume_step, const std::string& resolved_scene);
  H5Id create(const std::string& path, hid_t fapl, const std::string& resolved_scene);  // with the mesh

  std::string dir_, stem_;
  const Domain& domain_;
  State& state_;
  Output output_;
  std::vector<std::int64_t> pick_;  ///< with a node selection: the selected places of the natural slice
  std::int64_t sel_begin_ = 0, sel_count_ = 0, sel_total_ = 0;  ///< this rank's frame nodes in the file's order
  H5Id file_;
  std::vector<double> work_, selected_;
  std::vector<float> selected_single_;
  std::vector<std::array<std::int64_t, 3>> triangles_;
  std::vector<double> times_;
  std::vector<std::int64_t> steps_;
  // The XDMF entries of frames 0 .. xdmf_cached_ - 1 (vertices, surface), kept so that a rewrite
  // generates only the new frames' text; when the XDMF files were last written, and how many
  // frames they list.
  mutable std::string xdmf_grids_[2];
  mutable std::size_t xdmf_cached_[2] = {0, 0};
  mutable double xdmf_written_at_ = 0;
  mutable std::size_t xdmf_listed_ = 0;
};

/// CSV energy series, written by rank 0 (other ranks hold an inert writer).
/// Text of a CSV file whose rows start with a step number: `header`, then the complete rows with
/// step <= `step` (a partial last line is dropped). Used to continue outputs on restart.
std::string rows_up_to(const std::string& path, const std::string& header, std::int64_t step);

class SeriesWriter {
 public:
  /// `extra_columns`: further comma-separated column names appended to the header (none if empty).
  /// With resume_step >= 0 the existing file keeps its header and the complete rows of steps
  /// <= resume_step, and new rows are appended.
  SeriesWriter(const std::string& path, bool active, const std::string& extra_columns = "",
               std::int64_t resume_step = -1);
  /// `extra`: the values of the extra columns, comma-separated, in header order.
  void write(const EnergyRow& row, const std::string& extra = "");
  /// False once a row could not be written (a full disk); true on inactive ranks.
  bool good() const;

 private:
  std::ofstream out_;
  bool active_;
};

}  // namespace peri
