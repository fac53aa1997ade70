#include "peri/stages/simulation.hpp"

#include <petsclog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>

#include "peri/io/checkpoint.hpp"
#include "peri/io/restart.hpp"
#include "peri/stages/events.hpp"
#include "peri/stages/release.hpp"
#include "peri/stages/setup_checks.hpp"

namespace peri {
namespace {

constexpr int kCheckEvery = 20;  // steps between collective health/progress checks

}  // namespace

Simulation::Simulation(const Scene& scene, MPI_Comm comm, RunOptions options)
    : options_(std::move(options)),
      start_(std::chrono::steady_clock::now()),
      p_(build_problem(scene, comm, summary_)),
      scene_(p_->scene),
      comm_(p_->comm),
      rank_(p_->rank),
      ranks_(p_->ranks),
      domain_(p_->domain),
      state_(*p_->state),
      forces_(*p_->forces),
      total_steps_(p_->stages.total),
      health_(scene_, domain_, forces_.laws(), comm_),
      verlet_(*p_, ledger_, health_),
      equilibrium_(*p_, ledger_),
      output_(scene_.output, total_steps_, rank_),
      cadence_(scene_.output, !options_.out_dir.empty(), comm_) {
  if (p_->tools && p_->tools->friction())  // (natural id, tool, force) of every friction force, gathered to rank 0
    add_checkpoint_extra(
        "tool_friction", [this] { return p_->tools->save_friction(); },
        [this](const std::vector<double>* flat) { p_->tools->restore_friction(flat); });
  if (p_->tools && p_->tools->free())  // free tools' positions and velocities (every rank holds them)
    add_checkpoint_extra(
        "free_tools", [this] { return p_->tools->save_free(); },
        [this](const std::vector<double>* flat) { p_->tools->restore_free(flat); });
  if (TipAdvance* rule = forces_.tip_advance())  // break times of the damaged nodes, gathered to rank 0
    add_checkpoint_extra(
        "tip_advance_break_times", [this, rule] { return rule->save(time_, comm_); },
        [this, rule](const std::vector<double>* flat) { rule->restore(flat, forces_.bond_view()); });
  // The energy check's count of steps above its tolerance: a resumed run stops where the run
  // it continues would have.
  add_checkpoint_extra(
      "energy_error_since", [this] { return health_.save(); },
      [this](const std::vector<double>* saved) { health_.restore(saved); });
  if (options_.restart)
    check_restart(*options_.restart, scene_, domain_.global_nodes, summary_.ordered_bonds, p_->stages.steps,
                  reference_geometry_hash(domain_, comm_));
  tips_ = CrackTipMonitor::create(scene_, forces_.laws(), p_->bodies, p_->density,
                                  scene_.output.series_every * *std::max_element(p_->stages.dt.begin(), p_->stages.dt.end()),
                                  domain_, comm_);
  if (tips_) {
    summary_.crack_tracking = true;
    summary_.rayleigh_wave_speed = tips_->rayleigh_wave_speed();
    summary_.crack_speed_window = tips_->window();
    // The tip history continues across restarts; the tips themselves are recomputed from damage.
    add_checkpoint_extra(
        "crack_tip_tracks", [this] { return tips_->save(); },
        [this](const std::vector<double>* flat) { tips_->restore(flat); });
  }

  for (const Stage& stage : scene_.stages)
    if (stage.kind == StageKind::QuasiStatic) QuasiStaticLoader::check_options(comm_, stage);

  // Output last: nothing is written unless every check above passed.
  stop_point(comm_);
  if (!options_.out_dir.empty()) {
    std::string columns = tips_ ? tips_->series_columns() : std::string();
    if (p_->tools) {
      if (!columns.empty()) columns += ',';
      columns += p_->tools->series_columns();
    }
    output_.open(options_.out_dir, domain_, state_, p_->resolved, scene_.output,
                 options_.restart ? options_.restart->step : -1, columns, tips_ != nullptr, comm_,
                 mesh_triangles(p_->bodies));
    if (std::any_of(scene_.stages.begin(), scene_.stages.end(),
                    [](const Stage& s) { return s.kind == StageKind::QuasiStatic; })) {
      std::string qs = "step,stage,increment,load_factor,newton_iterations,linear_iterations,broken_bonds,"
                       "strain_energy,dissipated_energy,external_work";
      for (const Boundary& b : scene_.boundaries)
        for (const char* c : {"_reaction_x", "_reaction_y", "_reaction_z"}) qs += "," + b.name + c;
      output_.open_quasistatic(qs, options_.restart ? options_.restart->step : -1);
    }
  }
  summary_.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

Simulation::~Simulation() = default;

// ------------------------------------------------------------------------------------------------
// The run

void Simulation::run() {
  begin();
  advance(total_steps_);
  if (!cadence_.stopped()) finish();
}

void Simulation::begin() {
  cadence_.start(options_.restart ? options_.restart->step : -1);
  if (options_.restart) {
    const auto t0 = std::chrono::steady_clock::now();
    restore(*options_.restart);
    summary_.resume_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return;
  }
  apply_initial_conditions(*p_);
  // Stages that take no time and come first (preload, release) shape the initial state.
  const Stage* quasistatic = nullptr;
  while (stage_ < scene_.stages.size() && scene_.stages[stage_].kind != StageKind::Dynamic) {
    run_timeless_stage(scene_.stages[stage_]);
    if (scene_.stages[stage_].kind == StageKind::QuasiStatic) quasistatic = &scene_.stages[stage_];
    ++stage_;
  }
  verlet_.forces_at(time_);
  if (quasistatic) check_tools_clear(*quasistatic);
  write_series_row();
  summary_.initial_total_energy = summary_.final_energy.total();
  // Without a leading preload the whole run's balance starts here too (run_quasistatic sets it
  // before the first preload's work).
  if (summary_.quasistatic.empty()) summary_.run_initial_total_energy = summary_.initial_total_energy;
  if (output_.frame_due(0)) write_frame();
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] %lld nodes, %lld bonds, %d rank%s; dt = %.4g s (stable bound %.4g s), %lld steps; bond kernel %s\n",
                static_cast<long long>(summary_.nodes), static_cast<long long>(summary_.ordered_bonds / 2),
                ranks_, ranks_ > 1 ? "s" : "", summary_.dt, summary_.dt_stable,
                static_cast<long long>(total_steps_), bond_kernel_isa());
    std::fflush(stdout);
  }
  start_loop_clock();
}

