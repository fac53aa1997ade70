// Health of the explicit integration: the checks that stop a run which has gone wrong before
// anything non-finite reaches a file. The Verlet update notes a node that moved more than
// stability.motion_per_step spacings in one step (no stable step does that); check() then stops
// the run with RuntimeFailure naming it, or a node whose displacement or velocity is no longer
// finite; check_energy() stops a run whose energy balance error grows beyond
// stability.energy_error. The messages name the likely cause and the law's behaviour near its
// stable bound.
#pragma once
#include <mpi.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "peri/diagnostics/energies.hpp"
#include "peri/models/law.hpp"
#include "peri/models/long_range.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

class HealthCheck {
 public:
  /// `laws`: per body (empty for lattice bodies), for the messages.
  HealthCheck(const Scene& scene, const Domain& domain, const std::vector<BondLaw>& laws, MPI_Comm comm);

  /// (stability.motion_per_step x the body's spacing)^2, or infinity when the check is off.
  double motion_limit2(int body) const { return motion_limit2_[body]; }
  /// Natural id of the node noted as moving too far (the first noted), or -1.
  std::int64_t unstable_node() const { return unstable_node_; }
  /// The Verlet update found node `natural` moved `motion` [m] in one step (kept if the first).
  void note_unstable(std::int64_t natural, double motion) {
    if (unstable_node_ >= 0) return;
    unstable_node_ = natural;
    unstable_motion_ = motion;
  }

  /// RuntimeFailure if a node moved too far in a step since the run began, or an owned node's
  /// displacement or velocity (u, v: 3 per owned node) is not finite. Collective.
  void check(std::int64_t step, double time, const double* u, const double* v, double dt, double dt_stable) const;
  /// RuntimeFailure if `error`, the balance error of `row` against the total `e0`, has exceeded
  /// stability.energy_error (when that is set) at every check for kEnergyErrorSteps steps or more.
  /// A transient is let through: a tool's first touch of a body at rest books the penalty's onset
  /// by the trapezoidal rule, up to about a node's kinetic energy at the tool's speed in one step,
  /// which before anything else has moved can be most of the balance (0.74 of it for one step in
  /// the blunt tool's scene with dashpots, 0.05 or less from the next step); an instability does
  /// not recover.
  /// `run_end`: the run's last series row, where an error above the tolerance stops the run
  /// however few steps it has lasted.
  void check_energy(const EnergyRow& row, double error, double e0, double dt, double dt_stable, bool run_end);
  static constexpr std::int64_t kEnergyErrorSteps = 10;
  /// The energy check's memory across a restart (a checkpoint extra): the first step of the
  /// current run of checks above the tolerance, or -1. `restore` takes a checkpoint's values
  /// (nullptr: the checkpoint has none, as those written before it was kept: -1).
  std::vector<double> save() const { return {static_cast<double>(energy_over_since_)}; }
  void restore(const std::vector<double>* saved);
  /// How the laws behave near the stable bound: of body `body`, or of every body (-1).
  std::string law_note(int body) const;
  int body_of(long long node) const;  // the body of a node (natural id); collective
  /// The long-range rules whose contact a step dt exceeds (PairContactStep::exceeded_by) with the
  /// bonds' bound dt_stable, as a likely cause; empty when none does.
  std::string contact_note(double dt, double dt_stable) const;
  /// With a crack-tip rule: its share in an energy balance error, for the message.
  std::string tip_advance_note() const;

 private:
  std::array<double, 3> reference_position(std::int64_t natural) const;  // of any node (collective)

  const Scene& scene_;
  const Domain& domain_;
  const std::vector<BondLaw>& laws_;
  MPI_Comm comm_;
  std::vector<double> motion_limit2_;  // per body
  std::vector<PairContactStep> contact_;  // of the long-range rules with a well
  std::int64_t unstable_node_ = -1;    // natural id of a node that moved too far in one step
  double unstable_motion_ = 0;
  std::int64_t energy_over_since_ = -1;  // the first step of the checks above the energy tolerance, -1: none
};

}  // namespace peri
