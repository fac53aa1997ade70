// Rigid tools (Silling & Bobaru 7.4 and 7.2: a blunt cylinder pushed through a membrane, a
// fragment striking a balloon): a penalty force pushes the nodes inside a tool out, with Coulomb
// friction (contact.hpp). A tool's motion is prescribed (constant velocity), so it does work on
// the body (its force times its velocity, trapezoidal over the step); or, with a mass, it is a
// free rigid body moved by the reaction of its contact forces (velocity Verlet in step with the
// nodes), and the kinetic energy it loses is the work it does on the body (booked as its impulse
// times its mean velocity, which a heavy tool's kinetic energies would cancel). Friction dissipates
// (booked once the step's end velocity is known); the penalty's energy counts as strain energy.
#pragma once
#include <mpi.h>

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "peri/loads/contact.hpp"
#include "peri/loads/load.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"
#include "peri/state/state.hpp"

namespace peri {

class Tools final : public Load {
 public:
  /// The scene's tools, with a penalty stiffness per unit mass of `stiffness` times the stiffest
  /// node's bond stiffness (2 rho / dt_bound^2 at the stable bound dt_bound of the bodies), so
  /// that the bound with contact is at least dt_bound / sqrt(1 + stiffness) (stable_step).
  /// inv_density: per owned node. Velocities are read from `state` at each evaluation.
  Tools(const Scene& scene, double dt_bound, const State& state, const Domain& domain,
        const std::vector<double>& inv_density, MPI_Comm comm);
  bool empty() const { return tools_.empty(); }
  std::size_t size() const { return tools_.size(); }
  /// Tool k's velocity and its axis (sphere: centre) position at time t [m/s, m].
  std::array<double, 3> velocity(std::size_t k) const {
    return {tools_[k].velocity[0], tools_[k].velocity[1], tools_[k].velocity[2]};
  }
  std::array<double, 3> position(std::size_t k, double t) const {
    const RigidTool& c = tools_[k];
    return {c.center[0] + c.velocity[0] * (t - c.t0), c.center[1] + c.velocity[1] * (t - c.t0),
            c.center[2] + c.velocity[2] * (t - c.t0)};
  }
  /// Whether some tool is a free rigid body (its position and velocity are part of a checkpoint).
  bool free() const;
  /// Whether some tool has friction (its forces are then part of a checkpoint: save_friction).
  bool friction() const;
  /// The stable step of the bodies with the tools' penalty: dt_bound / sqrt(1 + largest stiffness).
  double stable_step(double dt_bound) const;

  /// With `book` (a step's evaluation at t = t_n + dt), a free tool first takes its half kick and
  /// drift to t, then, after the contact, its second half kick: velocity Verlet as the nodes'.
  void add_forces(double t, const LoadTarget& target, bool book, EnergyLedger& ledger) override;
  /// Friction: the force found at t + dt acts between v(t + dt/2) and v(t + 3dt/2), whose mean is
  /// the velocity at the step's end.
  void end_step(double dt, const double* v, EnergyLedger& ledger) override;

  /// Series columns per tool: its axis (a sphere: centre) position, a free tool's velocity, and
  /// the total force on the nodes (the reaction on the tool is its negative). Comma-separated.
  std::string series_columns() const;
  /// Their values at `time` (comma-separated; with `leading_comma` one before the first).
  /// Collective.
  std::string series_values(double time, bool leading_comma) const;

  /// The first tool (scene order) that touched a node at the last evaluation, on any rank; ""
  /// when none did. Collective.
  std::string touching() const;

  /// The friction forces of the last evaluation, (natural id, tool, force) per node, gathered on
  /// rank 0 (checkpoints). Collective.
  std::vector<double> save_friction() const;
  /// A resumed run's first evaluation applies the friction forces the interrupted run computed
  /// from its half-step velocities, which a checkpoint does not hold (nullptr: none stored).
  void restore_friction(const std::vector<double>* flat);
  /// The free tools' positions and velocities (6 values each, scene order), as every rank holds
  /// them; restore_free sets them (their accelerations follow from the next evaluation).
  std::vector<double> save_free() const;
  void restore_free(const std::vector<double>* flat);

 private:
  const State& state_;
  const Domain& domain_;
  const std::vector<double>& inv_density_;
  MPI_Comm comm_;
  /// The reaction on free tool k (minus its contact forces on the nodes), summed over the nodes in
  /// natural order whatever the ranks, so its motion is the same bits on any number of ranks.
  /// Collective.
  void reaction(std::size_t k, double out[3]) const;

  std::vector<RigidTool> tools_;           // stiffness per unit mass
  std::vector<double> mass_;               // per tool: > 0 free [kg], 0 prescribed
  std::vector<std::string> where_;         // per tool: its place in the scene file
  std::vector<std::array<double, 3>> accel_;  // per free tool: acceleration at the last evaluation
  std::vector<std::array<double, 3>> reaction_;  // per free tool: the reaction giving accel_ [N]
  std::vector<std::string> names_;
  std::vector<ContactTally> contact_;      // per tool: this rank's contact at the last evaluation
  std::optional<std::vector<std::vector<NodeFriction>>> resumed_friction_;  // per tool, from a checkpoint
  double stiffest_ = 0;                    // largest relative stiffness
};

}  // namespace peri
