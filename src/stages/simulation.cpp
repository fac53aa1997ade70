#include "peri/stages/simulation.hpp"

#include <petsclog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <limits>
#include <set>
#include <sstream>
#include <unordered_map>
#include <type_traits>

#include "peri/io/checkpoint.hpp"
#include "peri/io/restart.hpp"
#include "peri/stages/events.hpp"
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
      boundaries_(*p_->boundaries),
      mass_(p_->mass),
      inv_density_(p_->inv_density),
      total_steps_(p_->stages.total),
      health_(scene_, domain_, forces_.laws(), comm_),
      output_(scene_.output, total_steps_, rank_),
      cadence_(scene_.output, !options_.out_dir.empty(), comm_) {
  // The Verlet update's streams: runs of owned nodes of one body without a boundary (at most 64
  // nodes, so that a run failing the quick motion check is rechecked cheaply), and the others.
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    if (boundaries_.of(i) >= 0) continue;
    FreeRun* last = free_runs_.empty() ? nullptr : &free_runs_.back();
    if (last && last->end == i && last->body == domain_.body[i] && i - last->begin < 64)
      last->end = i + 1;
    else
      free_runs_.push_back({i, i + 1, domain_.body[i]});
  }
  if (p_->tools && p_->tools->friction())  // (natural id, tool, force) of every friction force, gathered to rank 0
    add_checkpoint_extra(
        "tool_friction", [this] { return p_->tools->save_friction(); },
        [this](const std::vector<double>* flat) { p_->tools->restore_friction(flat); });
  if (options_.restart)
    check_restart(*options_.restart, scene_, domain_.global_nodes, summary_.ordered_bonds, p_->stages.steps);
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

  // Output last: nothing is written unless every check above passed.
  stop_point(comm_);
  if (!options_.out_dir.empty()) {
    std::string columns = tips_ ? tips_->series_columns() : std::string();
    if (p_->tools) {
      if (!columns.empty()) columns += ',';
      columns += p_->tools->series_columns();
    }
    output_.open(options_.out_dir, domain_, state_, p_->resolved, scene_.output.write_velocity,
                 options_.restart ? options_.restart->step : -1, columns, tips_ != nullptr, comm_);
  }
  summary_.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

Simulation::~Simulation() = default;

std::vector<std::string> Simulation::derived_lines() const { return peri::derived_lines(summary_); }

const std::string& Simulation::resolved_scene() const { return p_->resolved; }

void Simulation::settle_kick() {
  if (!kick_pending_) return;
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  double* v;
  PERI_PETSC(VecGetArray(state_.velocity(), &v));
  second_kick_free(v, dt_);
  PERI_PETSC(VecRestoreArray(state_.velocity(), &v));
  kick_pending_ = false;
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
}

void Simulation::second_kick_free(double* v, double dt) const {
  for (const FreeRun& r : free_runs_) {  // kick with damp_new = 1, one stream per run
    const double ir = inv_density_[r.begin];
    const std::size_t k0 = 3 * static_cast<std::size_t>(r.begin), n = 3 * static_cast<std::size_t>(r.end - r.begin);
    double* __restrict vr = v + k0;
    const double* __restrict fr = forces_.force() + k0;
    for (std::size_t k = 0; k < n; ++k) vr[k] = vr[k] + 0.5 * dt * fr[k] * ir;
  }
}

