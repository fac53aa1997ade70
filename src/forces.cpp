#include "peri/forces.hpp"

#include <algorithm>
#if defined(__AVX2__) && defined(__FMA__)
#define PERI_AVX2 1
#include <immintrin.h>
#endif
#include <cmath>
#include <limits>

namespace peri {
namespace {

// Flag values: bit 0 = broken; bit 1 = broken during the current call (energy still to book).
constexpr std::uint8_t kBroken = 1, kJustBroken = 2;

// Book w_0 = w(lambda_0), the energy a bond holds when it breaks (eqs. 26-27), half per end, for
// the bonds of row i flagged during this call. A bond is detected at the first step past
// lambda_0; booking w at that step's larger stretch would gain energy systematically (first
// order in dt), w_0 is unbiased.
void book_breaks(const BondLaw& L, const BondView& v, std::int32_t i, int newly, BondTally& tally) {
  double diss = 0;
  for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
    if (!(v.broken[b] & kJustBroken)) continue;
    v.broken[b] = kBroken;
    const double s2 = v.xi2(i, b);
    const double lc = L.critical_stretch(std::sqrt(s2));
    diss += L.energy(s2, lc * lc * s2) * v.measure(i, b);
  }
  tally.dissipated += 0.5 * v.volume[i] * diss;
  tally.newly_broken += newly;
  if (v.row_broken) v.row_broken[i] = 1;
}

// The portable loop, specialised at compile time on the law's shape so that no per-bond branch on
// the model remains. `L` is a local copy whose flags are compile-time constants after assignment.
// Serves every law (hardening included) and views without family patterns.
template <ModelKind K, bool Conical, bool Linear, bool Hard, bool Energy>
struct ScalarLoop {
  BondLaw L;
  explicit ScalarLoop(const BondLaw& law) : L(law) {
    L.kind = K;
    L.conical = Conical;
    L.linear_critical = Linear;
    L.hardening = Hard;
  }
  void row(const BondView& v, std::int32_t i, double* force, BondTally& tally) const {
    const double* __restrict px = v.x;
    const double* __restrict py = v.x + v.x_stride;
    const double* __restrict pz = v.x + 2 * v.x_stride;
    const std::int32_t* __restrict nbr = v.neighbor;
    std::uint8_t* __restrict flag = v.broken;
    const double xi0 = px[i], xi1 = py[i], xi2c = pz[i];
    double f0 = 0, f1 = 0, f2 = 0, w = 0;
    int newly = 0;
    const std::int64_t b0 = v.offsets[i], b1 = v.offsets[i + 1];
    for (std::int64_t b = b0; b < b1; ++b) {
      const std::int32_t j = nbr[b];
      const double d0 = px[j] - xi0, d1 = py[j] - xi1, d2 = pz[j] - xi2c;
      const double s2 = v.xi2(i, b);
      // Guard against coincident nodes (y = 0) so a collapsed bond cannot produce inf/NaN.
      const double y2 = std::max(d0 * d0 + d1 * d1 + d2 * d2, 1e-12 * s2);
      const std::uint8_t was = flag[b];
      const bool now_broken = L.broken_at(s2, y2);
      const std::uint8_t fresh = static_cast<std::uint8_t>(now_broken & !(was & kBroken));
      flag[b] = static_cast<std::uint8_t>(was | (fresh * (kBroken | kJustBroken)));
      newly += fresh;
      const bool intact = !((was & kBroken) | fresh);
      const double scale = v.measure(i, b);
      const double k = intact ? L.coefficient(s2, y2) * scale : 0.0;
      f0 += k * d0;
      f1 += k * d1;
      f2 += k * d2;
      if constexpr (Energy) w += intact ? L.energy(s2, y2) * scale : 0.0;
    }
    force[3 * i] = f0;
    force[3 * i + 1] = f1;
    force[3 * i + 2] = f2;
    if constexpr (Energy) tally.strain_energy += 0.5 * v.volume[i] * w;
    if (newly) book_breaks(L, v, i, newly, tally);
  }
  void operator()(const BondView& v, const RowBlocks& rows, double* force, BondTally& tally) const {
    for (const RowRun& run : rows.runs)
      for (std::int32_t l = 0; l < run.count; ++l) row(v, run.first + l * run.stride, force, tally);
    for (std::int32_t i : rows.rest) row(v, i, force, tally);
  }
};

#if defined(PERI_AVX2)
// The vector loop (AVX2 + FMA): four rows at a time, one per lane. Lane l walks the bonds of its
// row in CSR order and sums them in that order (one fused multiply-add per bond and component),
// so a node's force is the same bits whichever way its row is loaded (a block of four neighbouring
// rows or a gathered group, below) and whichever rank computes it.

// All-ones lanes where bit l of the index is set.
struct LaneMasks {
  alignas(32) std::int64_t bits[16][4];
  constexpr LaneMasks() : bits{} {
    for (int m = 0; m < 16; ++m)
      for (int l = 0; l < 4; ++l) bits[m][l] = (m >> l & 1) ? -1 : 0;
  }
};
constexpr LaneMasks kLaneMasks;
inline __m256d lane_mask(unsigned bits) { return _mm256_load_pd(reinterpret_cast<const double*>(kLaneMasks.bits[bits])); }

// Four bonds, lane l the k-th bond of row l: y = x_j - x_i and the family pattern's slots.
struct Bonds4 {
  __m256d d0, d1, d2;
  __m256d xi2, measure, inv_xi, measure_per_xi2;  // |xi|^2, w V_j, 1/|xi|, w V_j / |xi|^2
  unsigned dead;  // bit l: lane l's bond is broken already, or lane l is idle
};

// One bond law on four lanes.
// Membrane (eq. 15): f_hat / y = 2 c g (1 - r^2) w V_j / xi^2 with r = xi^2 / y^2 = lambda^-2:
// one division, no square root, and the failure test (eq. 11) is r <= lambda_0^-2.
// PMB: f_hat / y = c g (1/xi - 1/y). The law's constant c multiplies the row's sum (c_row).
template <ModelKind K, bool Conical, bool Linear, bool Energy>
struct Avx2Law {
  double c_row;
  __m256d zero, one, c_energy, tiny, r_max, crit0, crit0_sq, inv_crit0_sq, crit_slope, inv_horizon;
  explicit Avx2Law(const BondLaw& L)
      : c_row(K == ModelKind::Membrane ? 2.0 * L.c : L.c),
        zero(_mm256_setzero_pd()),
        one(_mm256_set1_pd(1.0)),
        c_energy(_mm256_set1_pd(K == ModelKind::Membrane ? L.c : 0.5 * L.c)),
        tiny(_mm256_set1_pd(1e-12)),
        r_max(_mm256_set1_pd(1e12)),
        crit0(_mm256_set1_pd(L.critical0)),
        crit0_sq(_mm256_set1_pd(L.critical0 * L.critical0)),
        inv_crit0_sq(_mm256_set1_pd(1.0 / (L.critical0 * L.critical0))),  // 0 if unbreakable
        crit_slope(_mm256_set1_pd(Linear ? (L.critical_delta - L.critical0) / L.horizon : 0.0)),
        inv_horizon(_mm256_set1_pd(1.0 / L.horizon)) {}

