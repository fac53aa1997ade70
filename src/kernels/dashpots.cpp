#include "peri/kernels/dashpots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "peri/core/simd.hpp"

#include "peri/kernels/bond_loop.hpp"
#include "peri/kernels/free_rows.hpp"  // (the node lines' transpose, AVX-512)

namespace peri {

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
// The lanes' node records [x, y, z, v_x, v_y, v_z] as six vectors, the live lanes of a slot, and
// a sum of the live lanes.
#if defined(PERI_AVX512VL)
using Pack = simd::Simd8;
struct Lines {
  __m512d x, y, z, vx, vy, vz;
};
// As the free rows' node lines (their fields V, X, Y: here the velocity).
__attribute__((always_inline)) inline Lines transpose_lines(const double* const rec[8]) {
  const fast::Records<Pack> o = fast::transpose_records(rec);
  return {o.x, o.y, o.z, o.V, o.X, o.Y};
}
// Ends apart (y^2 > 0, false for NaN as the scalar test) and not dead.
__attribute__((always_inline)) inline __mmask8 live_lanes(__m512d y2, unsigned dead) {
  return _mm512_cmp_pd_mask(y2, Pack::zero(), _CMP_GT_OQ) & static_cast<__mmask8>(~dead);
}
__attribute__((always_inline)) inline __m512d add_live(__mmask8 live, __m512d k, __m512d d, __m512d f) {
  return _mm512_mask3_fmadd_pd(k, d, f, live);
}
#else
using Pack = simd::Simd4;
struct Lines {
  __m256d x, y, z, vx, vy, vz;
};
// Per pair of fields, lanes 0 and 2 (1 and 3) in the halves of one vector, then one unpack per
// field.
__attribute__((always_inline)) inline Lines transpose_lines(const double* const rec[4]) {
  auto pair = [&](int l, int c) {
    return _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(rec[l] + c)), _mm_load_pd(rec[l + 2] + c), 1);
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
__attribute__((always_inline)) inline __m256d live_lanes(__m256d y2, unsigned dead) {
  return _mm256_andnot_pd(_mm256_load_pd(reinterpret_cast<const double*>(simd::kLaneMasks.bits[dead])),
                          _mm256_cmp_pd(y2, Pack::zero(), _CMP_GT_OQ));
}
__attribute__((always_inline)) inline __m256d add_live(__m256d live, __m256d k, __m256d d, __m256d f) {
  return _mm256_blendv_pd(f, Pack::fmadd(k, d, f), live);
}
#endif

// Group g of `lanes`: its rows (`count` of them, group[0 ..]) one per lane, each walking its own
// bonds in CSR order with add_dashpot's operations; a lane at a broken bond, at coincident ends or
// past its row's end (its own record, constant 0) keeps its sums (as the scalar walk's
// `continue`). The same bits as dashpot_row. `Intact`: no flag byte is read.
template <bool Intact>
void dashpot_group(const BondView& v, const double* records, const DashpotLanes& lanes, std::size_t g,
                   const std::int32_t* group, int count, double* viscous) {
  using S = Pack;
  constexpr int W = S::W;
  std::int32_t rows[W];
  std::int64_t b0[W], n[W];
  const double* own[W];
  for (int l = 0; l < W; ++l) {
    rows[l] = group[l < count ? l : count - 1];
    b0[l] = v.offsets[rows[l]];
    n[l] = v.offsets[rows[l] + 1] - b0[l];
    own[l] = records + kDashpotRecord * static_cast<std::int64_t>(rows[l]);
  }
  const Lines o = transpose_lines(own);
  const std::int32_t* __restrict nbr = lanes.neighbor.data() + lanes.at[g];
  const double* __restrict coef = lanes.coefficient.data() + lanes.at[g];
  const std::int64_t slots = (lanes.at[g + 1] - lanes.at[g]) / W;
  typename S::V f0 = S::zero(), f1 = S::zero(), f2 = S::zero();
  for (std::int64_t k = 0; k < slots; ++k) {
    const double* r[W];
    // (Each address pinned to a general register, as in the free rows' loop.)
    for (int l = 0; l < W; ++l) {
      r[l] = records + kDashpotRecord * static_cast<std::int64_t>(nbr[k * W + l]);
      __asm__("" : "+r"(r[l]));
    }
    unsigned dead = 0;
    if constexpr (!Intact)
      for (int l = 0; l < W; ++l)
        dead |= static_cast<unsigned>(k < n[l] && (v.broken[b0[l] + k] & kBrokenFlag)) << l;
    const Lines j = transpose_lines(r);
    const auto d0 = S::sub(j.x, o.x), d1 = S::sub(j.y, o.y), d2 = S::sub(j.z, o.z);
    const auto y2 = S::fmadd(d2, d2, S::fmadd(d0, d0, S::mul(d1, d1)));
    const auto rate = S::fmadd(S::sub(j.vz, o.vz), d2, S::fmadd(S::sub(j.vx, o.vx), d0, S::mul(d1, S::sub(j.vy, o.vy))));
    const auto kk = S::div(S::mul(rate, S::loadu(coef + k * W)), y2);
    const auto live = live_lanes(y2, dead);
    f0 = add_live(live, kk, d0, f0);
    f1 = add_live(live, kk, d1, f1);
    f2 = add_live(live, kk, d2, f2);
  }
  double s0[W], s1[W], s2[W];
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

namespace {
// DashpotLanes of `rows`; coefficient(i, b): the constant of row i's bond at CSR position b.
template <class Coefficient>
DashpotLanes make_lanes(const BondView& v, const std::int32_t* rows, std::size_t nrows, Coefficient coefficient) {
  constexpr std::size_t W = kDashpotLanes;
  DashpotLanes out;
  out.at = lane_group_starts(v, rows, nrows, W);
  out.neighbor.resize(static_cast<std::size_t>(out.at.back()));
  out.coefficient.resize(static_cast<std::size_t>(out.at.back()));
  for (std::size_t g = 0; g + 1 < out.at.size(); ++g)
    for (std::size_t l = 0; l < W; ++l) {
      const std::size_t r = g * W + l;
      const std::int32_t i = rows[std::min(r, nrows - 1)];
      const std::int64_t b0 = v.offsets[i], n = r < nrows ? v.offsets[i + 1] - b0 : 0;
      for (std::int64_t k = 0, at = out.at[g] + static_cast<std::int64_t>(l); at < out.at[g + 1]; ++k, at += W) {
        out.neighbor[at] = k < n ? v.neighbor[b0 + k] : i;
        out.coefficient[at] = k < n ? coefficient(i, b0 + k) : 0.0;
      }
    }
  return out;
}
}  // namespace

DashpotLanes dashpot_lanes(const BondLaw& law, double tau, const BondView& v, const std::int32_t* rows,
                           std::size_t nrows) {
  return make_lanes(v, rows, nrows, [&](std::int32_t i, std::int64_t b) {
    const Family bonds = family(v, i);
    Family::iterator at = bonds.begin();
    at.b = b;
    const FamilyBond bond = *at;
    return tau * law.reference_stiffness(bond.xi2()) * bond.measure();
  });
}

DashpotLanes dashpot_lanes(const BondView& v, const double* coefficient, const std::int32_t* rows, std::size_t nrows) {
  return make_lanes(v, rows, nrows, [&](std::int32_t, std::int64_t b) { return coefficient[b]; });
}

void bond_dashpots_portable(const BondView& v, const double* records, const double* coefficient,
                            const std::int32_t* rows, std::size_t nrows, double* viscous) {
  for (std::size_t r = 0; r < nrows; ++r) dashpot_row(v, records, coefficient, rows[r], viscous);
}

void bond_dashpots(const BondView& v, const double* records, const DashpotLanes& lanes, const std::int32_t* rows,
                   std::size_t nrows, double* viscous) {
#if defined(PERI_AVX2)
  // (Measured no faster, with each lane reading its row's CSR list: two groups of four
  // interleaved in one loop, and runs of four consecutive rows of one family shape loading each
  // field as one vector from planes, about 40 instructions per four bonds instead of 56.)
  constexpr int W = kDashpotLanes;
  for (std::size_t r = 0; r < nrows; r += W) {
    const int count = static_cast<int>(std::min<std::size_t>(W, nrows - r));
    bool intact = v.row_broken != nullptr;
    for (int l = 0; l < count && intact; ++l) intact = v.row_broken[rows[r + l]] == 0;
    if (intact)
      dashpot_group<true>(v, records, lanes, r / W, rows + r, count, viscous);
    else
      dashpot_group<false>(v, records, lanes, r / W, rows + r, count, viscous);
  }
#else
  // One lane: each row's bonds in CSR order (add_dashpot's operations, as dashpot_row).
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    const double* ri = records + kDashpotRecord * static_cast<std::int64_t>(i);
    double f[3] = {0, 0, 0};
    for (std::int64_t b = v.offsets[i], at = lanes.at[r]; b < v.offsets[i + 1]; ++b, ++at)
      if (!(v.broken[b] & kBrokenFlag))
        add_dashpot(ri, records + kDashpotRecord * static_cast<std::int64_t>(lanes.neighbor[at]), lanes.coefficient[at], f);
    for (int c = 0; c < 3; ++c) viscous[3 * static_cast<std::int64_t>(i) + c] = f[c];
  }
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