void Simulation::step(bool with_energy, bool defer_kick) {
  const double dt = dt_, t0 = time_, t1 = time_ + dt;
  // Mass-proportional damping alpha (force -rho alpha v), integrated semi-implicitly:
  // v_half = (1 - alpha dt/2) v + dt/2 a(t),  v(t+dt) = (v_half + dt/2 a(t+dt)) / (1 + alpha dt/2).
  const double damp_old = 1.0 - 0.5 * damping_ * dt, damp_new = 1.0 / (1.0 + 0.5 * damping_ * dt);
  const double* force = forces_.force();
  const double* viscous_force = forces_.viscous();
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  double* u;
  double* v;
  PERI_PETSC(VecGetArray(state_.displacement(), &u));
  PERI_PETSC(VecGetArray(state_.velocity(), &v));
  Boundaries& boundaries = boundaries_;
  double damped = 0;  // energy removed by damping: alpha m v.v dt, trapezoidal in time
  // Energy removed by lattice dashpots: the kick by the dashpot force F_d over dt/2 changes the
  // kinetic energy by F_d . (v_before + v_after)/2 dt/2 (exactly the share of F_d in
  // m (v_after^2 - v_before^2)/2), booked as dissipated with the opposite sign.
  double viscous = 0;
  const bool kelvin = viscous_force != nullptr;  // lattice dashpots
  // Half kick and drift (velocity Verlet); prescribed components follow their boundary.
  const bool damped_run = damping_ > 0;
  // Free component k of node i: half kick, drift; returns the squared motion.
  auto kick_drift = [&](std::int32_t i, std::size_t k) {
    if (damped_run) damped += mass_[i] * v[k] * v[k];
    const double before = v[k];
    v[k] = damp_old * v[k] + 0.5 * dt * force[k] * inv_density_[i];
    if (kelvin) viscous -= viscous_force[k] * domain_.volume[i] * 0.5 * (before + v[k]);
    u[k] += dt * v[k];
    return dt * dt * v[k] * v[k];
  };
  // Instability detector: no stable explicit step moves a node by a sizeable part of the spacing.
  // (A node without intact bonds flies ballistically: exact at any speed, never unstable.)
  // The first such node in local order is reported (the streams below visit the nodes in another).
  std::int32_t unstable_row = -1;
  double unstable_moved2 = 0;
  auto check_motion = [&](std::int32_t i, double moved2) {
    if (!(moved2 <= health_.motion_limit2(domain_.body[i])) && health_.unstable_node() < 0 &&
        (unstable_row < 0 || i < unstable_row) &&
        forces_.has_intact_bond(i)) {
      unstable_row = i;
      unstable_moved2 = moved2;
    }
  };
  auto kick_drift_node = [&](std::int32_t i) {
    const int bi = boundaries.of(i);
    const std::size_t k0 = 3 * static_cast<std::size_t>(i);
    double moved2 = 0;
    if (bi < 0) {  // most nodes: no per-component boundary test
      for (int c = 0; c < 3; ++c) moved2 += kick_drift(i, k0 + c);
    }
    for (int c = 0; c < 3 && bi >= 0; ++c) {
      const std::size_t k = k0 + c;
      if (boundaries.prescribes(bi, c)) {
        moved2 += boundaries.drift(i, bi, c, k, t0, t1, u, v, force);
      } else {
        moved2 += kick_drift(i, k);
      }
    }
    check_motion(i, moved2);
  };
  const bool streaming = !damped_run && !kelvin;
  // The free nodes' second half kick of the step before, when it was deferred to this pass (a
  // stage, which alone sets damping and dt, begins with none pending).
  const bool pending = kick_pending_;
  kick_pending_ = false;
  if (streaming) {
    // Free runs: the same half kick and drift as kick_drift (damp_old = 1), one contiguous
    // stream of 3 (end - begin) components. Each component within (motion limit)^2 / 3 bounds
    // the node's squared motion by the limit; a run with any component beyond it (or a NaN) is
    // checked node by node.
    for (const FreeRun& r : free_runs_) {
      const double ir = inv_density_[r.begin];
      const double v2_third = health_.motion_limit2(r.body) / (3 * dt * dt) * (1 - 1e-12);
      const std::size_t k0 = 3 * static_cast<std::size_t>(r.begin), n = 3 * static_cast<std::size_t>(r.end - r.begin);
      double* __restrict vr = v + k0;
      double* __restrict ur = u + k0;
      const double* __restrict fr = force + k0;
      auto stream = [&](auto both) {  // (a compile-time choice: a test in the loop kept it scalar)
        for (std::size_t k = 0; k < n; ++k) {
          double vk = vr[k] + 0.5 * dt * fr[k] * ir;
          if constexpr (decltype(both)::value) vk = vk + 0.5 * dt * fr[k] * ir;  // two kicks, each rounded alone
          vr[k] = vk;
          ur[k] += dt * vk;
        }
      };
      if (pending) stream(std::true_type{});
      else stream(std::false_type{});
      int slow = 0;
      for (std::size_t k = 0; k < n; ++k) slow |= !(vr[k] * vr[k] <= v2_third);
      if (slow)
        for (std::int32_t i = r.begin; i < r.end; ++i) {
          const std::size_t k = 3 * static_cast<std::size_t>(i);
          check_motion(i, dt * dt * v[k] * v[k] + dt * dt * v[k + 1] * v[k + 1] + dt * dt * v[k + 2] * v[k + 2]);
        }
    }
    for (std::int32_t i : boundaries.rows()) kick_drift_node(i);
  } else {
    for (std::int32_t i = 0; i < domain_.owned; ++i) kick_drift_node(i);
  }
  if (unstable_row >= 0) health_.note_unstable(domain_.natural[unstable_row], std::sqrt(unstable_moved2));
  PERI_PETSC(VecRestoreArray(state_.displacement(), &u));
  PERI_PETSC(VecRestoreArray(state_.velocity(), &v));
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
  // Forces at x(t + dt); lattice dashpots see the half-step velocity v(t + dt/2) (README
  // "Kelvin dissipation").
  compute_forces(with_energy);
  add_load_forces(t1, true);
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  PERI_PETSC(VecGetArray(state_.velocity(), &v));
  // Free component k of node i: second half kick.
  auto kick = [&](std::int32_t i, std::size_t k) {
    const double before = v[k];
    v[k] = damp_new * (v[k] + 0.5 * dt * force[k] * inv_density_[i]);
    if (kelvin) viscous -= viscous_force[k] * domain_.volume[i] * 0.5 * (before + v[k]);
    if (damped_run) damped += mass_[i] * v[k] * v[k];
  };
  auto kick_node = [&](std::int32_t i) {
    const int bi = boundaries.of(i);
    const std::size_t k0 = 3 * static_cast<std::size_t>(i);
    for (int c = 0; c < 3; ++c) {
      const std::size_t k = k0 + c;
      if (bi >= 0 && boundaries.prescribes(bi, c)) {
        ledger_.external_work += boundaries.reaction_work(i, c, k, v, force, domain_.volume[i], mass_[i]);
      } else {
        kick(i, k);
      }
    }
  };
  if (streaming) {
    // The free nodes' second half kick: now, or (defer_kick, no tool reading v below) in the next
    // step's first pass, which then reads and writes velocity once for both kicks.
    if (defer_kick && !p_->tools) {
      kick_pending_ = true;
    } else {
      second_kick_free(v, dt);
    }
    for (std::int32_t i : boundaries.rows()) kick_node(i);
  } else {
    for (std::int32_t i = 0; i < domain_.owned; ++i) kick_node(i);
  }
  // The loads' work that needs the velocity just computed (friction).
  for (const auto& load : p_->loads) load->end_step(dt, v, ledger_);
  PERI_PETSC(VecRestoreArray(state_.velocity(), &v));
  if (damping_ > 0) ledger_.damping_work += 0.5 * damping_ * dt * damped;
  if (kelvin) ledger_.damping_work += 0.5 * dt * viscous;
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
  time_ = t1;
  ++step_;
}