  // Adds the four bonds to the lane sums f (force / c_row) and w (energy density); returns the
  // lanes whose bond reaches the failure test now (eq. 11; eq. 29 if linear), which add nothing.
  __attribute__((always_inline)) unsigned add(const Bonds4& b, __m256d& f0, __m256d& f1, __m256d& f2,
                                              __m256d& w) const {
    const __m256d s2 = b.xi2;
    // (x^2 + z^2) + y^2: two independent products, a shorter dependency chain than nested FMAs.
    const __m256d y2 = _mm256_add_pd(_mm256_fmadd_pd(b.d2, b.d2, _mm256_mul_pd(b.d0, b.d0)), _mm256_mul_pd(b.d1, b.d1));
    __m256d xi = zero, g = one;
    // |xi| = |xi|^2 / |xi|: a multiplication by the pattern's 1/|xi|, not a square root.
    if constexpr (Conical || Linear || (K == ModelKind::PMB && Energy)) xi = _mm256_mul_pd(s2, b.inv_xi);
    if constexpr (Conical) g = _mm256_max_pd(zero, _mm256_fnmadd_pd(xi, inv_horizon, one));
    // Membrane: r = xi^2 / y^2, capped for coincident nodes (as y^2 >= 1e-12 xi^2 in ScalarLoop).
    __m256d ratio = one, y2g = y2;
    if constexpr (K == ModelKind::Membrane) ratio = _mm256_min_pd(_mm256_div_pd(s2, y2), r_max);
    else y2g = _mm256_max_pd(y2, _mm256_mul_pd(tiny, s2));
    __m256d reached;
    if constexpr (Linear) {
      const __m256d lc = _mm256_fmadd_pd(crit_slope, xi, crit0);
      reached = _mm256_cmp_pd(y2g, _mm256_mul_pd(_mm256_mul_pd(lc, lc), s2), _CMP_GE_OQ);
    } else if constexpr (K == ModelKind::Membrane) {
      reached = _mm256_cmp_pd(ratio, inv_crit0_sq, _CMP_LE_OQ);
    } else {
      reached = _mm256_cmp_pd(y2g, _mm256_mul_pd(crit0_sq, s2), _CMP_GE_OQ);
    }
    const unsigned fresh = static_cast<unsigned>(_mm256_movemask_pd(reached)) & ~b.dead & 0xFu;
    const __m256d dead = _mm256_or_pd(reached, lane_mask(b.dead));  // all ones where the bond adds nothing
    __m256d coef;
    if constexpr (K == ModelKind::Membrane) {
      __m256d a = b.measure_per_xi2;
      if constexpr (Conical) a = _mm256_mul_pd(g, a);
      coef = _mm256_andnot_pd(dead, _mm256_fnmadd_pd(a, _mm256_mul_pd(ratio, ratio), a));  // g wV/xi^2 (1 - r^2)
      if constexpr (Energy) {  // eq. (13): c (lambda^2 + lambda^-2 - 2) g = c g (y^2 - xi^2)^2 / (xi^2 y^2)
        const __m256d y2e = _mm256_max_pd(y2, _mm256_mul_pd(tiny, s2));  // as ScalarLoop
        const __m256d e = _mm256_sub_pd(y2e, s2);
        const __m256d ge = _mm256_mul_pd(c_energy, Conical ? _mm256_mul_pd(g, b.measure) : b.measure);
        w = _mm256_add_pd(w, _mm256_andnot_pd(dead, _mm256_div_pd(_mm256_mul_pd(ge, _mm256_mul_pd(e, e)), _mm256_mul_pd(s2, y2e))));
      }
    } else {
      const __m256d gm = Conical ? _mm256_mul_pd(g, b.measure) : b.measure;
      // 1/y as a square root and a division (AVX2 has no double-precision reciprocal square
      // root estimate; the single-precision one and three Newton steps ran at 0.64 of this).
      const __m256d y = _mm256_sqrt_pd(y2g);
      const __m256d inv_y = _mm256_div_pd(one, y);
      coef = _mm256_andnot_pd(dead, _mm256_mul_pd(gm, _mm256_sub_pd(b.inv_xi, inv_y)));  // c g (1/xi - 1/y)
      if constexpr (Energy) {  // w = (c/2) g (y - xi)^2 / xi
        const __m256d stretch = _mm256_sub_pd(y, xi);
        const __m256d ge = _mm256_mul_pd(c_energy, gm);
        w = _mm256_add_pd(w, _mm256_andnot_pd(dead, _mm256_div_pd(_mm256_mul_pd(ge, _mm256_mul_pd(stretch, stretch)), xi)));
      }
    }
    f0 = _mm256_fmadd_pd(coef, b.d0, f0);
    f1 = _mm256_fmadd_pd(coef, b.d1, f1);
    f2 = _mm256_fmadd_pd(coef, b.d2, f2);
    return fresh;
  }

