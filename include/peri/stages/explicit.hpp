// The explicit stage: velocity Verlet over the problem's state, with mass-proportional damping
// (semi-implicit), lattice dashpots, prescribed boundary motion (boundaries.hpp) and the loads'
// forces after the bonds'. Each step books the work that is not kinetic or strain energy in the
// ledger: damping, dashpots and friction as dissipated, the boundaries' reactions and the loads'
// work as external work. A node that moves more than the health check's limit in one step is
// noted there.
//
// The free nodes (no boundary) of a stage without damping or dashpots are updated as contiguous
// streams, and their second half kick may wait for the next step's first pass, which then reads
// and writes each velocity once for both kicks (defer_kick; settle_kick() applies a pending one,
// as every reader of the velocity does first).
#pragma once
#include <cstdint>
#include <vector>

#include "peri/diagnostics/energies.hpp"
#include "peri/diagnostics/health.hpp"
#include "peri/stages/problem.hpp"

namespace peri {

class Verlet {
 public:
  Verlet(Problem& p, EnergyLedger& ledger, HealthCheck& health);
  Verlet(const Verlet&) = delete;
  Verlet& operator=(const Verlet&) = delete;

  /// A dynamic stage begins: its time step, damping and boundary velocities.
  void start(const Stage& stage, double dt);
  double dt() const { return dt_; }
  /// One step from `time` to time + dt (returned): half kick and drift, forces at time + dt (the
  /// bonds', with energy densities when `with_energy`, then the loads'), second half kick (now,
  /// or deferred with `defer_kick`).
  double step(double time, bool with_energy, bool defer_kick);
  /// Applies a deferred second half kick: v(t) whole.
  void settle_kick();
  /// Forces at the current state and time t (the bonds' with energies, then the loads'), their
  /// work not booked: a stage's first evaluation, a resumed run's.
  void forces_at(double t);

 private:
  void second_kick_free(double* v, double dt) const;  // the free runs' second half kick
  /// row(i) for each boundary row and run(r) for each free run, in node order.
  template <class Row, class Run>
  void in_node_order(Row row, Run run) const;
  /// Adds the loads' forces at time t (after the bonds': positions current); with `book`, their
  /// work goes to the ledger.
  void add_load_forces(double t, bool book);

  Problem& p_;
  Domain& domain_;
  State& state_;
  Forces& forces_;
  Boundaries& boundaries_;
  const std::vector<double>& mass_;         // per owned node
  const std::vector<double>& inv_density_;  // per owned node
  EnergyLedger& ledger_;
  HealthCheck& health_;
  double dt_ = 0;       // the current stage's time step (0 before the first dynamic stage)
  double damping_ = 0;  // the current stage's viscous damping [1/s]
  struct FreeRun {      // owned nodes [begin, end) of one body, no boundary
    std::int32_t begin, end;
    int body;
  };
  std::vector<FreeRun> free_runs_;  // the update's streams (without damping or dashpots)
  bool kick_pending_ = false;       // the free runs' second half kick deferred (dt_, the force)
};

}  // namespace peri