std::int64_t Simulation::advance(std::int64_t n) {
  std::int64_t taken = 0;
  while (stage_ < scene_.stages.size() && !cadence_.stopped()) {
    const Stage& stage = scene_.stages[stage_];
    if (stage.kind != StageKind::Dynamic) {
      // A later stage that takes no time: run it, and restart the energy balance after a
      // quasi-static one (it removes kinetic energy by construction).
      run_timeless_stage(stage);
      ++stage_;
      verlet_.forces_at(time_);
      if (stage.kind == StageKind::QuasiStatic) check_tools_clear(stage);
      write_series_row(stage.kind == StageKind::QuasiStatic);
      if (stage_ == scene_.stages.size() && final_frame_deferred_) {
        final_frame_deferred_ = false;
        write_frame();
      }
      continue;
    }
    if (!stage_started_) {
      verlet_.start(stage, p_->stages.dt[stage_]);
      stage_started_ = true;
    }
    if (stage_step_ >= p_->stages.steps[stage_]) {
      ++stage_;
      stage_step_ = 0;
      stage_started_ = false;
      continue;
    }
    if (taken >= n) break;
    explicit_step();
    ++taken;
  }
  verlet_.settle_kick();  // v(t) whole when the call returns
  return taken;
}

void Simulation::explicit_step() {
  const bool series = (step_ + 1) % scene_.output.series_every == 0 || step_ + 1 == total_steps_;
  // A frame's step is an energy call too: the bond loop then writes the energy density.
  const bool frame_next = output_.frame_due(step_ + 1);
  time_ = verlet_.step(time_, series || frame_next, true);
  ++step_;
  ++stage_step_;
  const bool frame = output_.frame_due(step_);
  // Checkpoints come at these steps and the polls' (kCheckEvery, the last step).
  const bool checkpoint_step =
      scene_.output.checkpoint_every_steps > 0 && step_ % scene_.output.checkpoint_every_steps == 0;
  // Nothing is written before the state is checked: no non-finite value reaches a file, and no
  // checkpoint holds a step that moved a node too far (a resumed run stops where this one would).
  // The checks' steps depend on the scene alone, not on whether this run writes checkpoints.
  // (Each reader of the velocity applies a deferred kick first: settle_kick().)
  if (series || frame || checkpoint_step || step_ % kCheckEvery == 0 || step_ == total_steps_)
    check_health(step_, time_);
  if (series) write_series_row();
  if (frame) {
    if (step_ == total_steps_ && scene_.stages.back().kind != StageKind::Dynamic) final_frame_deferred_ = true;
    else write_frame();
  }
  if (cadence_.due(step_, step_ % kCheckEvery == 0 || step_ == total_steps_)) write_checkpoint();
}

