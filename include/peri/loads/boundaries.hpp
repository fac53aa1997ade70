// Prescribed motion (scene boundaries): the nodes of each boundary's region (a later boundary
// wins where regions overlap) follow its velocity in the components it names, ramped up from
// rest over its ramp time; a dynamic stage may set other velocities (boundary_velocity), a
// quasi-static stage displaces them (displacements, displacement_gradient). The reaction that
// enforces the motion does work on the body, booked by the explicit update (reaction_work).
//
// The per-node calls (drift, reaction_work) are inline: the explicit update makes them for every
// prescribed component of every step.
#pragma once
#include <algorithm>
#include <cstdint>
#include <vector>

#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

/// Velocity ramp: v(t) = v_target ramp(t); its integral gives exact prescribed displacements.
inline double ramp(double t, double tr) { return tr > 0 ? std::min(t / tr, 1.0) : 1.0; }
inline double ramp_integral(double t, double tr) {
  if (tr <= 0) return t;
  return t < tr ? 0.5 * t * t / tr : t - 0.5 * tr;
}

class Boundaries {
 public:
  /// `node_boundary`: per owned node, the index of its boundary in scene.boundaries, or -1.
  Boundaries(const Scene& scene, std::vector<int> node_boundary);

  /// Boundary of owned node i, or -1.
  int of(std::int32_t i) const { return boundary_[i]; }
  /// The owned nodes with a boundary, ascending.
  const std::vector<std::int32_t>& rows() const { return rows_; }
  /// Whether boundary b prescribes component c.
  bool prescribes(int b, int c) const { return scene_.boundaries[b].components[c]; }

  /// The initial velocity of the prescribed components (v: 3 per owned node, t = 0).
  void apply_initial(double* v) const;
  /// A dynamic stage begins: the boundaries' velocities and ramps, with the stage's
  /// boundary_velocity (at once, no ramp) where it names them.
  void start_stage(const Stage& stage);
  /// Quasi-static stage: marks the prescribed components of the owned nodes (constrained = 1)
  /// and sets their increments, the stage's displacement of their boundary plus its
  /// displacement gradient times (X - initial.center). Both arrays: 3 per owned node.
  void quasistatic_targets(const Stage& stage, const Domain& domain, std::vector<std::uint8_t>& constrained,
                           std::vector<double>& increment) const;

  /// Prescribed component c (k = 3 i + c) of node i, boundary b, over a step from t0 to t1:
  /// keeps its velocity and force at the step's start for reaction_work (and the bond dashpots'
  /// share of that force, `viscous`, for dashpot_work; null without dashpots), moves u[k] by the
  /// ramped velocity's integral and sets v[k] to the velocity at t1. Returns the motion squared.
  double drift(std::int32_t i, int b, int c, std::size_t k, double t0, double t1, double* u, double* v,
               const double* force, const double* viscous) {
    const Active& a = active_[b];
    const std::size_t kb = 3 * static_cast<std::size_t>(slot_[i]) + c;
    v_old_[kb] = v[k];
    du_[kb] = a.velocity[c] * (ramp_integral(t1, a.ramp_time) - ramp_integral(t0, a.ramp_time));
    prev_force_[kb] = force[k];
    if (viscous) prev_viscous_[kb] = viscous[k];
    u[k] += du_[kb];
    v[k] = a.velocity[c] * ramp(t1, a.ramp_time);
    return du_[kb] * du_[kb];
  }
  /// Work of the reaction that enforced component c (k = 3 i + c) over the step drift() began:
  /// the change of the node's kinetic energy minus the work of the internal force (trapezoidal:
  /// the mean of `force` at the step's end and at its start, density times `volume`) along the
  /// prescribed path. v: at the step's end.
  double reaction_work(std::int32_t i, int c, std::size_t k, const double* v, const double* force, double volume,
                       double mass) const {
    const std::size_t kb = 3 * static_cast<std::size_t>(slot_[i]) + c;
    const double fi = 0.5 * (force[k] + prev_force_[kb]) * volume;
    return 0.5 * mass * (v[k] * v[k] - v_old_[kb] * v_old_[kb]) - fi * du_[kb];
  }
  /// Work of the bond dashpots' force on prescribed component c over the step drift() began, by
  /// the same trapezoid as reaction_work (whose internal force includes it): F_d du =
  /// (F_d(t0) + F_d(t1))/2 volume du, with `viscous` F_d at the step's end. The reaction works
  /// against it, so it is external work, and the dashpots dissipate it: -F_d du is booked as
  /// dissipated. (A clamped node has du = 0.)
  double dashpot_work(std::int32_t i, int c, std::size_t k, const double* viscous, double volume) const {
    const std::size_t kb = 3 * static_cast<std::size_t>(slot_[i]) + c;
    return 0.5 * (viscous[k] + prev_viscous_[kb]) * volume * du_[kb];
  }

 private:
  struct Active {
    Vec3 velocity{0, 0, 0};
    double ramp_time = 0;
  };
  const Scene& scene_;
  std::vector<int> boundary_;         // per owned node: boundary index or -1
  std::vector<std::int32_t> rows_;    // owned nodes with a boundary
  std::vector<std::int32_t> slot_;    // per owned node: its slot among rows_, or -1
  std::vector<Active> active_;        // per boundary, in the current stage
  // Per slot, 3 components each: the step's increment, and velocity, force and the force's
  // dashpot share at its start.
  std::vector<double> du_, v_old_, prev_force_, prev_viscous_;
};

}  // namespace peri
