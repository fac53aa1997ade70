#include "peri/forces.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace peri {
namespace {

// Flag values: bit 0 = broken; bit 1 = broken during the current call (energy still to book).
constexpr std::uint8_t kBroken = 1, kJustBroken = 2;

// The hot loop, specialised at compile time on the law's shape so that no per-bond branch on the
// model remains. `L` is a local copy whose flags are compile-time constants after assignment.
template <ModelKind K, bool Conical, bool Linear, bool Hard, bool Weighted, bool Energy>
void loop(const BondLaw& law_in, const BondView& v, const std::int32_t* rows, std::size_t nrows,
          double* force, BondTally& tally) {
  BondLaw L = law_in;
  L.kind = K;
  L.conical = Conical;
  L.linear_critical = Linear;
  L.hardening = Hard;
  const double* __restrict X = v.X;
  const double* __restrict u = v.u;
  const double* __restrict V = v.volume;
  const std::int32_t* __restrict nbr = v.neighbor;
  std::uint8_t* __restrict flag = v.broken;
  const float* __restrict wgt = v.weight;
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    const double Xi0 = X[3 * i], Xi1 = X[3 * i + 1], Xi2 = X[3 * i + 2];
    const double xi0 = Xi0 + u[3 * i], xi1 = Xi1 + u[3 * i + 1], xi2c = Xi2 + u[3 * i + 2];
    double f0 = 0, f1 = 0, f2 = 0, w = 0;
    int newly = 0;
    const std::int64_t b0 = v.offsets[i], b1 = v.offsets[i + 1];
    for (std::int64_t b = b0; b < b1; ++b) {
      const std::int32_t j = nbr[b];
      const double e0 = X[3 * j] - Xi0, e1 = X[3 * j + 1] - Xi1, e2 = X[3 * j + 2] - Xi2;
      const double d0 = X[3 * j] + u[3 * j] - xi0, d1 = X[3 * j + 1] + u[3 * j + 1] - xi1,
                   d2 = X[3 * j + 2] + u[3 * j + 2] - xi2c;
      const double s2 = e0 * e0 + e1 * e1 + e2 * e2;
      // Guard against coincident nodes (y = 0) so a collapsed bond cannot produce inf/NaN.
      const double y2 = std::max(d0 * d0 + d1 * d1 + d2 * d2, 1e-12 * s2);
      const std::uint8_t was = flag[b];
      const bool now_broken = L.broken_at(s2, y2);
      const std::uint8_t fresh = static_cast<std::uint8_t>(now_broken & !(was & kBroken));
      flag[b] = static_cast<std::uint8_t>(was | (fresh * (kBroken | kJustBroken)));
      newly += fresh;
      const bool intact = !((was & kBroken) | fresh);
      const double scale = V[j] * (Weighted ? static_cast<double>(wgt[b]) : 1.0);
      const double k = intact ? L.coefficient(s2, y2) * scale : 0.0;
      f0 += k * d0;
      f1 += k * d1;
      f2 += k * d2;
      if constexpr (Energy) w += intact ? L.energy(s2, y2) * scale : 0.0;
    }
    force[3 * i] = f0;
    force[3 * i + 1] = f1;
    force[3 * i + 2] = f2;
    if constexpr (Energy) tally.strain_energy += 0.5 * V[i] * w;
    if (newly) {
      // Book w_0 = w(lambda_0), the energy a bond holds when it breaks (eqs. 26-27), half per
      // end. A bond is detected at the first step past lambda_0; booking w at that step's larger
      // stretch would gain energy systematically (first order in dt), w_0 is unbiased.
      double diss = 0;
      for (std::int64_t b = b0; b < b1; ++b) {
        if (!(flag[b] & kJustBroken)) continue;
        flag[b] = kBroken;
        const std::int32_t j = nbr[b];
        const double e0 = X[3 * j] - Xi0, e1 = X[3 * j + 1] - Xi1, e2 = X[3 * j + 2] - Xi2;
        const double s2 = e0 * e0 + e1 * e1 + e2 * e2;
        const double lc = L.critical_stretch(std::sqrt(s2));
        diss += L.energy(s2, lc * lc * s2) * V[j] * (Weighted ? static_cast<double>(wgt[b]) : 1.0);
      }
      tally.dissipated += 0.5 * V[i] * diss;
      tally.newly_broken += newly;
    }
  }
}

