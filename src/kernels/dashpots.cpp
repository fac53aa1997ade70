#include "peri/kernels/dashpots.hpp"

#include <cmath>

#include "peri/kernels/bond_loop.hpp"

namespace peri {

void dashpot_coefficients(const BondLaw& law, double tau, const BondView& v, const std::int32_t* rows,
                          std::size_t nrows, double* coefficient) {
  for (std::size_t r = 0; r < nrows; ++r)
    for (const FamilyBond& bond : family(v, rows[r]))
      coefficient[bond.at()] = tau * law.reference_stiffness(bond.xi2()) * bond.measure();
}

void dashpot_records(const BondView& v, const double* velocity, std::int64_t nodes, double* records) {
  const double* x = v.x;
  const std::int64_t s = v.x_stride;
  for (std::int64_t j = 0; j < nodes; ++j) {
    double* r = records + kDashpotRecord * j;
    r[0] = x[j];
    r[1] = x[s + j];
    r[2] = x[2 * s + j];
    for (int c = 0; c < 3; ++c) r[3 + c] = velocity[3 * j + c];
  }
}

void bond_dashpots(const BondView& v, const double* records, const double* coefficient, const std::int32_t* rows,
                   std::size_t nrows, double* viscous) {
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    const double* ri = records + kDashpotRecord * static_cast<std::int64_t>(i);
    double f[3] = {0, 0, 0};
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
      if (v.broken[b] & kBrokenFlag) continue;
      const double* rj = records + kDashpotRecord * static_cast<std::int64_t>(v.neighbor[b]);
      const double d[3] = {rj[0] - ri[0], rj[1] - ri[1], rj[2] - ri[2]};
      const double y2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
      if (!(y2 > 0)) continue;  // coincident ends: no direction
      // tau C w V (e . dv) e = tau C w V (d . dv) d / y^2.
      const double rate = d[0] * (rj[3] - ri[3]) + d[1] * (rj[4] - ri[4]) + d[2] * (rj[5] - ri[5]);
      const double k = coefficient[b] * rate / y2;
      for (int c = 0; c < 3; ++c) f[c] += k * d[c];
    }
    for (int c = 0; c < 3; ++c) viscous[3 * static_cast<std::int64_t>(i) + c] = f[c];
  }
}

double dashpot_stable_time_step(double dt0, double tau) {
  // The dashpot matrix is tau times the reference axial stiffness matrix whose largest frequency
  // omega = 2 / dt0 sets dt0, so a mode of frequency omega is damped at gamma = tau omega^2.
  // Leapfrog with the half-step velocity is stable iff (omega dt)^2 / 4 + gamma dt / 2 < 1 (Jury,
  // as marder_stable_time_step), i.e. dt^2 + 2 tau dt < dt0^2.
  if (!(tau > 0)) return dt0;
  return dt0 * dt0 / (tau + std::sqrt(tau * tau + dt0 * dt0));  // sqrt(tau^2 + dt0^2) - tau, without cancellation
}

}  // namespace peri
