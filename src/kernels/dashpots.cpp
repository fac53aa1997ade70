#include "peri/kernels/dashpots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "peri/core/simd.hpp"

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

namespace {

// One bond of row i (own record ri, neighbour's rj, constant c) added to the row's sum f: as
// written, with the FMAs explicit (the file is compiled with -ffp-contract=off), so that the
// four-lane pass below gives the same bits; coincident ends (no direction) add nothing.
// tau C w V (e . dv) e = tau C w V (d . dv) d / y^2.
inline void add_dashpot(const double* ri, const double* rj, double c, double* f) {
  using S = simd::Scalar;
  const double d0 = rj[0] - ri[0], d1 = rj[1] - ri[1], d2 = rj[2] - ri[2];
  const double y2 = S::fmadd(d2, d2, S::fmadd(d0, d0, d1 * d1));
  if (!(y2 > 0)) return;  // coincident ends: no direction
  const double rate = S::fmadd(rj[5] - ri[5], d2, S::fmadd(rj[3] - ri[3], d0, d1 * (rj[4] - ri[4])));
  const double k = rate * c / y2;
  f[0] = S::fmadd(k, d0, f[0]);
  f[1] = S::fmadd(k, d1, f[1]);
  f[2] = S::fmadd(k, d2, f[2]);
}

void dashpot_row(const BondView& v, const double* records, const double* coefficient, std::int32_t i,
                 double* viscous) {
  const double* ri = records + kDashpotRecord * static_cast<std::int64_t>(i);
  double f[3] = {0, 0, 0};
  for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b)
    if (!(v.broken[b] & kBrokenFlag))
      add_dashpot(ri, records + kDashpotRecord * static_cast<std::int64_t>(v.neighbor[b]), coefficient[b], f);
  for (int c = 0; c < 3; ++c) viscous[3 * static_cast<std::int64_t>(i) + c] = f[c];
}

#if defined(PERI_AVX2)
// Four records' [x, y, z, v_x, v_y, v_z] as six vectors of the lanes' values: per pair of fields,
// lanes 0 and 2 (1 and 3) in the halves of one vector, then one unpack per field.
struct Lines {
  __m256d x, y, z, vx, vy, vz;
};
__attribute__((always_inline)) inline Lines transpose_lines(const double* const rec[4]) {
  auto pair = [&](int l, int c) {
    return _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(rec[l] + c)), _mm_loadu_pd(rec[l + 2] + c), 1);
  };
  Lines o;
  __m256d p = pair(0, 0), q = pair(1, 0);
  o.x = _mm256_unpacklo_pd(p, q);
  o.y = _mm256_unpackhi_pd(p, q);
  p = pair(0, 2), q = pair(1, 2);
  o.z = _mm256_unpacklo_pd(p, q);
  o.vx = _mm256_unpackhi_pd(p, q);
  p = pair(0, 4), q = pair(1, 4);
  o.vy = _mm256_unpacklo_pd(p, q);
  o.vz = _mm256_unpackhi_pd(p, q);
  return o;
}