  // Writes the rows' force densities and energy (lanes 0 .. count-1) and books their newly broken
  // bonds (`L`: the law this was built from).
  void finish(const BondLaw& L, const BondView& v, const std::int32_t rows[4], int count, __m256d f0, __m256d f1,
              __m256d f2, __m256d w, const int newly[4], double* force, BondTally& tally) const {
    alignas(32) double s0[4], s1[4], s2[4], se[4];
    _mm256_store_pd(s0, f0);
    _mm256_store_pd(s1, f1);
    _mm256_store_pd(s2, f2);
    _mm256_store_pd(se, w);
    for (int l = 0; l < count; ++l) {
      const std::int32_t i = rows[l];
      force[3 * i] = c_row * s0[l];
      force[3 * i + 1] = c_row * s1[l];
      force[3 * i + 2] = c_row * s2[l];
      if constexpr (Energy) tally.strain_energy += 0.5 * v.volume[i] * se[l];
      if (newly[l]) book_breaks(L, v, i, newly[l], tally);
    }
  }
};

// Marks the fresh lanes' bonds (bond k of rows[l], CSR positions flag_row[l] + k) as broken now.
inline void mark_fresh(unsigned fresh, std::uint8_t* const flag_row[4], std::int64_t k, int newly[4]) {
  for (int l = 0; l < 4; ++l)
    if (fresh >> l & 1) {
      flag_row[l][k] |= kBroken | kJustBroken;
      ++newly[l];
    }
}

// What the blocks of one run (RowRun) share: the neighbour list of its first row (n bonds) and
// its family pattern's slots.
struct RunSlots {
  const std::int32_t* __restrict neighbor;
  std::int64_t n;
  const double *xi2, *measure, *inv_xi, *measure_per_xi2;
};

// A block of a run: rows i + l s, the k-th neighbours of the four rows nodes j + shift + l s with
// j the run's k-th neighbour. Per four bonds: the neighbours' positions (one vector load of each
// coordinate plane if s = 1, `Unit`; else four loads each), the pattern's slots broadcast, the
// four flag bytes as lane bits unless the block has no broken bond (`Intact`).
template <bool Intact, bool Unit, class Law>
void block_avx2(const Law& law, const BondLaw& L, const BondView& v, const RunSlots& run, std::int32_t i,
                std::int32_t stride, std::int64_t shift, double* force, BondTally& tally) {
  const double* __restrict px = v.x + shift;
  const double* __restrict py = v.x + v.x_stride + shift;
  const double* __restrict pz = v.x + 2 * v.x_stride + shift;
  const std::int64_t s = Unit ? 1 : stride;
  const std::int32_t rows[4] = {i, static_cast<std::int32_t>(i + s), static_cast<std::int32_t>(i + 2 * s),
                                static_cast<std::int32_t>(i + 3 * s)};
  auto lanes = [s](const double* p, std::int64_t at) {
    if constexpr (Unit) return _mm256_loadu_pd(p + at);
    else return _mm256_setr_pd(p[at], p[at + s], p[at + 2 * s], p[at + 3 * s]);
  };
  const std::int64_t n = run.n;
  const double *sx = run.xi2, *sm = run.measure, *sr = run.inv_xi, *sa = run.measure_per_xi2;
  const std::int32_t* __restrict nbr = run.neighbor;
  std::uint8_t* const flag_row[4] = {v.broken + v.offsets[rows[0]], v.broken + v.offsets[rows[1]],
                                     v.broken + v.offsets[rows[2]], v.broken + v.offsets[rows[3]]};
  const std::uint8_t *fl0 = flag_row[0], *fl1 = flag_row[1], *fl2 = flag_row[2], *fl3 = flag_row[3];
  const __m256d xi0 = lanes(v.x, i), xi1 = lanes(v.x + v.x_stride, i), xi2 = lanes(v.x + 2 * v.x_stride, i);
  __m256d f0 = law.zero, f1 = law.zero, f2 = law.zero, w = law.zero;
  int newly[4] = {0, 0, 0, 0};
  for (std::int64_t k = 0; k < n; ++k) {
    const std::int64_t j = nbr[k];
    Bonds4 b;
    b.d0 = _mm256_sub_pd(lanes(px, j), xi0);
    b.d1 = _mm256_sub_pd(lanes(py, j), xi1);
    b.d2 = _mm256_sub_pd(lanes(pz, j), xi2);
    b.xi2 = _mm256_broadcast_sd(sx + k);
    b.measure = _mm256_broadcast_sd(sm + k);
    b.inv_xi = _mm256_broadcast_sd(sr + k);
    b.measure_per_xi2 = _mm256_broadcast_sd(sa + k);
    if constexpr (Intact) b.dead = 0;
    else b.dead = (fl0[k] & kBroken) | (fl1[k] & kBroken) << 1 | (fl2[k] & kBroken) << 2 | (fl3[k] & kBroken) << 3;
    const unsigned fresh = law.add(b, f0, f1, f2, w);
    if (fresh) [[unlikely]] mark_fresh(fresh, flag_row, k, newly);
  }
  law.finish(L, v, rows, 4, f0, f1, f2, w, newly, force, tally);
}

// G intact blocks of a stride-1 run side by side, rows i .. i + 4G - 1: per k one neighbour index
// and one broadcast of each slot serve 4G bonds. Each lane's arithmetic is that of block_avx2.
template <int G, class Law>
void blocks_avx2(const Law& law, const BondLaw& L, const BondView& v, const RunSlots& run, std::int32_t i,
                 std::int64_t shift, double* force, BondTally& tally) {
  const double* __restrict px = v.x + shift;
  const double* __restrict py = v.x + v.x_stride + shift;
  const double* __restrict pz = v.x + 2 * v.x_stride + shift;
  const std::int64_t n = run.n;
  const double *sx = run.xi2, *sm = run.measure, *sr = run.inv_xi, *sa = run.measure_per_xi2;
  const std::int32_t* __restrict nbr = run.neighbor;
  __m256d x0[G], x1[G], x2[G], f0[G], f1[G], f2[G], w[G];
  for (int g = 0; g < G; ++g) {
    x0[g] = _mm256_loadu_pd(v.x + i + 4 * g);
    x1[g] = _mm256_loadu_pd(v.x + v.x_stride + i + 4 * g);
    x2[g] = _mm256_loadu_pd(v.x + 2 * v.x_stride + i + 4 * g);
    f0[g] = f1[g] = f2[g] = w[g] = law.zero;
  }
  bool broke = false;
  for (std::int64_t k = 0; k < n; ++k) {
    const std::int64_t j = nbr[k];
    Bonds4 b;
    b.xi2 = _mm256_broadcast_sd(sx + k);
    b.measure = _mm256_broadcast_sd(sm + k);
    b.inv_xi = _mm256_broadcast_sd(sr + k);
    b.measure_per_xi2 = _mm256_broadcast_sd(sa + k);
    b.dead = 0;
    unsigned fresh = 0;
    for (int g = 0; g < G; ++g) {
      b.d0 = _mm256_sub_pd(_mm256_loadu_pd(px + j + 4 * g), x0[g]);
      b.d1 = _mm256_sub_pd(_mm256_loadu_pd(py + j + 4 * g), x1[g]);
      b.d2 = _mm256_sub_pd(_mm256_loadu_pd(pz + j + 4 * g), x2[g]);
      fresh |= law.add(b, f0[g], f1[g], f2[g], w[g]);
    }
    if (fresh) [[unlikely]] {
      broke = true;
      break;
    }
  }
  if (!broke) {
    for (int g = 0; g < G; ++g) {
      const std::int32_t rows[4] = {i + 4 * g, i + 4 * g + 1, i + 4 * g + 2, i + 4 * g + 3};
      const int newly[4] = {0, 0, 0, 0};
      law.finish(L, v, rows, 4, f0[g], f1[g], f2[g], w[g], newly, force, tally);
    }
    return;
  }
  // A bond reached the failure test (nothing is flagged yet): these rows again, block by block,
  // with the flag bookkeeping; the same sums.
  for (int g = 0; g < G; ++g)
    block_avx2<true, true>(law, L, v, run, i + 4 * g, 1, shift + 4 * g, force, tally);
}

// Whether any of the flag bytes [begin, end) is non-zero: 32 at a time, then the tail.
inline bool any_flag(const std::uint8_t* begin, const std::uint8_t* end) {
  __m256i acc = _mm256_setzero_si256();
  for (; begin + 32 <= end; begin += 32)
    acc = _mm256_or_si256(acc, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(begin)));
  std::uint8_t tail = 0;
  for (; begin < end; ++begin) tail |= *begin;
  return tail != 0 || !_mm256_testz_si256(acc, acc);
}

