// Loads that act through forces on the nodes (tools, pressure): each adds its force densities at
// the current positions after the bond forces, and books the work it does in the energy ledger.
// A scene's loads are a list evaluated in order (one virtual call per load per evaluation).
// Prescribed motion (boundaries.hpp) is not a force and is not one of them.
#pragma once
#include <cstdint>

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
};

}  // namespace peri
