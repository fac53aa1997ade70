// The files of a run in its output directory: scene.resolved.yaml, frames.h5 + frames.xdmf,
// series.csv, tips.csv, quasistatic.csv (rank 0) and summary.json, written last (its presence marks a complete
// run); and the steps that get a frame. A fresh run first removes every file of an earlier run
// in the directory; a resumed one continues them, dropping frames and rows after its checkpoint.
#pragma once
#include <mpi.h>

#include <array>
#include <cstdint>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "peri/io/output.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

class RunOutput {
 public:
  /// The frames of a run of `total_steps` steps: output.frames of them evenly spaced from step 0
  /// to the last, at most one per step (rank 0 warns when fewer than asked).
  RunOutput(const Output& output, std::int64_t total_steps, int rank);

  /// Opens the files in `dir` (collective): a fresh run (resume_step < 0) removes an earlier
  /// run's files first; a resumed one continues them up to resume_step. Series columns beside
  /// the energies: `series_columns` (comma-separated); `tips`: write tips.csv; `triangles`: the
  /// mesh membranes' triangles (natural ids) for /mesh/triangles.
  /// Frames hold the scene output's fields, nodes and precision; a run whose predicted output
  /// (frames still to write, the mesh, checkpoints by step count) exceeds the free space of dir's
  /// file system is refused first, with InputError on every rank, unless output.check_free_space
  /// is false.
  void open(const std::string& dir, const Domain& domain, State& state, const std::string& resolved_scene,
            const Output& output, std::int64_t resume_step, const std::string& series_columns, bool tips,
            MPI_Comm comm, std::vector<std::array<std::int64_t, 3>> triangles = {});
  /// Whether files are written (open() was called).
  bool writes() const { return frames_ != nullptr; }

  /// Whether a frame is due at `step`: files are written and the next frame's step is at most
  /// `step`.
  bool frame_due(std::int64_t step) const {
    return frames_ && next_frame_ < frame_steps_.size() && frame_steps_[next_frame_] <= step;
  }
  /// The frames due up to `step` are taken (written now, or before a checkpoint).
  void skip_frames_through(std::int64_t step) {
    while (next_frame_ < frame_steps_.size() && frame_steps_[next_frame_] <= step) ++next_frame_;
  }
  /// One frame (owned arrays, local order), and the frames due up to `step` are taken. Collective:
  /// a frame that cannot be written, or a row of series.csv or tips.csv that could not be written
  /// since the last frame (a full disk), raises RuntimeFailure on every rank.
  void write_frame(std::int64_t step, double time, const double* u, const double* v, const double* damage,
                   const double* energy_density);
  int frames() const { return frames_ ? frames_->frames() : 0; }

  /// One row of series.csv: the energies, then the other columns' values (`extra`).
  void write_series(const EnergyRow& row, const std::string& extra) {
    if (series_) series_->write(row, extra);
  }
  /// Rows of tips.csv (rank 0; the other ranks write nothing).
  void write_tips(const std::string& rows);
  /// quasistatic.csv (rank 0), for scenes with quasi-static stages: its header is `columns`; a
  /// fresh run starts it empty, a resumed one keeps the rows of steps before resume_step (a
  /// quasi-static stage at the checkpoint's step runs again after the resume). Call after open().
  void open_quasistatic(const std::string& columns, std::int64_t resume_step);
  /// One row of quasistatic.csv (rank 0; the other ranks write nothing).
  void write_quasistatic(const std::string& row);
  /// summary.json (written by rank 0), the run's last file. Collective: a failure to write it,
  /// or an earlier row of series.csv or tips.csv that could not be written, raises RuntimeFailure
  /// on every rank.
  void write_summary(const std::string& json) const;

 private:
  /// RuntimeFailure on every rank when rank 0's series or tips could not be written. Collective.
  void check_text_files() const;
  /// About how many bytes the run still writes (frames after resume_step, the mesh when fresh,
  /// checkpoints by step count), with those parts in words.
  double predicted_bytes(const Output& output, std::int64_t nodes, std::int64_t resume_step, std::string* parts) const;
  void check_free_space(const Output& output, std::int64_t nodes, std::int64_t resume_step) const;

  std::string dir_;
  int rank_ = 0;
  MPI_Comm comm_ = MPI_COMM_NULL;
  std::vector<std::int64_t> frame_steps_;
  std::size_t next_frame_ = 0;
  std::unique_ptr<FrameWriter> frames_;
  std::unique_ptr<SeriesWriter> series_;
  std::unique_ptr<std::ofstream> tips_;  // rank 0
  std::unique_ptr<std::ofstream> quasistatic_;  // rank 0
};

}  // namespace peri
