#include "peri/stages/explicit.hpp"

#include <cmath>
#include <optional>
#include <type_traits>

#include "peri/stages/events.hpp"

namespace peri {

Verlet::Verlet(Problem& p, EnergyLedger& ledger, HealthCheck& health)
    : p_(p),
      domain_(p.domain),
      state_(*p.state),
      forces_(*p.forces),
      boundaries_(*p.boundaries),
      mass_(p.mass),
      inv_density_(p.inv_density),
      ledger_(ledger),
      health_(health) {
  // The update's streams: runs of owned nodes of one body without a boundary (at most 64 nodes,
  // so that a run failing the quick motion check is rechecked cheaply), and the others.
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    if (boundaries_.of(i) >= 0) continue;
    FreeRun* last = free_runs_.empty() ? nullptr : &free_runs_.back();
    if (last && last->end == i && last->body == domain_.body[i] && i - last->begin < 64)
      last->end = i + 1;
    else
      free_runs_.push_back({i, i + 1, domain_.body[i]});
  }
}

void Verlet::start(const Stage& stage, double dt) {
  settle_kick();  // with the force and time step it was deferred with
  dt_ = dt;
  damping_ = stage.damping;
  boundaries_.start_stage(stage);
}

void Verlet::forces_at(double t) {
  forces_.set_time(t);
  forces_.compute(true, false, ledger_.bonds);
  add_load_forces(t, false);
}

void Verlet::settle_kick() {
  if (!kick_pending_) return;
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  {
    const VecArray v(state_.velocity());
    second_kick_free(v.data(), dt_);
  }
  kick_pending_ = false;
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
}

void Verlet::second_kick_free(double* v, double dt) const {
  for (const FreeRun& r : free_runs_) {  // kick with damp_new = 1, one stream per run
    const double ir = inv_density_[r.begin];
    const std::size_t k0 = 3 * static_cast<std::size_t>(r.begin), n = 3 * static_cast<std::size_t>(r.end - r.begin);
    double* __restrict vr = v + k0;
    const double* __restrict fr = forces_.force() + k0;
    for (std::size_t k = 0; k < n; ++k) vr[k] = vr[k] + 0.5 * dt * fr[k] * ir;
  }
}

template <class Row, class Run>
void Verlet::in_node_order(Row row, Run run) const {
  const std::vector<std::int32_t>& rows = boundaries_.rows();  // (ascending)
  std::size_t b = 0;
  for (const FreeRun& r : free_runs_) {
    for (; b < rows.size() && rows[b] < r.begin; ++b) row(rows[b]);
    run(r);
  }
  for (; b < rows.size(); ++b) row(rows[b]);
}