// Any one to four rows (`count`), one per lane: each lane's neighbour positions gathered element
// by element, evaluated by the same law as a block. `Shared`: four rows of one family pattern
// (plan_rows sorts the other rows by pattern), whose slots are broadcast as in a block; otherwise
// the slots are gathered too, and a lane past its row's end (or past `count`) repeats its last
// bond, flagged dead.
template <bool Shared, class Law>
void group_avx2(const Law& law, const BondLaw& L, const BondView& v, const std::int32_t* group, int count,
                double* force, BondTally& tally) {
  const FamilyPatterns& P = *v.patterns;
  const double* px = v.x;
  const double* py = v.x + v.x_stride;
  const double* pz = v.x + 2 * v.x_stride;
  std::int32_t rows[4];
  std::int64_t n[4], b0[4], slot0[4], nmax = 0;
  std::uint8_t* flag_row[4];
  for (int l = 0; l < 4; ++l) {
    rows[l] = group[std::min(l, count - 1)];
    b0[l] = v.offsets[rows[l]];
    n[l] = v.offsets[rows[l] + 1] - b0[l];
    slot0[l] = P.begin[P.of_row[rows[l]]];
    flag_row[l] = v.broken + b0[l];
    if (l < count) nmax = std::max(nmax, n[l]);
  }
  const unsigned idle = 0xFu & ~((1u << count) - 1u);
  const __m256d xi0 = _mm256_setr_pd(px[rows[0]], px[rows[1]], px[rows[2]], px[rows[3]]);
  const __m256d xi1 = _mm256_setr_pd(py[rows[0]], py[rows[1]], py[rows[2]], py[rows[3]]);
  const __m256d xi2 = _mm256_setr_pd(pz[rows[0]], pz[rows[1]], pz[rows[2]], pz[rows[3]]);
  __m256d f0 = law.zero, f1 = law.zero, f2 = law.zero, w = law.zero;
  int newly[4] = {0, 0, 0, 0};
  for (std::int64_t k = 0; k < nmax; ++k) {
    std::int64_t b[4], s[4];
    std::int32_t j[4];
    unsigned dead = idle;
    for (int l = 0; l < 4; ++l) {
      const std::int64_t kk = Shared ? k : std::min(k, n[l] - 1);
      b[l] = b0[l] + kk;
      s[l] = slot0[l] + kk;
      j[l] = v.neighbor[b[l]];
      dead |= (static_cast<unsigned>(k != kk) | (v.broken[b[l]] & kBroken)) << l;
    }
    auto gather = [&](const double* a, const auto* at) {
      return _mm256_setr_pd(a[at[0]], a[at[1]], a[at[2]], a[at[3]]);
    };
    auto slots = [&](const std::vector<double>& a) {
      if constexpr (Shared) return _mm256_broadcast_sd(a.data() + s[0]);
      else return gather(a.data(), s);
    };
    Bonds4 bonds;
    bonds.d0 = _mm256_sub_pd(gather(px, j), xi0);
    bonds.d1 = _mm256_sub_pd(gather(py, j), xi1);
    bonds.d2 = _mm256_sub_pd(gather(pz, j), xi2);
    bonds.xi2 = slots(P.xi2);
    bonds.measure = slots(P.measure);
    bonds.inv_xi = slots(P.inv_xi);
    bonds.measure_per_xi2 = slots(P.measure_per_xi2);
    bonds.dead = dead;
    const unsigned fresh = law.add(bonds, f0, f1, f2, w);
    if (fresh) [[unlikely]] mark_fresh(fresh, flag_row, k, newly);
  }
  law.finish(L, v, rows, count, f0, f1, f2, w, newly, force, tally);
}

