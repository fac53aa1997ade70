// Loads that act through forces on the nodes (tools, pressure): each adds its force densities at
// the current positions after the bond forces, and books the work it does in the energy ledger.
// A scene's loads are a list evaluated in order (one virtual call per load per evaluation).
// Prescribed motion (boundaries.hpp) is not a force and is not one of them.
#pragma once
#include <cstdint>
#include <functional>
#include <string>

#include "peri/diagnostics/energies.hpp"

namespace peri {

/// The configuration a load acts on at one force evaluation, and where its forces go.
struct LoadTarget {
  const double* x = nullptr;   ///< current positions of the local nodes, planes x, y, z `x_stride` apart
  std::int64_t x_stride = 0;
  double* force = nullptr;     ///< force densities [N/m^3], 3 per owned node (the bond forces' sum)
  double dt = 0;               ///< the current time step [s]
};

class Load {
 public:
  virtual ~Load() = default;
  /// Adds the load's force densities at time t to target.force. With `book`, the work it did
  /// since the last booked evaluation goes to ledger.external_work (a stage's first evaluation
  /// books none).
  virtual void add_forces(double t, const LoadTarget& target, bool book, EnergyLedger& ledger) = 0;
  /// The end of a step of length dt, `v` the velocities at its end (3 per owned node): work that
  /// needs them (friction) goes to the ledger.
  virtual void end_step(double /*dt*/, const double* /*v*/, EnergyLedger& /*ledger*/) {}

  // Quasi-static stages. A load that acts there says so; its forces join the equilibrium's
  // residual and its stiffness the tangent. The others (tools) act in dynamic stages only.
  virtual bool quasistatic() const { return false; }
  /// The start of a quasi-static stage at time t: the load's value now is where its level 0 is.
  virtual void begin_quasistatic(double /*t*/) {}
  /// Quasi-static load stepping: the load at `level` in [0, 1] of the way from its value at the
  /// stage's start to its full value, whatever the time; once at level 1 it stays full after.
  virtual void set_quasistatic_level(double /*level*/) {}
  /// The load at quasi-static `level` in words, for messages ("the pressure in body 'balloon'
  /// 6120521 Pa", 7 digits); empty for a load that has none. The same on every rank.
  virtual std::string quasistatic_text(double /*level*/) const { return {}; }
  /// 3x3 blocks K_ij = -dF_i/dx_j (row-major, F in N) of the load's stiffness at the current
  /// positions, row i an owned node, column j a local node.
  using StiffnessSink = std::function<void(std::int32_t i, std::int32_t j, const double* block)>;
  virtual void add_stiffness(const LoadTarget& /*target*/, const StiffnessSink& /*sink*/) const {}
};

}  // namespace peri