void Simulation::add_load_forces(double t, bool book) {
  if (p_->loads.empty()) return;
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  const LoadTarget target{forces_.positions(), forces_.position_stride(), forces_.force(), dt_};
  for (const auto& load : p_->loads) load->add_forces(t, target, book, ledger_);
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
}

double Simulation::kinetic_energy() {
  settle_kick();
  const VecArrayRead v(state_.velocity());
  return peri::kinetic_energy(v.data(), mass_, comm_);
}

EnergyRow Simulation::energies() {
  // Strain energy of the current state from a separate (non-breaking) pass.
  return reduce_energies(forces_.strain_energy());
}

double Simulation::energy_balance_error(const EnergyRow& row) const {
  return peri::energy_balance_error(row, summary_.initial_total_energy, p_->energy_floor);
}

EnergyRow Simulation::reduce_energies(double local_strain) {
  const double kinetic = kinetic_energy();
  return peri::reduce_energies(ledger_, local_strain, kinetic, step_, time_, comm_);
}

void Simulation::write_series_row() {
  const EnergyRow row = reduce_energies(ledger_.bonds.strain_energy);
  // Energy growth detector (after the first row, which sets the reference).
  if (step_ > 0)
    health_.check_energy(row, energy_balance_error(row), summary_.initial_total_energy, dt_, summary_.dt_stable);
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
  settle_kick();
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

void Simulation::check_health(std::int64_t step, double time) {
  settle_kick();
  {
    const VecArrayRead u(state_.displacement()), v(state_.velocity());
    health_.check(step, time, u.data(), v.data(), dt_, summary_.dt_stable);
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

void Simulation::run() {
  begin();
  advance(total_steps_);
  if (!cadence_.stopped()) finish();
}

void Simulation::begin() {
  cadence_.start(options_.restart ? options_.restart->step : -1);
  if (options_.restart) {
    restore(*options_.restart);
    return;
  }
  apply_initial_conditions(*p_);
  // Stages that take no time and come first (preload, release) shape the initial state.
  while (stage_ < scene_.stages.size() && scene_.stages[stage_].kind != StageKind::Dynamic) {
    start_stage();
    ++stage_;
  }
  compute_forces(true);
  add_load_forces(time_, false);
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
  loop_start_ = std::chrono::steady_clock::now();
  loop_start_step_ = step_;
  output_seconds_at_loop_start_ = summary_.output_seconds;  // the first frame is not the loop's
  last_progress_ = loop_start_;
}

void Simulation::start_stage() {
  settle_kick();  // with the force and time step it was deferred with
  const Stage& st = scene_.stages[stage_];
  if (st.kind == StageKind::QuasiStatic) {
    run_quasistatic(st);
    return;
  }
  if (st.kind == StageKind::Release) {
    run_release(st);
    return;
  }
  dt_ = p_->stages.dt[stage_];
  damping_ = st.damping;
  boundaries_.start_stage(st);
}

std::int64_t Simulation::advance(std::int64_t n) {
  std::int64_t taken = 0;
  while (stage_ < scene_.stages.size() && !cadence_.stopped()) {
    if (scene_.stages[stage_].kind != StageKind::Dynamic) {
      // A later stage that takes no time: run it, and restart the energy balance after a
      // quasi-static one (it removes kinetic energy by construction).
      start_stage();
      ++stage_;
      compute_forces(true);
      add_load_forces(time_, false);
      write_series_row();
      if (scene_.stages[stage_ - 1].kind == StageKind::QuasiStatic)
        summary_.initial_total_energy = summary_.final_energy.total();
      continue;
    }
    if (!stage_started_) {
      start_stage();
      stage_started_ = true;
    }
    if (stage_step_ >= p_->stages.steps[stage_]) {
      ++stage_;
      stage_step_ = 0;
      stage_started_ = false;
      continue;
    }
    if (taken >= n) break;
    const bool series = (step_ + 1) % scene_.output.series_every == 0 || step_ + 1 == total_steps_;
    // A frame's step is an energy call too: the bond loop then writes the energy density.
    const bool frame_next = output_.frame_due(step_ + 1);
    step(series || frame_next, true);
    ++stage_step_;
    ++taken;
    const bool frame = output_.frame_due(step_);
    // Nothing is written before the state is checked: no non-finite value reaches a file.
    // (Each reader of the velocity applies a deferred kick first: settle_kick().)
    if (series || frame || step_ % kCheckEvery == 0 || step_ == total_steps_) check_health(step_, time_);
    if (series) write_series_row();
    if (frame) write_frame();
    if (cadence_.due(step_, step_ % kCheckEvery == 0 || step_ == total_steps_)) write_checkpoint();
  }
  settle_kick();  // v(t) whole when the call returns
  return taken;
}

void Simulation::run_release(const Stage& stage) {
  // Break every intact bond crossing the named cracks in the current (e.g. preloaded) state; its
  // current energy becomes dissipated energy, so the energy balance continues exactly.
  std::vector<const Crack*> cracks;
  for (const std::string& name : stage.cracks)
    for (const Crack& c : scene_.cracks)
      if (c.name == name) cracks.push_back(&c);
  state_.halo_begin();
  state_.halo_end();
  LocalArray u(state_.displacement());
  std::int64_t released = 0;
  double energy = 0;
  const BondView view = forces_.bond_view();
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const BondLaw& law = forces_.laws()[domain_.body[i]];
    const double* Xi = &domain_.X[3 * static_cast<std::size_t>(i)];
    for (std::int64_t b = domain_.bonds.offsets[i]; b < domain_.bonds.offsets[i + 1]; ++b) {
      if (domain_.bonds.broken[b]) continue;
      const std::int32_t j = domain_.bonds.neighbor[b];
      const double* Xj = &domain_.X[3 * static_cast<std::size_t>(j)];
      bool cut = false;
      for (const Crack* c : cracks) cut = cut || crosses(Xi, Xj, *c);
      if (!cut) continue;
      double y2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double e = Xj[c] - Xi[c] + u.data()[3 * j + c] - u.data()[3 * i + c];
        y2 += e * e;
      }
      energy += 0.5 * domain_.volume[i] * view.measure(i, b) * law.energy(view.xi2(i, b), y2);  // eq. (5), one end
      domain_.bonds.broken[b] = 1;
      domain_.bonds.row_broken[i] = 1;
      ++released;
    }
  }
  forces_.flags_changed();
  ledger_.bonds.dissipated += energy;
  ledger_.bonds.newly_broken += released;
  long long global = 0, local = released;
  MPI_Allreduce(&local, &global, 1, MPI_LONG_LONG, MPI_SUM, comm_);
  summary_.precrack_bonds += global / 2;
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] release '%s': %lld bonds broken\n", stage.name.c_str(), global / 2);
    std::fflush(stdout);
  }
  if (global == 0)
    throw InputError(stage.where.str() + ": stages." + stage.name + ".cracks: no intact bond crosses the named cracks");
}