// Blocks of an intact run evaluated side by side (ab_forces.sh on a 400 x 400 membrane: two
// blocks 1.15-1.18 times as fast as one; three 0.91 times two: the lane sums then spill).
constexpr int kBlocksAtOnce = 2;
template <ModelKind K, bool Conical, bool Linear, bool Energy>
void loop_avx2(const BondLaw& L, const BondView& v, const RowBlocks& rows, double* force, BondTally& tally) {
  const Avx2Law<K, Conical, Linear, Energy> law(L);
  const FamilyPatterns& P = *v.patterns;
  for (const RowRun& run : rows.runs) {
    const std::int64_t b0 = v.offsets[run.first], slot0 = P.begin[P.of_row[run.first]];
    const RunSlots slots{v.neighbor + b0,           v.offsets[run.first + 1] - b0,  P.xi2.data() + slot0,
                         P.measure.data() + slot0, P.inv_xi.data() + slot0, P.measure_per_xi2.data() + slot0};
    // Blocks without a broken bond (most, in most runs) skip the flag bytes. Whether rows
    // first + l s (l < count) have none: from the rows' summary bytes (BondFamilies::row_broken)
    // where the view has them, else from the flags; for s = 1 either is one range.
    auto intact = [&v](std::int32_t first, std::int32_t s, std::int32_t count) {
      if (s == 1)
        return v.row_broken ? !any_flag(v.row_broken + first, v.row_broken + first + count)
                            : !any_flag(v.broken + v.offsets[first], v.broken + v.offsets[first + count]);
      for (std::int32_t l = 0; l < count; ++l) {
        const std::int32_t r = first + l * s;
        if (v.row_broken ? v.row_broken[r] != 0 : any_flag(v.broken + v.offsets[r], v.broken + v.offsets[r + 1]))
          return false;
      }
      return true;
    };
    if (run.stride == 1) {
      const bool whole_run = intact(run.first, 1, run.count);
      std::int32_t q = 0;
      if (whole_run)
        for (; q + 4 * kBlocksAtOnce <= run.count; q += 4 * kBlocksAtOnce)
          blocks_avx2<kBlocksAtOnce>(law, L, v, slots, run.first + q, q, force, tally);
      for (; q < run.count; q += 4) {
        const std::int32_t i = run.first + q;
        if (whole_run || intact(i, 1, 4)) block_avx2<true, true>(law, L, v, slots, i, 1, q, force, tally);
        else block_avx2<false, true>(law, L, v, slots, i, 1, q, force, tally);
      }
    } else {
      for (std::int32_t q = 0; q < run.count; q += 4) {
        const std::int32_t i = run.first + q * run.stride;
        const std::int64_t shift = static_cast<std::int64_t>(q) * run.stride;
        if (intact(i, run.stride, 4)) block_avx2<true, false>(law, L, v, slots, i, run.stride, shift, force, tally);
        else block_avx2<false, false>(law, L, v, slots, i, run.stride, shift, force, tally);
      }
    }
  }
  const std::size_t nrest = rows.rest.size();
  for (std::size_t r = 0; r < nrest; r += 4) {
    const std::int32_t* group = rows.rest.data() + r;
    const int count = static_cast<int>(std::min<std::size_t>(4, nrest - r));
    const bool shared = count == 4 && P.of_row[group[0]] == P.of_row[group[1]] &&
                        P.of_row[group[0]] == P.of_row[group[2]] && P.of_row[group[0]] == P.of_row[group[3]];
    if (shared) group_avx2<true>(law, L, v, group, count, force, tally);
    else group_avx2<false>(law, L, v, group, count, force, tally);
  }
}
#endif

