#include "peri/io/run_output.hpp"

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "peri/core/collective.hpp"
#include "peri/core/error.hpp"
#include "peri/diagnostics/crack_tip_monitor.hpp"
#include "peri/io/run_dir.hpp"

namespace peri {

RunOutput::RunOutput(const Output& output, std::int64_t total_steps, int rank) : rank_(rank) {
  // More frames than steps would repeat steps: one per step at most (the same frames are written).
  const int frames = static_cast<int>(output_frames(output, total_steps));
  if (frames < output.frames && rank == 0)
    std::fprintf(stderr, "peridrive: warning: output.frames: %d frames asked for a run of %lld steps; writing %d, "
                 "one per step\n", output.frames, static_cast<long long>(total_steps), frames);
  for (int k = 0; k < frames; ++k)
    frame_steps_.push_back(frames == 1 ? total_steps : std::llround(double(k) * total_steps / (frames - 1)));
}

void RunOutput::open(const std::string& dir, const Domain& domain, State& state, const std::string& resolved_scene,
                     const Output& output, std::int64_t resume_step, const std::string& series_columns, bool tips,
                     MPI_Comm comm, std::vector<std::array<std::int64_t, 3>> triangles) {
  dir_ = dir;
  comm_ = comm;
  make_output_dir(dir, comm);
  frames_ = std::make_unique<FrameWriter>(dir, "frames", domain, state, output);  // (writes nothing yet)
  frames_->set_triangles(std::move(triangles));
  check_free_space(output, domain.global_nodes, resume_step);
  std::string error;
  if (rank_ == 0) {
    // A previous run's completion marker must not vouch for this one until it finishes; a fresh
    // run leaves nothing of an earlier one (checkpoints, tips, temporaries) to be mixed with its own.
    const std::vector<std::string> stale =
        resume_step >= 0 ? std::vector<std::string>{"summary.json", "FAILED"} : run_file_names();
    for (const std::string& name : stale) {
      const std::string path = dir + "/" + name;
      errno = 0;
      if (std::remove(path.c_str()) != 0 && errno != ENOENT && error.empty())
        error = path + ": cannot remove this file of an earlier run (" + std::strerror(errno) +
                "); it would describe this run's output; remove it, or give another --out";
    }
    if (!error.empty()) {
      try {  // (the marker, so that the earlier run's files left there are not taken for this run's)
        write_text_file(dir + "/FAILED", error + "\n");
      } catch (const Error&) {
      }
    } else {
      try {
        write_text_file(dir + "/scene.resolved.yaml", resolved_scene);
      } catch (const Error& e) {
        error = e.what();
      }
    }
  }
  const std::string verdict = agree_on_message(error, comm);  // (also the barrier before the frames)
  if (!verdict.empty()) throw RuntimeFailure(verdict);
  frames_->start(resolved_scene, resume_step);
  if (tips && rank_ == 0) {
    const std::string path = dir + "/tips.csv", header = CrackTipMonitor::kCsvHeader;
    const std::string kept = resume_step >= 0 ? rows_up_to(path, header, resume_step) : header;
    tips_ = std::make_unique<std::ofstream>(path, std::ios::trunc);
    *tips_ << kept;
  }
  // (A tips.csv that cannot be written is reported with the next frame, on every rank.)
  series_ = std::make_unique<SeriesWriter>(dir + "/series.csv", rank_ == 0, series_columns, resume_step);
  check_text_files();
}

double RunOutput::predicted_bytes(const Output& output, std::int64_t nodes, std::int64_t resume_step,
                                  std::string* parts) const {
  std::int64_t frames = 0;
  for (std::int64_t s : frame_steps_) frames += s > resume_step;
  return output_bytes(output, frames, frames_->frame_nodes(), nodes, resume_step < 0, frames_->triangles(), parts);
}

void RunOutput::check_free_space(const Output& output, std::int64_t nodes, std::int64_t resume_step) const {
  std::string parts;
  const double need = predicted_bytes(output, nodes, resume_step, &parts);
  std::string error;
  if (rank_ == 0 && output.check_free_space) {
    const double free = free_bytes(dir_);
    if (free >= 0 && need > free) {
      std::ostringstream s;
      s.precision(3);
      s << "output: the run would write about " << need / 1e6 << " MB to '" << dir_ << "' (" << parts
        << ") and its file system has " << free / 1e6 << " MB free; write fewer frames, nodes or fields "
        << "(output.frames, output.node_stride, output.region, output.fields, output.precision: single), free "
        << "space, or set output.check_free_space: false";
      error = s.str();
    }
  }
  const std::string verdict = agree_on_message(error, comm_);
  if (!verdict.empty()) throw InputError(verdict);
}

void RunOutput::open_quasistatic(const std::string& columns, std::int64_t resume_step) {
  if (rank_ == 0) {
    const std::string path = dir_ + "/quasistatic.csv", header = columns + "\n";
    const std::string kept = resume_step >= 0 ? rows_up_to(path, header, resume_step - 1) : header;
    quasistatic_ = std::make_unique<std::ofstream>(path, std::ios::trunc);
    *quasistatic_ << kept;
    quasistatic_->flush();
  }
  check_text_files();
}

void RunOutput::write_quasistatic(const std::string& row) {
  if (!quasistatic_) return;
  *quasistatic_ << row << '\n';
  quasistatic_->flush();
}

void RunOutput::check_text_files() const {
  std::string error;
  if (rank_ == 0 && series_ && !series_->good()) error = dir_ + "/series.csv: a row could not be written";
  if (rank_ == 0 && error.empty() && tips_ && !*tips_) error = dir_ + "/tips.csv: a row could not be written";
  if (rank_ == 0 && error.empty() && quasistatic_ && !*quasistatic_)
    error = dir_ + "/quasistatic.csv: a row could not be written";
  if (!error.empty()) {
    const double free = free_bytes(dir_);
    if (free >= 0) error += " (the file system holding '" + dir_ + "' has " + std::to_string(static_cast<long long>(free)) + " bytes free)";
  }
  const std::string verdict = agree_on_message(error, comm_);
  if (!verdict.empty()) throw RuntimeFailure(verdict);
}

void RunOutput::write_frame(std::int64_t step, double time, const double* u, const double* v, const double* damage,
                            const double* energy_density) {
  check_text_files();
  frames_->write(step, time, u, v, damage, energy_density);
  skip_frames_through(step);
}

void RunOutput::write_tips(const std::string& rows) {
  if (!tips_) return;
  *tips_ << rows;
  tips_->flush();
}

void RunOutput::write_summary(const std::string& json) const {
  if (dir_.empty()) return;
  check_text_files();
  std::string error;
  if (rank_ == 0) {
    try {
      write_text_file(dir_ + "/summary.json", json);
    } catch (const Error& e) {
      error = e.what();
    }
  }
  const std::string verdict = agree_on_message(error, comm_);
  if (!verdict.empty()) throw RuntimeFailure(verdict);
}

}  // namespace peri