void Simulation::finish() {
  const auto t_end = std::chrono::steady_clock::now();
  summary_.step_seconds = std::chrono::duration<double>(t_end - loop_start_).count() -
                          (summary_.output_seconds - output_seconds_at_loop_start_);
  summary_.steps_timed = step_ - loop_start_step_;
  summary_.wall_seconds = std::chrono::duration<double>(t_end - start_).count();
  summary_.simulated_time = time_;
  summary_.frames = output_.frames();
  summary_.energy_balance_error = energy_balance_error(summary_.final_energy);
  summary_.run_energy_balance_error =
      peri::energy_balance_error(summary_.final_energy, summary_.run_initial_total_energy, p_->energy_floor);
  if (tips_) {
    summary_.max_crack_speed = tips_->max_speed();
    summary_.mean_crack_speed = tips_->mean_speed();
    summary_.crack_tips_json = tips_->tracks_json();
    summary_.crack_tip_seconds = tips_->seconds();
  }
  // Timings of the slowest rank: the job's figures.
  double times[6] = {summary_.step_seconds, summary_.output_seconds, summary_.wall_seconds,
                     summary_.crack_tip_seconds, summary_.checkpoint_seconds, summary_.resume_seconds}, tmax[6];
  MPI_Allreduce(times, tmax, 6, MPI_DOUBLE, MPI_MAX, comm_);
  summary_.checkpoint_seconds = tmax[4];
  summary_.resume_seconds = tmax[5];
  summary_.crack_tip_seconds = tmax[3];
  summary_.step_seconds = tmax[0];
  summary_.output_seconds = tmax[1];
  summary_.wall_seconds = tmax[2];
  mark_memory(summary_, "end", comm_);
  output_.write_summary(summary_.to_json());
}

void Simulation::start_loop_clock() {
  loop_start_ = std::chrono::steady_clock::now();
  loop_start_step_ = step_;  // (a resumed run: the steps before the checkpoint were timed by the run that took them)
  output_seconds_at_loop_start_ = summary_.output_seconds;  // the first frame is not the loop's
  last_progress_ = loop_start_;
}

// ------------------------------------------------------------------------------------------------
// Stages that take no time

void Simulation::run_timeless_stage(const Stage& stage) {
  verlet_.settle_kick();  // with the force and time step it was deferred with
  if (stage.kind == StageKind::QuasiStatic) run_quasistatic(stage);
  else run_release(stage);
}

void Simulation::check_tools_clear(const Stage& stage) {
  // Tools act in dynamic stages only: an equilibrium found without a tool that touches the body
  // is not the state the scene describes.
  const std::string tool = p_->tools ? p_->tools->touching() : std::string();
  if (!tool.empty())
    throw RuntimeFailure(stage.where.str() + ": stages." + stage.name + ": tool '" + tool +
                     "' touches the body at the end of this quasi-static stage; tools act in dynamic stages only "
                     "(the equilibrium holds the bonds and the pressure): place the tool clear of the body until a "
                     "dynamic stage");
}