template <ModelKind K, bool Conical, bool Linear, bool Hard, bool Energy>
void loop(const BondLaw& law, const BondView& v, const RowBlocks& rows, double* force, BondTally& t) {
#if defined(PERI_AVX2)
  if constexpr (!Hard)
    if (v.patterns) return loop_avx2<K, Conical, Linear, Energy>(law, v, rows, force, t);
#endif
  const ScalarLoop<K, Conical, Linear, Hard, Energy> scalar{law};
  scalar(v, rows, force, t);
}

template <ModelKind K, bool Conical, bool Linear, bool Hard>
void dispatch_tail(const BondLaw& law, const BondView& v, const RowBlocks& rows, double* force, bool energy,
                   BondTally& t) {
  if (energy) loop<K, Conical, Linear, Hard, true>(law, v, rows, force, t);
  else loop<K, Conical, Linear, Hard, false>(law, v, rows, force, t);
}

template <ModelKind K, bool Conical>
void dispatch_linear(const BondLaw& law, const BondView& v, const RowBlocks& rows, double* force, bool energy,
                     BondTally& t) {
  const bool hard = K == ModelKind::Membrane && law.hardening;
  if (law.linear_critical) {
    if (hard) dispatch_tail<K, Conical, true, true>(law, v, rows, force, energy, t);
    else dispatch_tail<K, Conical, true, false>(law, v, rows, force, energy, t);
  } else {
    if (hard) dispatch_tail<K, Conical, false, true>(law, v, rows, force, energy, t);
    else dispatch_tail<K, Conical, false, false>(law, v, rows, force, energy, t);
  }
}

