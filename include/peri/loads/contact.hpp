// Rigid tools in contact with the nodes (Silling & Bobaru 7.4: a blunt tool, a rigid cylinder,
// pushed edge-on through a membrane, with friction): the loop over a rank's nodes, with the
// contact law of models/laws/contact.hpp. Kernels only: no MPI, no PETSc.
#pragma once
#include <cstdint>
#include <vector>

namespace peri {

/// A rigid cylinder of infinite length, axis along z through (cx, cy) + (vx, vy) (t - t0); or, with
/// `sphere`, a rigid sphere about (cx, cy, cz) + (vx, vy, vz) (t - t0) (a fragment, example 7.2).
struct RigidTool {
  bool sphere = false;
  double radius = 0;
  double center[3] = {0, 0, 0};    ///< axis (cylinder: x, y) or centre at t = t0 [m]
  double velocity[3] = {0, 0, 0};  ///< [m/s] (cylinder: z component 0)
  double t0 = 0;                   ///< the time `center` is at [s] (a free tool's last move)
  double friction = 0;          ///< Coulomb coefficient mu
  /// Penalty stiffness per unit mass [1/s^2]: a node of density rho inside the cylinder by a
  /// depth p feels the normal force density rho * stiffness * p [N/m^3].
  double stiffness = 0;
};

using RigidCylinder = RigidTool;

/// Friction force density on one node [N/m^3].
struct NodeFriction {
  std::int32_t node;
  double force[3];
};

/// What the contact did on a set of nodes (sums over the nodes, forces times node volume).
struct ContactTally {
  double force[3] = {0, 0, 0};  ///< total force of the tool on the nodes [N]
  std::int64_t nodes = 0;       ///< nodes in contact
  double energy = 0;            ///< penalty energy: sum of volume * rho k p^2 / 2 [J]
  double mass = 0;              ///< mass of the nodes in contact: sum of rho volume [kg]
  std::vector<NodeFriction> friction;  ///< nodes with a friction force, and that force
  /// With `per_node` set before the call: each node in contact and its total contact force
  /// times its volume [N] (a free tool sums them in an order independent of the ranks).
  bool per_node = false;
  std::vector<NodeFriction> node_forces;
};

/// Adds the tool's contact force densities to `force` (stride 3) for nodes [0, n) at time t.
/// x: current positions (planes x, y, ... `x_stride` apart, as current_positions); v: velocities (stride 3, the half-step
/// velocities of velocity Verlet); volume and inv_density per node; dt the time step.
/// Normal: rho k p along the outward radial direction (p the depth inside the cylinder).
/// Friction (Coulomb, regularized for an explicit step): opposite to the velocity relative to
/// the tool's surface, tangential part t, with magnitude min(mu rho k p, rho |t| / (2 dt)), so that
/// a step never reverses the sliding direction (sticking is approached, not overshot). Appends
/// each friction force to tally.friction: its work is booked once the node's velocity at the end
/// of the step is known (friction_work).
/// With `given` (sorted by node), friction is not computed but taken from it (nodes not listed
/// get none): a run resumed from a checkpoint applies the friction forces the interrupted run
/// computed from its half-step velocities, which a checkpoint does not hold.
void cylinder_contact(const RigidCylinder& tool, double time, double dt, const double* x, std::int64_t x_stride,
                      const double* v, const double* volume, const double* inv_density, std::int32_t n,
                      double* force, ContactTally& tally, const std::vector<NodeFriction>* given = nullptr);

/// Work done on the nodes over one step of length dt by the friction forces of `tally`, with v the
/// velocities at the end of the step (the mean of the two half-step velocities the force acts
/// between, exactly, in velocity Verlet): sum over nodes of dt V f . (v - V_tool) (<= 0) [J].
double friction_work(const RigidCylinder& tool, const ContactTally& tally, double dt, const double* v,
                     const double* volume);

}  // namespace peri