void Simulation::run_release(const Stage& stage) {
  const std::int64_t released = release_cracks(*p_, stage, ledger_);
  summary_.precrack_bonds += released;
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] release '%s': %lld bonds broken\n", stage.name.c_str(), static_cast<long long>(released));
    std::fflush(stdout);
  }
  // (Cracks that cross no bond at all are refused at setup: check_release_stages.) Every bond
  // they cross may have broken before the release, as a running crack breaks them.
  if (released == 0 && rank_ == 0)
    std::fprintf(stderr, "peridrive: warning: %s: stages.%s: every bond the named cracks cross was already broken; "
                 "the release broke none\n", stage.where.str().c_str(), stage.name.c_str());
}

void Simulation::run_quasistatic(const Stage& stage) {
  const EnergyRow before = energies();
  if (step_ == 0 && summary_.quasistatic.empty()) summary_.run_initial_total_energy = before.total();
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] quasistatic '%s': %ld initial load steps\n", stage.name.c_str(), stage.load_steps);
    std::fflush(stdout);
  }
  // quasistatic.csv: a row per converged increment (energies, support work so far, and the
  // support reaction summed over each boundary's nodes).
  IncrementObserver observer;
  if (output_.writes())
    observer = [&](const QuasiStaticStats& so_far, const double* reaction) {
      const std::size_t nb = scene_.boundaries.size();
      std::vector<double> local(1 + 3 * nb, 0.0), sum(local.size());
      local[0] = so_far.external_work;
      for (std::int32_t i : p_->boundaries->rows())
        for (int c = 0; c < 3; ++c) local[1 + 3 * p_->boundaries->of(i) + c] += reaction[3 * static_cast<std::size_t>(i) + c];
      MPI_Allreduce(local.data(), sum.data(), static_cast<int>(local.size()), MPI_DOUBLE, MPI_SUM, comm_);
      const EnergyRow row = energies();
      if (rank_ != 0) return;
      const LoadIncrement& inc = so_far.increments.back();
      std::ostringstream s;
      s.precision(12);
      s << step_ << ',' << stage.name << ',' << so_far.increments.size() << ',' << inc.load_factor << ','
        << inc.newton_iterations << ',' << inc.linear_iterations << ',' << row.broken_bonds << ',' << row.strain << ','
        << row.dissipated << ',' << row.external_work + sum[0];
      for (std::size_t k = 1; k < sum.size(); ++k) s << ',' << sum[k];
      output_.write_quasistatic(s.str());
    };
  const QuasiStaticStats stats =
      peri::run_quasistatic(*p_, stage, time_, equilibrium_, ledger_, !options_.quiet, observer);
  const EnergyRow after = energies();
  const double work = stats.external_work;
  const double stored = (after.strain - before.strain) + (after.dissipated - before.dissipated) - before.kinetic;
  summary_.quasistatic.push_back({stage.name, stats});
  // Relative to the work, or where the work is round-off (a rigid motion of the whole body), to
  // 1e-9 of the prescribed moves' energy scale. A stage that moves no support (a relaxation)
  // does no work to compare with: no figure (null in summary.json), no warning.
  const double scale = std::max(std::fabs(work), 1e-9 * stats.work_scale);
  summary_.quasistatic_work_error.push_back(scale > 0 ? std::fabs(work - stored) / scale : NAN);
  // Work the supports did that the body neither holds nor dissipated: bonds that break between
  // two equilibria (a preload that tears the sheet) release energy no stage follows. The explicit
  // part's balance restarts after this stage and would not show it; run_energy_balance_error does.
  const double tolerance = scene_.stability.energy_error;
  if (rank_ == 0 && tolerance > 0 && std::isfinite(summary_.quasistatic_work_error.back()) &&
      summary_.quasistatic_work_error.back() > tolerance)
    std::fprintf(stderr,
                 "peridrive: warning: %s: stages.%zu ('%s'): the quasi-static supports did %.6g J of work, but "
                 "the body stores and dissipated %.6g J (%.3g%% apart, more than stability.energy_error = %g; "
                 "%lld bonds broke in the stage); summary.json's run_energy_balance_error counts the difference\n",
                 stage.where.str().c_str(), stage_, stage.name.c_str(), work, stored,
                 100 * summary_.quasistatic_work_error.back(), tolerance, static_cast<long long>(stats.broken));
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] quasistatic '%s': %zu increments, %d cut-backs, %ld Newton and %ld linear iterations, "
                "%lld bonds broken, %.3g s; support work %.6g J vs stored + dissipated %.6g J\n",
                stage.name.c_str(), stats.increments.size(), stats.cutbacks, stats.newton_iterations,
                stats.linear_iterations, static_cast<long long>(stats.broken), stats.seconds, work, stored);
    std::fflush(stdout);
  }
}