std::unique_ptr<QuasiStaticLoader> Simulation::make_loader(const Stage& stage) {
  std::vector<PetscInt> d_nnz(domain_.owned), o_nnz(domain_.owned);
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    PetscInt d = 1, o = 0;
    for (std::int64_t b = domain_.bonds.offsets[i]; b < domain_.bonds.offsets[i + 1]; ++b)
      (domain_.bonds.neighbor[b] < domain_.owned ? d : o) += 1;
    d_nnz[i] = d;
    o_nnz[i] = o;
  }
  double local[2] = {forces_.reference_stiffness_sum(), double(domain_.owned)}, global[2];
  MPI_Allreduce(local, global, 2, MPI_DOUBLE, MPI_SUM, comm_);
  double spacing = INFINITY;
  for (const Body& b : scene_.bodies) spacing = std::min(spacing, b.spacing);
  return std::make_unique<QuasiStaticLoader>(comm_, domain_.owned, d_nnz, o_nnz, global[0] / std::max(global[1], 1.0),
                                             spacing, stage);
}

void Simulation::run_quasistatic(const Stage& stage) {
  const std::size_t n = 3 * static_cast<std::size_t>(domain_.owned);
  std::vector<std::uint8_t> constrained(n, 0);
  std::vector<double> increment(n, 0.0);
  boundaries_.quasistatic_targets(stage, domain_, constrained, increment);
  // Flat membranes under in-plane load have no out-of-plane stiffness at the flat state.
  if (stage.in_plane)
    for (std::int32_t i = 0; i < domain_.owned; ++i)
      if (scene_.bodies[domain_.body[i]].kind == BodyKind::Membrane) constrained[3 * static_cast<std::size_t>(i) + 2] = 1;
  const EnergyRow before = energies();
  if (step_ == 0 && summary_.quasistatic.empty()) summary_.run_initial_total_energy = before.total();
  std::unique_ptr<QuasiStaticLoader> loader = make_loader(stage);
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] quasistatic '%s': %ld initial load steps\n", stage.name.c_str(), stage.load_steps);
    std::fflush(stdout);
  }
  QuasiStaticStats stats = loader->run(*this, constrained, increment, !options_.quiet);
  ledger_.external_work += stats.external_work;
  // Equilibrium: at rest.
  PERI_PETSC(VecSet(state_.velocity(), 0.0));
  const EnergyRow after = energies();
  double work = 0, local = stats.external_work;
  MPI_Allreduce(&local, &work, 1, MPI_DOUBLE, MPI_SUM, comm_);
  stats.external_work = work;
  const double stored = (after.strain - before.strain) + (after.dissipated - before.dissipated) - before.kinetic;
  summary_.quasistatic.push_back({stage.name, stats});
  summary_.quasistatic_work_error.push_back(std::fabs(work - stored) / std::max(std::fabs(work), 1e-300));
  // Work the supports did that the body neither holds nor dissipated: bonds that break between
  // two equilibria (a preload that tears the sheet) release energy no stage follows. The explicit
  // part's balance restarts after this stage and would not show it; run_energy_balance_error does.
  const double tolerance = scene_.stability.energy_error;
  if (rank_ == 0 && tolerance > 0 && !(summary_.quasistatic_work_error.back() <= tolerance))
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