double Verlet::step(double time, bool with_energy, bool defer_kick) {
  const double dt = dt_, t0 = time, t1 = time + dt;
  // Mass-proportional damping alpha (force -rho alpha v), integrated semi-implicitly:
  // v_half = (1 - alpha dt/2) v + dt/2 a(t),  v(t+dt) = (v_half + dt/2 a(t+dt)) / (1 + alpha dt/2).
  const double damp_old = 1.0 - 0.5 * damping_ * dt, damp_new = 1.0 / (1.0 + 0.5 * damping_ * dt);
  const double* force = forces_.force();
  const double* viscous_force = forces_.viscous();
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  // The arrays of u and v for the first half; of v again for the second (the forces between read
  // the displacement's local form).
  std::optional<VecArray> u_array(std::in_place, state_.displacement()), v_array(std::in_place, state_.velocity());
  double* u = u_array->data();
  double* v = v_array->data();
  Boundaries& boundaries = boundaries_;
  double damped = 0;  // energy removed by damping: alpha m v.v dt, trapezoidal in time
  // Energy removed by bond dashpots: the kick by the dashpot force F_d over dt/2 changes the
  // kinetic energy by F_d . (v_before + v_after)/2 dt/2 (exactly the share of F_d in
  // m (v_after^2 - v_before^2)/2), booked as dissipated with the opposite sign.
  double viscous = 0;
  // The dashpots' share of the internal force at prescribed components does work -F_d du along
  // the prescribed path, which reaction_work books as the reaction's (external) work against it:
  // it is dissipated too (Boundaries::dashpot_work).
  double viscous_prescribed = 0;
  const bool kelvin = viscous_force != nullptr;  // bond dashpots (lattice or peridynamic)
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
        moved2 += boundaries.drift(i, bi, c, k, t0, t1, u, v, force, viscous_force);
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
    // Damping or bond dashpots: their work is one sum each in node order (so that its bits do
    // not depend on how the nodes are walked), so the free runs and the boundary rows go merged in
    // node order; a run's nodes with kick_drift's operations but no per-node boundary test, the
    // sums in registers (through the lambda's references they went to memory and back for every
    // component: the update of the blunt tool's scene with dashpots ran at half this speed), the
    // motion checked where it is exceeded.
    in_node_order([&](std::int32_t i) { kick_drift_node(i); },
                  [&](const FreeRun& r) {
                    const double limit2 = health_.motion_limit2(r.body);
                    double damped_sum = damped, viscous_sum = viscous;
                    for (std::int32_t i = r.begin; i < r.end; ++i) {
                      const std::size_t k0 = 3 * static_cast<std::size_t>(i);
                      double moved2 = 0;
                      for (std::size_t k = k0; k < k0 + 3; ++k) {
                        if (damped_run) damped_sum += mass_[i] * v[k] * v[k];
                        const double before = v[k];
                        v[k] = damp_old * v[k] + 0.5 * dt * force[k] * inv_density_[i];
                        if (kelvin) viscous_sum -= viscous_force[k] * domain_.volume[i] * 0.5 * (before + v[k]);
                        u[k] += dt * v[k];
                        moved2 += dt * dt * v[k] * v[k];
                      }
                      if (!(moved2 <= limit2)) check_motion(i, moved2);
                    }
                    damped = damped_sum;
                    viscous = viscous_sum;
                  });
  }
  if (unstable_row >= 0) health_.note_unstable(domain_.natural[unstable_row], std::sqrt(unstable_moved2));
  u_array.reset();
  v_array.reset();
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
  // Forces at x(t + dt); bond dashpots see the half-step velocity v(t + dt/2) (README
  // "Kelvin dissipation").
  forces_.set_time(t1);
  forces_.compute(with_energy, false, ledger_.bonds);
  add_load_forces(t1, true);
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  v_array.emplace(state_.velocity());
  v = v_array->data();
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
        if (kelvin) viscous_prescribed -= boundaries.dashpot_work(i, c, k, viscous_force, domain_.volume[i]);
      } else {
        kick(i, k);
      }
    }
  };
  if (streaming) {
    // The free nodes' second half kick: now, or (defer_kick, no tool reading v below) in the next
    // step's first pass, which then reads and writes velocity once for both kicks.
    if (defer_kick && !p_.tools) {
      kick_pending_ = true;
    } else {
      second_kick_free(v, dt);
    }
    for (std::int32_t i : boundaries.rows()) kick_node(i);
  } else {  // damping or bond dashpots, as in the first pass (kick's operations)
    in_node_order([&](std::int32_t i) { kick_node(i); },
                  [&](const FreeRun& r) {
                    double damped_sum = damped, viscous_sum = viscous;
                    for (std::int32_t i = r.begin; i < r.end; ++i)
                      for (std::size_t k = 3 * static_cast<std::size_t>(i); k < 3 * static_cast<std::size_t>(i) + 3; ++k) {
                        const double before = v[k];
                        v[k] = damp_new * (v[k] + 0.5 * dt * force[k] * inv_density_[i]);
                        if (kelvin) viscous_sum -= viscous_force[k] * domain_.volume[i] * 0.5 * (before + v[k]);
                        if (damped_run) damped_sum += mass_[i] * v[k] * v[k];
                      }
                    damped = damped_sum;
                    viscous = viscous_sum;
                  });
  }
  // The loads' work that needs the velocity just computed (friction).
  for (const auto& load : p_.loads) load->end_step(dt, v, ledger_);
  v_array.reset();
  if (damping_ > 0) ledger_.damping_work += 0.5 * damping_ * dt * damped;
  if (kelvin) {
    ledger_.damping_work += 0.5 * dt * viscous;
    ledger_.damping_work += viscous_prescribed;  // (a sum of its own: 0 where no boundary moves)
  }
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
  return t1;
}

void Verlet::add_load_forces(double t, bool book) {
  if (p_.loads.empty()) return;
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  const LoadTarget target{forces_.positions(), forces_.position_stride(), forces_.force(), dt_};
  for (const auto& load : p_.loads) load->add_forces(t, target, book, ledger_);
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
}

}  // namespace peri