template <ModelKind K>
void dispatch_conical(const BondLaw& law, const BondView& v, const RowBlocks& rows, double* force, bool energy,
                      BondTally& t) {
  if (law.conical) dispatch_linear<K, true>(law, v, rows, force, energy, t);
  else dispatch_linear<K, false>(law, v, rows, force, energy, t);
}

}  // namespace

const char* bond_kernel_isa() {
#if defined(PERI_AVX2)
  return "avx2";
#else
  return "portable";
#endif
}

void current_positions(const double* X, const double* u, std::int32_t begin, std::int32_t end,
                       std::int64_t stride, double* x) {
  // One pass over X and u (a pass per plane re-read both from memory three times).
  double* __restrict px = x;
  double* __restrict py = x + stride;
  double* __restrict pz = x + 2 * stride;
  for (std::int64_t i = begin; i < end; ++i) {
    px[i] = X[3 * i] + u[3 * i];
    py[i] = X[3 * i + 1] + u[3 * i + 1];
    pz[i] = X[3 * i + 2] + u[3 * i + 2];
  }
}

RowBlocks plan_rows(const BondView& v, const std::int32_t* rows, std::size_t nrows) {
  RowBlocks plan;
  if (!v.patterns) {
    plan.rest.assign(rows, rows + nrows);
    return plan;
  }
  const FamilyPatterns& P = *v.patterns;
  // Whether list entries a[0..3] continue a run from row `first` with stride s whose next row is
  // its q-th: rows first + (q + l) s, first's pattern, neighbours those of first shifted by (q + l) s.
  auto continues = [&](std::int32_t first, std::int32_t s, std::int32_t q, const std::int32_t* a, std::size_t left) {
    if (left < 4 || s <= 0) return false;
    const std::int64_t b0 = v.offsets[first], n = v.offsets[first + 1] - b0;
    for (std::int32_t l = 0; l < 4; ++l) {
      const std::int64_t shift = static_cast<std::int64_t>(q + l) * s;
      if (a[l] != first + shift || P.of_row[a[l]] != P.of_row[first]) return false;
      const std::int64_t bl = v.offsets[a[l]];
      if (v.offsets[a[l] + 1] - bl != n) return false;
      for (std::int64_t k = 0; k < n; ++k)
        if (v.neighbor[bl + k] != v.neighbor[b0 + k] + shift) return false;
    }
    return true;
  };
  // Takes the longest run starting at list entry a[0] with stride s (0 if there is none).
  auto take_run = [&](const std::int32_t* a, std::size_t left, std::int32_t s) {
    std::int32_t count = 0;
    while (continues(a[0], s, count, a + count, left - static_cast<std::size_t>(count))) count += 4;
    if (count > 0) plan.runs.push_back({a[0], s, count});
    return count;
  };
  // Runs of consecutive rows in list order first (stride 1).
  std::vector<std::int32_t> others;
  for (std::size_t r = 0; r < nrows;) {
    if (const std::int32_t count = take_run(rows + r, nrows - r, 1)) r += static_cast<std::size_t>(count);
    else others.push_back(rows[r++]);
  }
  // The others by family pattern within windows of 4096 rows of the list (stable: in list order
  // within a pattern), so that rows a grid row apart along an edge meet (strided runs) and most
  // remaining groups of four share a pattern (the loop broadcasts its slots), while a window's
  // neighbours stay in cache. The order does not change any row's sum.
  constexpr std::size_t kWindow = 4096;
  for (std::size_t w = 0; w < others.size(); w += kWindow)
    std::stable_sort(others.begin() + w, others.begin() + std::min(others.size(), w + kWindow),
                     [&](std::int32_t a, std::int32_t b) { return P.of_row[a] < P.of_row[b]; });
  for (std::size_t r = 0; r < others.size();) {
    const std::size_t left = others.size() - r;
    const std::int32_t s = left >= 2 ? others[r + 1] - others[r] : 0;
    if (const std::int32_t count = s > 0 ? take_run(others.data() + r, left, s) : 0) r += static_cast<std::size_t>(count);
    else plan.rest.push_back(others[r++]);
  }
  return plan;
}