void Simulation::set_displacement(const double* u_owned) {
  double* u;
  PERI_PETSC(VecGetArray(state_.displacement(), &u));
  std::copy(u_owned, u_owned + 3 * static_cast<std::size_t>(domain_.owned), u);
  PERI_PETSC(VecRestoreArray(state_.displacement(), &u));
  forces_.displacement_changed();
  state_.halo_begin();
  state_.halo_end();
}

void Simulation::get_displacement(double* u_owned) {
  const double* u;
  PERI_PETSC(VecGetArrayRead(state_.displacement(), &u));
  std::copy(u, u + 3 * static_cast<std::size_t>(domain_.owned), u_owned);
  PERI_PETSC(VecRestoreArrayRead(state_.displacement(), &u));
}

void Simulation::internal_force(double* f_owned) {
  compute_forces(false, true);
  for (std::int32_t i = 0; i < domain_.owned; ++i)
    for (int c = 0; c < 3; ++c) f_owned[3 * i + c] = forces_.force()[3 * i + c] * domain_.volume[i];
}

void Simulation::add_tangent(Mat J) { forces_.add_tangent(J); }

std::int64_t Simulation::break_bonds() {
  const std::int64_t before = ledger_.bonds.newly_broken;
  compute_forces(false);
  long long local = ledger_.bonds.newly_broken - before, global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_LONG_LONG, MPI_SUM, comm_);
  return global / 2;
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
  double times[4] = {summary_.step_seconds, summary_.output_seconds, summary_.wall_seconds,
                     summary_.crack_tip_seconds}, tmax[4];
  MPI_Allreduce(times, tmax, 4, MPI_DOUBLE, MPI_MAX, comm_);
  summary_.crack_tip_seconds = tmax[3];
  summary_.step_seconds = tmax[0];
  summary_.output_seconds = tmax[1];
  summary_.wall_seconds = tmax[2];
  mark_memory(summary_, "end", comm_);
  output_.write_summary(summary_.to_json());
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
  const double* u;
  PERI_PETSC(VecGetArrayRead(state_.displacement(), &u));
  std::vector<double> x(3 * static_cast<std::size_t>(domain_.owned));
  for (std::size_t a = 0; a < x.size(); ++a) x[a] = domain_.X[a] + u[a];
  PERI_PETSC(VecRestoreArrayRead(state_.displacement(), &u));
  return gather_natural(x.data(), 3);
}