// ------------------------------------------------------------------------------------------------
// Checks and output of a step

void Simulation::check_health(std::int64_t step, double time) {
  verlet_.settle_kick();
  {
    const VecArrayRead u(state_.displacement()), v(state_.velocity());
    health_.check(step, time, u.data(), v.data(), verlet_.dt(), summary_.dt_stable);
  }
  if (options_.quiet) return;
  const auto now = std::chrono::steady_clock::now();
  int print = rank_ == 0 && std::chrono::duration<double>(now - last_progress_).count() >= scene_.output.progress_seconds;
  MPI_Bcast(&print, 1, MPI_INT, 0, comm_);
  if (!print) return;
  long long broken_local = ledger_.bonds.newly_broken, broken = 0;
  MPI_Reduce(&broken_local, &broken, 1, MPI_LONG_LONG, MPI_SUM, 0, comm_);
  if (rank_ == 0) {
    const double elapsed = std::chrono::duration<double>(now - loop_start_).count();
    const double rate = (step - loop_start_step_) / std::max(elapsed, 1e-9);
    std::printf("[peridrive] step %lld/%lld  t = %.4g s  %.0f steps/s  ETA %.0f s  broken bonds %lld\n",
                static_cast<long long>(step), static_cast<long long>(total_steps_), time, rate,
                (total_steps_ - step) / std::max(rate, 1e-9), broken / 2);
    std::fflush(stdout);
  }
  last_progress_ = now;
}

void Simulation::write_series_row(bool new_reference) {
  const EnergyRow row = reduce_energies(ledger_.bonds.strain_energy);
  if (new_reference) summary_.initial_total_energy = row.total();
  // Energy growth detector (after the first row, which sets the reference).
  if (step_ > 0)
    health_.check_energy(row, energy_balance_error(row), summary_.initial_total_energy, verlet_.dt(), summary_.dt_stable,
                         step_ == total_steps_);
  std::string extra;
  if (tips_) {
    extra = tips_->sample(row, [this] { return forces_.damage(); });
    output_.write_tips(tips_->csv_rows(row));
  }
  if (p_->tools) extra += p_->tools->series_values(time_, !extra.empty());
  output_.write_series(row, extra);
  summary_.final_energy = row;
}

void Simulation::write_frame() {
  verlet_.settle_kick();
  PetscLogEventBegin(events().output, 0, 0, 0, 0);
  const auto t0 = std::chrono::steady_clock::now();
  const double* damage = forces_.damage();
  const double* energy_density = forces_.energy_density();
  {
    const VecArrayRead u(state_.displacement()), v(state_.velocity());
    output_.write_frame(step_, time_, u.data(), v.data(), damage, energy_density);
  }
  summary_.output_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  PetscLogEventEnd(events().output, 0, 0, 0, 0);
}

// ------------------------------------------------------------------------------------------------
// Checkpoints and restart