void bond_forces(const BondLaw& law, const BondView& view, const RowBlocks& rows, double* force,
                 bool with_energy, BondTally& tally) {
  if (law.kind == ModelKind::Membrane)
    dispatch_conical<ModelKind::Membrane>(law, view, rows, force, with_energy, tally);
  else
    dispatch_conical<ModelKind::PMB>(law, view, rows, force, with_energy, tally);
}

void bond_forces(const BondLaw& law, const BondView& view, const std::int32_t* rows, std::size_t nrows,
                 double* force, bool with_energy, BondTally& tally) {
  bond_forces(law, view, plan_rows(view, rows, nrows), force, with_energy, tally);
}

double bond_energy(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t nrows) {
  double total = 0;
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    double w = 0;
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
      if (v.broken[b] & kBroken) continue;
      const std::int32_t j = v.neighbor[b];
      double y2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double d = v.X[3 * j + c] + v.u[3 * j + c] - (v.X[3 * i + c] + v.u[3 * i + c]);
        y2 += d * d;
      }
      const double s2 = v.xi2(i, b);
      w += law.energy(s2, std::max(y2, 1e-12 * s2)) * v.measure(i, b);
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
      const double m = v.measure(i, b);
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
      sum += law.reference_stiffness(v.xi2(i, b)) * v.measure(i, b);
    }
    if (sum > 0) dt = std::min(dt, std::sqrt(2.0 * density / sum));
  }
  return dt;
}

}  // namespace peri