std::vector<double> Simulation::natural_velocities() {
  settle_kick();
  const double* v;
  PERI_PETSC(VecGetArrayRead(state_.velocity(), &v));
  std::vector<double> copy(v, v + 3 * static_cast<std::size_t>(domain_.owned));
  PERI_PETSC(VecRestoreArrayRead(state_.velocity(), &v));
  return gather_natural(copy.data(), 3);
}

std::vector<double> Simulation::natural_damage() {
  return gather_natural(forces_.damage(), 1);
}

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

std::array<double, 6> Simulation::momentum() {
  const VecArrayRead u(state_.displacement()), v(state_.velocity());
  return peri::momentum(domain_.X.data(), u.data(), v.data(), mass_, comm_);
}

}  // namespace peri

// ------------------------------------------------------------------------------------------------
// Checkpoints and restart

namespace peri {

void Simulation::add_checkpoint_extra(std::string name, std::function<std::vector<double>()> save,
                                      std::function<void(const std::vector<double>*)> restore) {
  extras_.add(std::move(name), std::move(save), std::move(restore));
}

Checkpoint Simulation::make_checkpoint() {
  return peri::make_checkpoint(scene_, domain_, state_, ledger_, {step_, time_, stage_, stage_step_}, summary_, extras_,
                               comm_);
}

void Simulation::write_checkpoint() {
  settle_kick();
  PetscLogEventBegin(events().output, 0, 0, 0, 0);
  const auto t0 = std::chrono::steady_clock::now();
  store_checkpoint(checkpoint_path(), make_checkpoint(), comm_);
  cadence_.written(step_);
  summary_.output_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  PetscLogEventEnd(events().output, 0, 0, 0, 0);
}

void Simulation::restore(const Checkpoint& c) {
  restore_state(c, domain_, state_, ledger_, comm_);
  forces_.flags_changed();
  restore_summary(c, scene_, summary_);
  step_ = c.step;
  time_ = c.time;
  stage_ = static_cast<std::size_t>(c.stage);
  stage_step_ = c.stage_step;
  summary_.initial_total_energy = c.initial_total_energy;
  extras_.restore(c);

  // Forces at the restored positions, computed as the uninterrupted run did at the end of this
  // step; every bond past its critical stretch there is already broken, so none breaks now.
  compute_forces(true);
  add_load_forces(time_, false);
  summary_.final_energy = reduce_energies(ledger_.bonds.strain_energy);
  output_.skip_frames_through(step_);
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] resumed at step %lld/%lld (t = %.6g s) from a checkpoint written on %d rank%s\n",
                static_cast<long long>(step_), static_cast<long long>(total_steps_), time_, c.ranks,
                c.ranks > 1 ? "s" : "");
    std::fflush(stdout);
  }
  loop_start_ = std::chrono::steady_clock::now();
  loop_start_step_ = step_;  // the steps before the checkpoint were timed by the run that took them
  output_seconds_at_loop_start_ = summary_.output_seconds;  // the first frame is not the loop's
  last_progress_ = loop_start_;
}

}  // namespace peri