void Simulation::add_checkpoint_extra(std::string name, std::function<std::vector<double>()> save,
                                      std::function<void(const std::vector<double>*)> restore) {
  extras_.add(std::move(name), std::move(save), std::move(restore));
}

Checkpoint Simulation::make_checkpoint() {
  return peri::make_checkpoint(scene_, domain_, state_, ledger_, {step_, time_, stage_, stage_step_}, summary_, extras_,
                               comm_, forces_.dashpot_velocity());
}

void Simulation::write_checkpoint() {
  verlet_.settle_kick();
  PetscLogEventBegin(events().output, 0, 0, 0, 0);
  const auto t0 = std::chrono::steady_clock::now();
  store_checkpoint(checkpoint_path(), make_checkpoint(), comm_);
  cadence_.written(step_);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  summary_.output_seconds += seconds;
  summary_.checkpoint_seconds += seconds;
  ++summary_.checkpoints_written;
  PetscLogEventEnd(events().output, 0, 0, 0, 0);
}

void Simulation::restore(const Checkpoint& c) {
  std::vector<double> dashpot_velocity;
  restore_state(c, domain_, state_, ledger_, comm_, forces_.has_dashpots() ? &dashpot_velocity : nullptr);
  forces_.flags_changed();
  restore_summary(c, scene_, summary_);
  step_ = c.step;
  time_ = c.time;
  stage_ = static_cast<std::size_t>(c.stage);
  stage_step_ = c.stage_step;
  summary_.initial_total_energy = c.initial_total_energy;
  extras_.restore(c);
  // A load that a quasi-static stage before this one brought to its full value keeps it.
  for (std::size_t k = 0; k < stage_ && k < scene_.stages.size(); ++k)
    if (scene_.stages[k].kind == StageKind::QuasiStatic)
      for (const auto& load : p_->loads)
        if (load->quasistatic()) {
          load->begin_quasistatic(time_);
          load->set_quasistatic_level(1.0);
        }

  // Forces at the restored positions, computed as the uninterrupted run did at the end of this
  // step; every bond past its critical stretch there is already broken, so none breaks now. Bond
  // dashpots see the velocity they saw then (the half step's, kept by the checkpoint; files
  // without it: the full step's, and the run continues close to, not exactly as, the original).
  if (!dashpot_velocity.empty()) {
    const auto swap_velocity = [&] {
      const VecArray v(state_.velocity());
      std::swap_ranges(dashpot_velocity.begin(), dashpot_velocity.end(), v.data());
    };
    swap_velocity();
    verlet_.forces_at(time_);
    swap_velocity();
  } else {
    verlet_.forces_at(time_);
    if (forces_.has_dashpots() && rank_ == 0 && !options_.quiet)
      std::fprintf(stderr,
                   "peridrive: note: checkpoint '%s' holds no dashpot velocity (written before it was kept): the "
                   "resumed run continues close to, not bit for bit as, the uninterrupted one\n",
                   c.path.c_str());
  }
  summary_.final_energy = reduce_energies(ledger_.bonds.strain_energy);
  output_.skip_frames_through(step_);
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] resumed at step %lld/%lld (t = %.6g s) from a checkpoint written on %d rank%s\n",
                static_cast<long long>(step_), static_cast<long long>(total_steps_), time_, c.ranks,
                c.ranks > 1 ? "s" : "");
    std::fflush(stdout);
  }
  start_loop_clock();
}

// ------------------------------------------------------------------------------------------------
// Energies and fields

EnergyRow Simulation::energies() {
  // Strain energy of the current state from a separate (non-breaking) pass.
  return reduce_energies(forces_.strain_energy());
}

double Simulation::energy_balance_error(const EnergyRow& row) const {
  return peri::energy_balance_error(row, summary_.initial_total_energy, p_->energy_floor);
}

EnergyRow Simulation::reduce_energies(double local_strain) {
  verlet_.settle_kick();
  const VecArrayRead v(state_.velocity());
  const double kinetic = kinetic_energy(v.data(), p_->mass, comm_);
  return peri::reduce_energies(ledger_, local_strain, kinetic, step_, time_, comm_);
}