template <ModelKind K, bool Conical, bool Linear, bool Hard>
void dispatch_tail(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t n,
                   double* force, bool energy, BondTally& t) {
  const bool weighted = v.weight != nullptr;
  if (weighted) {
    if (energy) loop<K, Conical, Linear, Hard, true, true>(law, v, rows, n, force, t);
    else loop<K, Conical, Linear, Hard, true, false>(law, v, rows, n, force, t);
  } else {
    if (energy) loop<K, Conical, Linear, Hard, false, true>(law, v, rows, n, force, t);
    else loop<K, Conical, Linear, Hard, false, false>(law, v, rows, n, force, t);
  }
}

template <ModelKind K, bool Conical>
void dispatch_linear(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t n,
                     double* force, bool energy, BondTally& t) {
  const bool hard = K == ModelKind::Membrane && law.hardening;
  if (law.linear_critical) {
    if (hard) dispatch_tail<K, Conical, true, true>(law, v, rows, n, force, energy, t);
    else dispatch_tail<K, Conical, true, false>(law, v, rows, n, force, energy, t);
  } else {
    if (hard) dispatch_tail<K, Conical, false, true>(law, v, rows, n, force, energy, t);
    else dispatch_tail<K, Conical, false, false>(law, v, rows, n, force, energy, t);
  }
}

template <ModelKind K>
void dispatch_conical(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t n,
                      double* force, bool energy, BondTally& t) {
  if (law.conical) dispatch_linear<K, true>(law, v, rows, n, force, energy, t);
  else dispatch_linear<K, false>(law, v, rows, n, force, energy, t);
}

}  // namespace

void bond_forces(const BondLaw& law, const BondView& view, const std::int32_t* rows,
                 std::size_t nrows, double* force, bool with_energy, BondTally& tally) {
  if (law.kind == ModelKind::Membrane)
    dispatch_conical<ModelKind::Membrane>(law, view, rows, nrows, force, with_energy, tally);
  else
    dispatch_conical<ModelKind::PMB>(law, view, rows, nrows, force, with_energy, tally);
}

double bond_energy(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t nrows) {
  double total = 0;
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    double w = 0;
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
      if (v.broken[b] & kBroken) continue;
      const std::int32_t j = v.neighbor[b];
      double s2 = 0, y2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double e = v.X[3 * j + c] - v.X[3 * i + c];
        const double d = v.X[3 * j + c] + v.u[3 * j + c] - (v.X[3 * i + c] + v.u[3 * i + c]);
        s2 += e * e;
        y2 += d * d;
      }
      w += law.energy(s2, std::max(y2, 1e-12 * s2)) * v.volume[j] * (v.weight ? v.weight[b] : 1.0f);
    }
    total += 0.5 * v.volume[i] * w;
  }
  return total;
}

void node_damage(const BondView& v, const std::int32_t* rows, std::size_t nrows, double* damage) {
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    double all = 0, lost = 0;
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
      const double m = v.volume[v.neighbor[b]] * (v.weight ? v.weight[b] : 1.0f);
      all += m;
      lost += (v.broken[b] & kBroken) ? m : 0.0;
    }
    damage[i] = all > 0 ? lost / all : 0.0;
  }
}

double stable_time_step(const BondLaw& law, double density, const BondView& v,
                        const std::int32_t* rows, std::size_t nrows) {
  double dt = std::numeric_limits<double>::infinity();
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    double sum = 0;
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
      const std::int32_t j = v.neighbor[b];
      double s2 = 0;
      for (int c = 0; c < 3; ++c) s2 += std::pow(v.X[3 * j + c] - v.X[3 * i + c], 2);
      sum += law.reference_stiffness(s2) * v.volume[j] * (v.weight ? v.weight[b] : 1.0f);
    }
    if (sum > 0) dt = std::min(dt, std::sqrt(2.0 * density / sum));
  }
  return dt;
}

}  // namespace peri
