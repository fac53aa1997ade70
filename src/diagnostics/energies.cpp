#include "peri/diagnostics/energies.hpp"

#include <algorithm>
#include <cmath>

namespace peri {

EnergyRow reduce_energies(const EnergyLedger& mine, double local_strain, double kinetic, std::int64_t step,
                          double time, MPI_Comm comm) {
  double local[4] = {local_strain, mine.bonds.dissipated + mine.damping_work, mine.external_work,
                     double(mine.bonds.newly_broken)};
  double global[4];
  MPI_Allreduce(local, global, 4, MPI_DOUBLE, MPI_SUM, comm);
  EnergyRow row;
  row.step = step;
  row.time = time;
  row.kinetic = kinetic;
  row.strain = global[0];
  row.dissipated = global[1];
  row.external_work = global[2];
  row.broken_bonds = std::llround(global[3]) / 2;  // ordered bonds -> bonds
  return row;
}

double kinetic_energy(const double* v, const std::vector<double>& mass, MPI_Comm comm) {
  double ke = 0;
  for (std::size_t i = 0; i < mass.size(); ++i)
    ke += 0.5 * mass[i] * (v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
  double total = 0;
  MPI_Allreduce(&ke, &total, 1, MPI_DOUBLE, MPI_SUM, comm);
  return total;
}

std::array<double, 6> momentum(const double* X, const double* u, const double* v, const std::vector<double>& mass,
                               MPI_Comm comm) {
  std::array<double, 6> p{}, total{};
  for (std::size_t i = 0; i < mass.size(); ++i) {
    const double m = mass[i];
    const double x[3] = {X[3 * i] + u[3 * i], X[3 * i + 1] + u[3 * i + 1], X[3 * i + 2] + u[3 * i + 2]};
    const double* w = &v[3 * i];
    for (int c = 0; c < 3; ++c) p[c] += m * w[c];
    p[3] += m * (x[1] * w[2] - x[2] * w[1]);
    p[4] += m * (x[2] * w[0] - x[0] * w[2]);
    p[5] += m * (x[0] * w[1] - x[1] * w[0]);
  }
  MPI_Allreduce(p.data(), total.data(), 6, MPI_DOUBLE, MPI_SUM, comm);
  return total;
}

double energy_floor(const std::vector<double>& mass, const int* body, const std::vector<double>& wave2, MPI_Comm comm) {
  double local = 0, floor = 0;
  for (std::size_t i = 0; i < mass.size(); ++i) local += mass[i] * wave2[body[i]] * 1e-20;
  MPI_Allreduce(&local, &floor, 1, MPI_DOUBLE, MPI_SUM, comm);
  return floor;
}

double energy_balance_error(const EnergyRow& row, double e0, double floor) {
  const double scale = std::max({std::fabs(row.kinetic) + std::fabs(row.strain) + std::fabs(row.dissipated),
                                 std::fabs(row.external_work), std::fabs(e0), floor, 1e-300});
  return std::fabs(row.total() - e0) / scale;
}

}  // namespace peri