std::array<double, 6> Simulation::momentum() {
  const VecArrayRead u(state_.displacement()), v(state_.velocity());
  return peri::momentum(domain_.X.data(), u.data(), v.data(), p_->mass, comm_);
}

std::vector<double> Simulation::gather_natural(const double* owned, int bs) {
  const double* slice = state_.to_natural(owned, bs);
  const int n = static_cast<int>(bs * state_.natural_count());
  std::vector<int> counts(ranks_), displs(ranks_, 0);
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
  for (int r = 1; r < ranks_; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(static_cast<std::size_t>(bs) * domain_.global_nodes);
  MPI_Allgatherv(slice, n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, comm_);
  return all;
}

std::vector<double> Simulation::natural_positions() {
  std::vector<double> x(3 * static_cast<std::size_t>(domain_.owned));
  {
    const VecArrayRead u(state_.displacement());
    for (std::size_t a = 0; a < x.size(); ++a) x[a] = domain_.X[a] + u[a];
  }
  return gather_natural(x.data(), 3);
}

std::vector<double> Simulation::natural_velocities() {
  verlet_.settle_kick();
  std::vector<double> copy;
  {
    const VecArrayRead v(state_.velocity());
    copy.assign(v.data(), v.data() + 3 * static_cast<std::size_t>(domain_.owned));
  }
  return gather_natural(copy.data(), 3);
}

std::vector<double> Simulation::natural_damage() { return gather_natural(forces_.damage(), 1); }

std::vector<std::pair<std::int64_t, std::int64_t>> Simulation::broken_bonds() {
  std::vector<long long> mine;
  for (std::int32_t i = 0; i < domain_.owned; ++i)
    for (std::int64_t b = domain_.bonds.offsets[i]; b < domain_.bonds.offsets[i + 1]; ++b)
      if (domain_.bonds.broken[b] & 1) {  // bit 0: broken (lattices keep other bits)
        const long long a = domain_.natural[i], c = domain_.natural[domain_.bonds.neighbor[b]];
        if (a < c) mine.insert(mine.end(), {a, c});
        else mine.insert(mine.end(), {c, a});
      }
  const int n = static_cast<int>(mine.size());
  std::vector<int> counts(ranks_), displs(ranks_, 0);
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
  for (int r = 1; r < ranks_; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<long long> all(displs.back() + counts.back());
  MPI_Allgatherv(mine.data(), n, MPI_LONG_LONG, all.data(), counts.data(), displs.data(), MPI_LONG_LONG, comm_);
  std::set<std::pair<std::int64_t, std::int64_t>> set;
  for (std::size_t k = 0; k < all.size(); k += 2) set.insert({all[k], all[k + 1]});
  return {set.begin(), set.end()};
}

std::vector<std::string> Simulation::derived_lines() const { return peri::derived_lines(summary_); }

const std::string& Simulation::resolved_scene() const { return p_->resolved; }

// ------------------------------------------------------------------------------------------------
// The quasi-static loader's view (tests call it directly)

void Simulation::set_displacement(const double* u_owned) { equilibrium_.set_displacement(u_owned); }
void Simulation::get_displacement(double* u_owned) { equilibrium_.get_displacement(u_owned); }
void Simulation::internal_force(double* f_owned) { equilibrium_.internal_force(f_owned); }
bool Simulation::load_force(double* f_owned) { return equilibrium_.load_force(f_owned); }
void Simulation::set_load_level(double level) { equilibrium_.set_load_level(level); }
std::string Simulation::load_text(double level) const { return equilibrium_.load_text(level); }
void Simulation::add_tangent(Mat J, const DofLayout& layout) { equilibrium_.add_tangent(J, layout); }
std::int64_t Simulation::break_bonds() { return equilibrium_.break_bonds(); }

std::unique_ptr<QuasiStaticLoader> Simulation::make_loader(const Stage& stage) { return peri::make_loader(*p_, stage); }

}  // namespace peri
