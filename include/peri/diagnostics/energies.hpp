// Energies and their balance: each rank's accounts of the energy that entered or left the bodies
// other than as kinetic and strain energy (bonds broken, damping, dashpots and friction, the work
// of boundaries, tools and pressure), the run's totals at a step (collective), and the balance
// error that the stability check and summary.json report.
#pragma once
#include <mpi.h>

#include <array>
#include <cstdint>
#include <vector>

#include "peri/kernels/forces.hpp"

namespace peri {

/// Series row: the run's energies at one step, as series.csv holds them.
struct EnergyRow {
  std::int64_t step = 0;
  double time = 0;
  double kinetic = 0, strain = 0, external_work = 0, dissipated = 0;
  std::int64_t broken_bonds = 0;  ///< bonds (not ordered pairs) broken so far
  double total() const { return kinetic + strain + dissipated - external_work; }
};

/// This rank's energy accounts, cumulative over the run. Checkpoints store them per rank, so that
/// a resumed run's sums continue bit for bit.
struct EnergyLedger {
  /// The bond loop's (and release stages'): energy dissipated by broken bonds and the ordered
  /// bonds broken so far; strain_energy: of the last force evaluation (plus the tools' penalty).
  BondTally bonds;
  double damping_work = 0;   ///< removed by damping, bond dashpots and friction [J]
  double external_work = 0;  ///< done on the bodies by boundaries, tools, pressure, supports [J]
};

/// The run's energies at (step, time): strain energy from each rank's `local_strain`, dissipated
/// energy, external work and broken bonds from each rank's ledger; `kinetic` is the run's (see
/// kinetic_energy). Collective.
EnergyRow reduce_energies(const EnergyLedger& mine, double local_strain, double kinetic, std::int64_t step,
                          double time, MPI_Comm comm);

/// Sum of m |v|^2 / 2 over the owned nodes of every rank (v: 3 per owned node). Collective.
double kinetic_energy(const double* v, const std::vector<double>& mass, MPI_Comm comm);

/// Total linear momentum and angular momentum about the origin of the owned nodes of every rank
/// at positions X + u (3 per owned node each). Collective.
std::array<double, 6> momentum(const double* X, const double* u, const double* v, const std::vector<double>& mass,
                               MPI_Comm comm);

/// The smallest energy the balance is judged against: the energy of a uniform strain of 1e-10
/// in every body, sum over nodes of m c^2 1e-20, with c^2 per body (`wave2`, indexed by `body`
/// of each owned node). A body at rest holds only round-off, ~1e-21 J. Collective.
double energy_floor(const std::vector<double>& mass, const int* body, const std::vector<double>& wave2, MPI_Comm comm);

/// |total - e0| over the run's energy scale: the largest of |kinetic| + |strain| + |dissipated|,
/// |external work|, |e0| and `floor`.
double energy_balance_error(const EnergyRow& row, double e0, double floor);

}  // namespace peri