// Four rows, one per lane (`count` of them; idle lanes repeat the last row and write nothing),
// each walking its own bonds in CSR order with add_dashpot's operations: a lane past its row's
// end, or at a broken bond or coincident ends, keeps its sums (a blend, as the scalar walk's
// `continue`). The same bits as dashpot_row. `Intact`: no flag byte is read.
template <bool Intact>
void dashpot_rows4(const BondView& v, const double* records, const double* coefficient, const std::int32_t* group,
                   int count, double* viscous) {
  using S = simd::Simd4;
  static constexpr double kNone = 0.0;
  std::int32_t rows[4];
  std::int64_t b0[4], n[4], nmin = INT64_MAX, nmax = 0;
  const double* own[4];
  for (int l = 0; l < 4; ++l) {
    rows[l] = group[l < count ? l : count - 1];
    b0[l] = v.offsets[rows[l]];
    n[l] = v.offsets[rows[l] + 1] - b0[l];
    nmin = std::min(nmin, n[l]);
    nmax = std::max(nmax, n[l]);
    own[l] = records + kDashpotRecord * static_cast<std::int64_t>(rows[l]);
  }
  const Lines o = transpose_lines(own);
  __m256d f0 = S::zero(), f1 = S::zero(), f2 = S::zero();
  for (std::int64_t k = 0; k < nmax; ++k) {
    const double* r[4];
    const double* c[4];
    unsigned dead = 0;
    if (k < nmin) [[likely]] {
      for (int l = 0; l < 4; ++l) {
        r[l] = records + kDashpotRecord * static_cast<std::int64_t>(v.neighbor[b0[l] + k]);
        c[l] = coefficient + b0[l] + k;
      }
    } else {  // a lane past its row's end reads its own record (coincident: no bond)
      for (int l = 0; l < 4; ++l) {
        const bool past = k >= n[l];
        dead |= static_cast<unsigned>(past) << l;
        r[l] = past ? own[l] : records + kDashpotRecord * static_cast<std::int64_t>(v.neighbor[b0[l] + k]);
        c[l] = past ? &kNone : coefficient + b0[l] + k;
      }
    }
    if constexpr (!Intact)
      for (int l = 0; l < 4; ++l)
        dead |= static_cast<unsigned>(k < n[l] && (v.broken[b0[l] + k] & kBrokenFlag)) << l;
    const Lines j = transpose_lines(r);
    const __m256d d0 = S::sub(j.x, o.x), d1 = S::sub(j.y, o.y), d2 = S::sub(j.z, o.z);
    const __m256d y2 = S::fmadd(d2, d2, S::fmadd(d0, d0, S::mul(d1, d1)));
    const __m256d rate =
        S::fmadd(S::sub(j.vz, o.vz), d2, S::fmadd(S::sub(j.vx, o.vx), d0, S::mul(d1, S::sub(j.vy, o.vy))));
    const __m256d cv = _mm256_setr_pd(*c[0], *c[1], *c[2], *c[3]);
    const __m256d kk = S::div(S::mul(rate, cv), y2);
    // Live lanes: ends apart (y^2 > 0, false for NaN as the scalar test) and not dead.
    const __m256d live = _mm256_andnot_pd(_mm256_load_pd(reinterpret_cast<const double*>(simd::kLaneMasks.bits[dead])),
                                          _mm256_cmp_pd(y2, S::zero(), _CMP_GT_OQ));
    f0 = _mm256_blendv_pd(f0, S::fmadd(kk, d0, f0), live);
    f1 = _mm256_blendv_pd(f1, S::fmadd(kk, d1, f1), live);
    f2 = _mm256_blendv_pd(f2, S::fmadd(kk, d2, f2), live);
  }
  double s0[4], s1[4], s2[4];
  S::storeu(s0, f0);
  S::storeu(s1, f1);
  S::storeu(s2, f2);
  for (int l = 0; l < count; ++l) {
    double* out = viscous + 3 * static_cast<std::int64_t>(rows[l]);
    out[0] = s0[l];
    out[1] = s1[l];
    out[2] = s2[l];
  }
}
#endif

}  // namespace

void bond_dashpots_portable(const BondView& v, const double* records, const double* coefficient,
                            const std::int32_t* rows, std::size_t nrows, double* viscous) {
  for (std::size_t r = 0; r < nrows; ++r) dashpot_row(v, records, coefficient, rows[r], viscous);
}

void bond_dashpots(const BondView& v, const double* records, const double* coefficient, const std::int32_t* rows,
                   std::size_t nrows, double* viscous) {
#if defined(PERI_AVX2)
  // (Measured no faster: two groups of four interleaved in one loop, and runs of four consecutive
  // rows of one family shape loading each field as one vector from planes, about 40 instructions
  // per four bonds instead of 56.)
  for (std::size_t r = 0; r < nrows; r += 4) {
    const int count = static_cast<int>(std::min<std::size_t>(4, nrows - r));
    bool intact = v.row_broken != nullptr;
    for (int l = 0; l < count && intact; ++l) intact = v.row_broken[rows[r + l]] == 0;
    if (intact)
      dashpot_rows4<true>(v, records, coefficient, rows + r, count, viscous);
    else
      dashpot_rows4<false>(v, records, coefficient, rows + r, count, viscous);
  }
#else
  bond_dashpots_portable(v, records, coefficient, rows, nrows, viscous);
#endif
}

double dashpot_stable_time_step(double dt0, double tau) {
  // The dashpot matrix is tau times the reference axial stiffness matrix whose largest frequency
  // omega = 2 / dt0 sets dt0, so a mode of frequency omega is damped at gamma = tau omega^2.
  // Leapfrog with the half-step velocity is stable iff (omega dt)^2 / 4 + gamma dt / 2 < 1 (Jury,
  // as marder_stable_time_step), i.e. dt^2 + 2 tau dt < dt0^2.
  if (!(tau > 0)) return dt0;
  // sqrt(tau^2 + dt0^2) - tau, without cancellation (tau^2 fused where the build has FMA)
  return dt0 * dt0 / (tau + std::sqrt(simd::Scalar::fmadd(tau, tau, dt0 * dt0)));
}

}  // namespace peri
