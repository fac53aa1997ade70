#include "peri/forces.hpp"

#include <algorithm>
#if defined(__AVX512F__) && defined(__AVX512VL__) && defined(__AVX512BW__)
#define PERI_AVX512 1
#include <immintrin.h>
// GCC 12 reports its own intrinsics' _mm512_undefined_* temporaries as maybe-uninitialized.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#elif defined(__AVX2__) && defined(__FMA__)
#define PERI_AVX2 1
#include <immintrin.h>
#endif
#include <cmath>
#include <cstring>
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
}

// The portable loop, specialised at compile time on the law's shape so that no per-bond branch on
// the model remains. `L` is a local copy whose flags are compile-time constants after assignment.
// Serves every law (hardening included) and views without family patterns.
template <ModelKind K, bool Conical, bool Linear, bool Hard, bool Energy>
void loop_scalar(const BondLaw& law_in, const BondView& v, const std::int32_t* rows, std::size_t nrows,
                 double* force, BondTally& tally) {
  BondLaw L = law_in;
  L.kind = K;
  L.conical = Conical;
  L.linear_critical = Linear;
  L.hardening = Hard;
  const double* __restrict x = v.x;
  const std::int32_t* __restrict nbr = v.neighbor;
  std::uint8_t* __restrict flag = v.broken;
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    const double xi0 = x[4 * i], xi1 = x[4 * i + 1], xi2c = x[4 * i + 2];
    double f0 = 0, f1 = 0, f2 = 0, w = 0;
    int newly = 0;
    const std::int64_t b0 = v.offsets[i], b1 = v.offsets[i + 1];
    for (std::int64_t b = b0; b < b1; ++b) {
      const std::int32_t j = nbr[b];
      const double d0 = x[4 * j] - xi0, d1 = x[4 * j + 1] - xi1, d2 = x[4 * j + 2] - xi2c;
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
}

#if defined(PERI_AVX512) || defined(PERI_AVX2)
// Scalar constants of a law for the vector loops (each broadcasts them to its own width).
template <ModelKind K, bool Linear>
struct VectorLawConstants {
  double c_energy, crit0, crit0_sq, inv_crit0_sq, crit_slope, inv_horizon, c_row;
  explicit VectorLawConstants(const BondLaw& L)
      : c_energy(K == ModelKind::Membrane ? L.c : 0.5 * L.c),
        crit0(L.critical0),
        crit0_sq(L.critical0 * L.critical0),
        inv_crit0_sq(1.0 / (L.critical0 * L.critical0)),  // 0 if unbreakable
        crit_slope(Linear ? (L.critical_delta - L.critical0) / L.horizon : 0.0),
        inv_horizon(1.0 / L.horizon),
        c_row(K == ModelKind::Membrane ? 2.0 * L.c : L.c) {}  // applied to the row's sum
};

// Row i's bonds (CSR slices) and its family pattern's slots.
struct RowSlices {
  std::int64_t n;                  // bonds in the row
  const std::int32_t* neighbor;
  std::uint8_t* flag;
  const double *xi2, *measure, *inv_xi, *measure_per_xi2;
};
inline RowSlices row_slices(const BondView& v, std::int32_t i) {
  const FamilyPatterns& P = *v.patterns;
  const std::int64_t b0 = v.offsets[i], slot0 = P.begin[P.of_row[i]];
  return {v.offsets[i + 1] - b0, v.neighbor + b0, v.broken + b0, P.xi2.data() + slot0,
          P.measure.data() + slot0, P.inv_xi.data() + slot0, P.measure_per_xi2.data() + slot0};
}
#endif

#if defined(PERI_AVX512)
// 1/sqrt(d) from the 14-bit hardware estimate and two Newton steps (relative error about 2^-52,
// within an ulp or two of the correctly rounded value): the PMB law's 1/y without a square root
// and a division. (The same for the membrane's one division was slower than vdivpd: 5.0-5.3e8
// against 5.4-7.2e8 bond updates/s in alternating runs of bench_kernels.)
inline __m512d reciprocal_sqrt(__m512d d) {
  const __m512d half = _mm512_set1_pd(0.5), three_halves = _mm512_set1_pd(1.5);
  const __m512d hd = _mm512_mul_pd(half, d);
  __m512d r = _mm512_rsqrt14_pd(d);
  r = _mm512_mul_pd(r, _mm512_fnmadd_pd(hd, _mm512_mul_pd(r, r), three_halves));
  return _mm512_mul_pd(r, _mm512_fnmadd_pd(hd, _mm512_mul_pd(r, r), three_halves));
}

// Lane sums of a, b, c and d, each reduced in one fixed order (so a node's force does not depend
// on which rank computes it): out = {sum a, sum b, sum c, sum d}. Seven shuffles and four adds for
// all four, against six operations per vector for separate reductions.
inline void lane_sums(__m512d a, __m512d b, __m512d c, __m512d d, double out[4]) {
  const __m512d ab = _mm512_add_pd(_mm512_shuffle_f64x2(a, b, _MM_SHUFFLE(1, 0, 1, 0)),
                                   _mm512_shuffle_f64x2(a, b, _MM_SHUFFLE(3, 2, 3, 2)));
  const __m512d cd = _mm512_add_pd(_mm512_shuffle_f64x2(c, d, _MM_SHUFFLE(1, 0, 1, 0)),
                                   _mm512_shuffle_f64x2(c, d, _MM_SHUFFLE(3, 2, 3, 2)));
  const __m512d s = _mm512_add_pd(_mm512_shuffle_f64x2(ab, cd, _MM_SHUFFLE(2, 0, 2, 0)),
                                  _mm512_shuffle_f64x2(ab, cd, _MM_SHUFFLE(3, 1, 3, 1)));
  const __m512d t = _mm512_add_pd(s, _mm512_permute_pd(s, 0x55));
  // Lanes 0, 2, 4, 6 by register extracts (a store and scalar reloads would miss store forwarding).
  out[0] = _mm_cvtsd_f64(_mm512_castpd512_pd128(t));
  out[1] = _mm_cvtsd_f64(_mm512_extractf64x2_pd(t, 1));
  out[2] = _mm_cvtsd_f64(_mm512_extractf64x2_pd(t, 2));
  out[3] = _mm_cvtsd_f64(_mm512_extractf64x2_pd(t, 3));
}

// The same bond law, eight bonds at a time (AVX-512). Per bond: one 256-bit load of the
// neighbour's current position (x, y, z, 0), contiguous loads of the family pattern's |xi|^2 and
// measure term, and the flag byte; no reference positions, measures or weights are gathered.
// (AVX-512 gathers of the three coordinates cost more than the rest of the bond on Zen 4: 3.3e8
// against 8.6e8 bond updates/s with the positions loaded contiguously.)
// Membrane (eq. 15): f_hat / y = 2 c g (1 - r^2) w V_j / xi^2 with r = xi^2 / y^2 = lambda^-2:
// one division, no square root, and the failure test (eq. 11) is r <= lambda_0^-2.
// PMB: f_hat / y = c g (1/xi - 1/y), one reciprocal square root. The law's constant c multiplies
// the row's sum. Full chunks of eight run unmasked; a row's last partial chunk is masked and
// loads its idle lanes' neighbour index as node 0.
template <ModelKind K, bool Conical, bool Linear, bool Energy>
void loop_avx512(const BondLaw& L, const BondView& v, const std::int32_t* rows, std::size_t nrows,
                 double* force, BondTally& tally) {
  const double* __restrict x = v.x;
  const __m512d zero = _mm512_setzero_pd(), one = _mm512_set1_pd(1.0);
  const VectorLawConstants<K, Linear> constants(L);
  const __m512d c_energy = _mm512_set1_pd(constants.c_energy);
  const __m512d tiny = _mm512_set1_pd(1e-12), r_max = _mm512_set1_pd(1e12);
  const __m512d crit0 = _mm512_set1_pd(constants.crit0), crit0_sq = _mm512_set1_pd(constants.crit0_sq);
  const __m512d inv_crit0_sq = _mm512_set1_pd(constants.inv_crit0_sq), crit_slope = _mm512_set1_pd(constants.crit_slope);
  const __m512d inv_horizon = _mm512_set1_pd(constants.inv_horizon);
  const __m128i bit_broken = _mm_set1_epi8(static_cast<char>(kBroken));
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    const __m512d xi0 = _mm512_set1_pd(x[4 * i]), xi1 = _mm512_set1_pd(x[4 * i + 1]),
                  xi2c = _mm512_set1_pd(x[4 * i + 2]);
    const RowSlices row = row_slices(v, i);
    const std::int64_t n = row.n;
    const double *sx = row.xi2, *sm = row.measure, *sr = row.inv_xi, *sa = row.measure_per_xi2;
    const std::int32_t* __restrict row_nbr = row.neighbor;
    std::uint8_t* __restrict row_flag = row.flag;
    __m512d f0 = zero, f1 = zero, f2 = zero, w = zero;
    int newly = 0;
    // Eight bonds from slot k; m marks the lanes in the row, jb their neighbour indices.
    auto chunk = [&](std::int64_t k, __mmask8 m, const std::int32_t* jb) __attribute__((always_inline)) {
      // Neighbour positions: one 256-bit load each (x, y, z, 0), transposed in registers into
      // x, y and z of eight bonds in CSR order.
      auto pos = [x](std::int32_t j) { return _mm256_loadu_pd(x + 4 * static_cast<std::int64_t>(j)); };
      const __m512d a0 = _mm512_insertf64x4(_mm512_castpd256_pd512(pos(jb[0])), pos(jb[2]), 1);
      const __m512d a1 = _mm512_insertf64x4(_mm512_castpd256_pd512(pos(jb[1])), pos(jb[3]), 1);
      const __m512d a2 = _mm512_insertf64x4(_mm512_castpd256_pd512(pos(jb[4])), pos(jb[6]), 1);
      const __m512d a3 = _mm512_insertf64x4(_mm512_castpd256_pd512(pos(jb[5])), pos(jb[7]), 1);
      const __m512d t0 = _mm512_unpacklo_pd(a0, a1), t1 = _mm512_unpackhi_pd(a0, a1);  // x z | y 0
      const __m512d t2 = _mm512_unpacklo_pd(a2, a3), t3 = _mm512_unpackhi_pd(a2, a3);
      const __m512d d0 = _mm512_sub_pd(_mm512_shuffle_f64x2(t0, t2, _MM_SHUFFLE(2, 0, 2, 0)), xi0);
      const __m512d d1 = _mm512_sub_pd(_mm512_shuffle_f64x2(t1, t3, _MM_SHUFFLE(2, 0, 2, 0)), xi1);
      const __m512d d2 = _mm512_sub_pd(_mm512_shuffle_f64x2(t0, t2, _MM_SHUFFLE(3, 1, 3, 1)), xi2c);
      const __m512d s2 = _mm512_mask_loadu_pd(one, m, sx + k);  // 1 in idle lanes: no 0/0
      // (x^2 + z^2) + y^2: two independent products, a shorter dependency chain than nested FMAs.
      const __m512d y2 = _mm512_add_pd(_mm512_fmadd_pd(d2, d2, _mm512_mul_pd(d0, d0)), _mm512_mul_pd(d1, d1));
      __m512d xi = zero, g = one;
      if constexpr (Conical || Linear || (K == ModelKind::PMB && Energy)) xi = _mm512_sqrt_pd(s2);
      if constexpr (Conical) g = _mm512_max_pd(zero, _mm512_fnmadd_pd(xi, inv_horizon, one));
      // Membrane: r = xi^2 / y^2, capped for coincident nodes (as y^2 >= 1e-12 xi^2 in loop_scalar).
      __m512d ratio = one, y2g = y2;
      if constexpr (K == ModelKind::Membrane) ratio = _mm512_min_pd(_mm512_div_pd(s2, y2), r_max);
      else y2g = _mm512_max_pd(y2, _mm512_mul_pd(tiny, s2));
      __mmask8 reached;  // eq. (11): broken once y^2 >= lambda_0(|xi|)^2 |xi|^2 (eq. 29 if linear)
      if constexpr (Linear) {
        const __m512d lc = _mm512_fmadd_pd(crit_slope, xi, crit0);
        reached = _mm512_mask_cmp_pd_mask(m, y2g, _mm512_mul_pd(_mm512_mul_pd(lc, lc), s2), _CMP_GE_OQ);
      } else if constexpr (K == ModelKind::Membrane) {
        reached = _mm512_mask_cmp_pd_mask(m, ratio, inv_crit0_sq, _CMP_LE_OQ);
      } else {
        reached = _mm512_mask_cmp_pd_mask(m, y2g, _mm512_mul_pd(crit0_sq, s2), _CMP_GE_OQ);
      }
      const __mmask8 was = _mm_mask_test_epi8_mask(m, _mm_maskz_loadu_epi8(m, row_flag + k), bit_broken);
      const __mmask8 fresh = reached & static_cast<__mmask8>(~was);
      if (fresh) [[unlikely]] {
        for (int l = 0; l < 8; ++l)
          if (fresh >> l & 1) row_flag[k + l] |= kBroken | kJustBroken;
        newly += __builtin_popcount(fresh);
      }
      const __mmask8 intact = m & static_cast<__mmask8>(~(was | reached));
      __m512d coef;
      if constexpr (K == ModelKind::Membrane) {
        __m512d a = _mm512_maskz_loadu_pd(m, sa + k);  // w V_j / xi^2
        if constexpr (Conical) a = _mm512_mul_pd(g, a);
        coef = _mm512_maskz_fnmadd_pd(intact, a, _mm512_mul_pd(ratio, ratio), a);  // g wV/xi^2 (1 - r^2)
        if constexpr (Energy) {  // eq. (13): c (lambda^2 + lambda^-2 - 2) g = c g (y^2 - xi^2)^2 / (xi^2 y^2)
          const __m512d meas = _mm512_maskz_loadu_pd(m, sm + k);
          const __m512d y2e = _mm512_max_pd(y2, _mm512_mul_pd(tiny, s2));  // as loop_scalar
          const __m512d e = _mm512_sub_pd(y2e, s2);
          const __m512d ge = _mm512_mul_pd(c_energy, Conical ? _mm512_mul_pd(g, meas) : meas);
          w = _mm512_mask_add_pd(w, intact, w, _mm512_div_pd(_mm512_mul_pd(ge, _mm512_mul_pd(e, e)), _mm512_mul_pd(s2, y2e)));
        }
      } else {
        const __m512d meas = _mm512_maskz_loadu_pd(m, sm + k);
        const __m512d gm = Conical ? _mm512_mul_pd(g, meas) : meas;
        const __m512d inv_y = reciprocal_sqrt(y2g), inv_xi = _mm512_mask_loadu_pd(one, m, sr + k);
        coef = _mm512_maskz_mul_pd(intact, gm, _mm512_sub_pd(inv_xi, inv_y));  // c g (1/xi - 1/y)
        if constexpr (Energy) {  // w = c s^2 |xi| g / 2 = (c/2) g (y - xi)^2 / xi
          const __m512d stretch = _mm512_sub_pd(_mm512_sqrt_pd(y2g), xi);
          const __m512d ge = _mm512_mul_pd(c_energy, gm);
          w = _mm512_mask_add_pd(w, intact, w, _mm512_div_pd(_mm512_mul_pd(ge, _mm512_mul_pd(stretch, stretch)), xi));
        }
      }
      f0 = _mm512_fmadd_pd(coef, d0, f0);
      f1 = _mm512_fmadd_pd(coef, d1, f1);
      f2 = _mm512_fmadd_pd(coef, d2, f2);
    };
    std::int64_t k = 0;
    for (; k + 8 <= n; k += 8) chunk(k, __mmask8(0xFF), row_nbr + k);
    if (k < n) {
      const auto m = static_cast<__mmask8>((1u << (n - k)) - 1u);
      alignas(32) std::int32_t tail[8];
      _mm256_store_si256(reinterpret_cast<__m256i*>(tail), _mm256_maskz_loadu_epi32(m, row_nbr + k));
      chunk(k, m, tail);
    }
    double sums[4];
    lane_sums(f0, f1, f2, w, sums);
    force[3 * i] = constants.c_row * sums[0];
    force[3 * i + 1] = constants.c_row * sums[1];
    force[3 * i + 2] = constants.c_row * sums[2];
    if constexpr (Energy) tally.strain_energy += 0.5 * v.volume[i] * sums[3];
    if (newly) book_breaks(L, v, i, newly, tally);
  }
}
#endif

#if defined(PERI_AVX2)
// Lane sums of a, b, c and d in one fixed order: out = {sum a, sum b, sum c, sum d}.
inline void lane_sums4(__m256d a, __m256d b, __m256d c, __m256d d, double out[4]) {
  const __m256d ab = _mm256_hadd_pd(a, b);  // a0+a1 b0+b1 a2+a3 b2+b3
  const __m256d cd = _mm256_hadd_pd(c, d);
  const __m256d s = _mm256_add_pd(_mm256_permute2f128_pd(ab, cd, 0x20), _mm256_permute2f128_pd(ab, cd, 0x31));
  _mm256_storeu_pd(out, s);
}

// The same bond law four bonds at a time (AVX2 + FMA, for CPUs without AVX-512): the arithmetic
// of loop_avx512 on 256-bit vectors. Per bond two 128-bit loads of the neighbour's padded position,
// (x, y) and (z, 0), merged into 256-bit registers and transposed, the family pattern's slots
// loaded contiguously, the flag byte. Masks are whole-lane bit patterns (all ones = true). PMB:
// 1/y as a square root and a division (AVX2 has no double-precision reciprocal square root
// estimate; the single-precision one and three Newton steps ran at 0.64 of this).
template <ModelKind K, bool Conical, bool Linear, bool Energy>
void loop_avx2(const BondLaw& L, const BondView& v, const std::int32_t* rows, std::size_t nrows,
               double* force, BondTally& tally) {
  const double* __restrict x = v.x;
  const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
  const VectorLawConstants<K, Linear> constants(L);
  const __m256d c_energy = _mm256_set1_pd(constants.c_energy);
  const __m256d tiny = _mm256_set1_pd(1e-12), r_max = _mm256_set1_pd(1e12);
  const __m256d crit0 = _mm256_set1_pd(constants.crit0), crit0_sq = _mm256_set1_pd(constants.crit0_sq);
  const __m256d inv_crit0_sq = _mm256_set1_pd(constants.inv_crit0_sq), crit_slope = _mm256_set1_pd(constants.crit_slope);
  const __m256d inv_horizon = _mm256_set1_pd(constants.inv_horizon);
  const __m256i bit_broken = _mm256_set1_epi64x(kBroken);
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    const __m256d xi0 = _mm256_set1_pd(x[4 * i]), xi1 = _mm256_set1_pd(x[4 * i + 1]),
                  xi2c = _mm256_set1_pd(x[4 * i + 2]);
    const RowSlices row = row_slices(v, i);
    const std::int64_t n = row.n;
    const double *sx = row.xi2, *sm = row.measure, *sr = row.inv_xi, *sa = row.measure_per_xi2;
    const std::int32_t* __restrict row_nbr = row.neighbor;
    std::uint8_t* __restrict row_flag = row.flag;
    __m256d f0 = zero, f1 = zero, f2 = zero, w = zero;
    int newly = 0;
    // Four bonds from slot k. Tail: the row's last partial chunk, `live` its lanes (all ones),
    // jb its neighbour indices, and its pattern slots loaded under the mask.
    auto chunk = [&]<bool Tail>(std::int64_t k, const std::int32_t* jb, __m256i live, std::uint32_t flags)
                     __attribute__((always_inline)) {
      // (x, y) of two neighbours per 256-bit register, transposed in registers.
      auto xy = [x](std::int32_t j0, std::int32_t j1) {
        return _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(x + 4 * static_cast<std::int64_t>(j0))),
                                    _mm_loadu_pd(x + 4 * static_cast<std::int64_t>(j1)), 1);
      };
      auto z = [x](std::int32_t j0, std::int32_t j1) {
        return _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(x + 4 * static_cast<std::int64_t>(j0) + 2)),
                                    _mm_loadu_pd(x + 4 * static_cast<std::int64_t>(j1) + 2), 1);
      };
      const __m256d m0 = xy(jb[0], jb[2]), m1 = xy(jb[1], jb[3]);  // x0 y0 x2 y2 | x1 y1 x3 y3
      const __m256d n0 = z(jb[0], jb[2]), n1 = z(jb[1], jb[3]);    // z0 0 z2 0 | z1 0 z3 0
      const __m256d d0 = _mm256_sub_pd(_mm256_unpacklo_pd(m0, m1), xi0);
      const __m256d d1 = _mm256_sub_pd(_mm256_unpackhi_pd(m0, m1), xi1);
      const __m256d d2 = _mm256_sub_pd(_mm256_unpacklo_pd(n0, n1), xi2c);
      __m256d s2;
      if constexpr (Tail) s2 = _mm256_blendv_pd(one, _mm256_maskload_pd(sx + k, live), _mm256_castsi256_pd(live));
      else s2 = _mm256_loadu_pd(sx + k);  // 1 in idle lanes: no 0/0
      auto slots = [&](const double* s) {
        if constexpr (Tail) return _mm256_maskload_pd(s + k, live);
        else return _mm256_loadu_pd(s + k);
      };
      const __m256d y2 = _mm256_add_pd(_mm256_fmadd_pd(d2, d2, _mm256_mul_pd(d0, d0)), _mm256_mul_pd(d1, d1));
      __m256d xi = zero, g = one;
      if constexpr (Conical || Linear || (K == ModelKind::PMB && Energy)) xi = _mm256_sqrt_pd(s2);
      if constexpr (Conical) g = _mm256_max_pd(zero, _mm256_fnmadd_pd(xi, inv_horizon, one));
      __m256d ratio = one, y2g = y2;
      if constexpr (K == ModelKind::Membrane) ratio = _mm256_min_pd(_mm256_div_pd(s2, y2), r_max);
      else y2g = _mm256_max_pd(y2, _mm256_mul_pd(tiny, s2));
      __m256d reached;  // eq. (11), as in loop_avx512
      if constexpr (Linear) {
        const __m256d lc = _mm256_fmadd_pd(crit_slope, xi, crit0);
        reached = _mm256_cmp_pd(y2g, _mm256_mul_pd(_mm256_mul_pd(lc, lc), s2), _CMP_GE_OQ);
      } else if constexpr (K == ModelKind::Membrane) {
        reached = _mm256_cmp_pd(ratio, inv_crit0_sq, _CMP_LE_OQ);
      } else {
        reached = _mm256_cmp_pd(y2g, _mm256_mul_pd(crit0_sq, s2), _CMP_GE_OQ);
      }
      if constexpr (Tail) reached = _mm256_and_pd(reached, _mm256_castsi256_pd(live));
      const __m256i flag_lanes = _mm256_cvtepu8_epi64(_mm_cvtsi32_si128(static_cast<int>(flags)));
      const __m256d was = _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_and_si256(flag_lanes, bit_broken), bit_broken));
      const int fresh = _mm256_movemask_pd(_mm256_andnot_pd(was, reached));
      if (fresh) [[unlikely]] {
        for (int l = 0; l < 4; ++l)
          if (fresh >> l & 1) row_flag[k + l] |= kBroken | kJustBroken;
        newly += __builtin_popcount(static_cast<unsigned>(fresh));
      }
      __m256d dead = _mm256_or_pd(was, reached);  // all ones where the bond adds nothing
      if constexpr (Tail) dead = _mm256_or_pd(dead, _mm256_castsi256_pd(_mm256_xor_si256(live, _mm256_set1_epi64x(-1))));
      __m256d coef;
      if constexpr (K == ModelKind::Membrane) {
        __m256d a = slots(sa);  // w V_j / xi^2
        if constexpr (Conical) a = _mm256_mul_pd(g, a);
        coef = _mm256_andnot_pd(dead, _mm256_fnmadd_pd(a, _mm256_mul_pd(ratio, ratio), a));  // g wV/xi^2 (1 - r^2)
        if constexpr (Energy) {  // eq. (13), as in loop_avx512
          const __m256d meas = slots(sm);
          const __m256d y2e = _mm256_max_pd(y2, _mm256_mul_pd(tiny, s2));
          const __m256d e = _mm256_sub_pd(y2e, s2);
          const __m256d ge = _mm256_mul_pd(c_energy, Conical ? _mm256_mul_pd(g, meas) : meas);
          w = _mm256_add_pd(w, _mm256_andnot_pd(dead, _mm256_div_pd(_mm256_mul_pd(ge, _mm256_mul_pd(e, e)), _mm256_mul_pd(s2, y2e))));
        }
      } else {
        const __m256d meas = slots(sm);
        const __m256d gm = Conical ? _mm256_mul_pd(g, meas) : meas;
        __m256d inv_xi;
        if constexpr (Tail) inv_xi = _mm256_blendv_pd(one, slots(sr), _mm256_castsi256_pd(live));
        else inv_xi = slots(sr);
        const __m256d y = _mm256_sqrt_pd(y2g);
        const __m256d inv_y = _mm256_div_pd(one, y);
        coef = _mm256_andnot_pd(dead, _mm256_mul_pd(gm, _mm256_sub_pd(inv_xi, inv_y)));  // c g (1/xi - 1/y)
        if constexpr (Energy) {  // w = (c/2) g (y - xi)^2 / xi
          const __m256d stretch = _mm256_sub_pd(y, xi);
          const __m256d ge = _mm256_mul_pd(c_energy, gm);
          w = _mm256_add_pd(w, _mm256_andnot_pd(dead, _mm256_div_pd(_mm256_mul_pd(ge, _mm256_mul_pd(stretch, stretch)), xi)));
        }
      }
      f0 = _mm256_fmadd_pd(coef, d0, f0);
      f1 = _mm256_fmadd_pd(coef, d1, f1);
      f2 = _mm256_fmadd_pd(coef, d2, f2);
    };
    std::int64_t k = 0;
    const __m256i all = _mm256_set1_epi64x(-1);
    for (; k + 4 <= n; k += 4) {
      std::uint32_t flags;
      std::memcpy(&flags, row_flag + k, 4);
      chunk.template operator()<false>(k, row_nbr + k, all, flags);
    }
    if (k < n) {
      // Idle lanes repeat the row's last bond (no data-dependent branch); `live` masks them out.
      std::int32_t tail[4];
      std::uint32_t flags = 0;
      for (int l = 0; l < 4; ++l) {
        const std::int64_t b = std::min<std::int64_t>(k + l, n - 1);
        tail[l] = row_nbr[b];
        flags |= static_cast<std::uint32_t>(row_flag[b]) << (8 * l);
      }
      const __m256i live = _mm256_cmpgt_epi64(_mm256_set1_epi64x(n - k), _mm256_setr_epi64x(0, 1, 2, 3));
      chunk.template operator()<true>(k, tail, live, flags);
    }
    double sums[4];
    lane_sums4(f0, f1, f2, w, sums);
    force[3 * i] = constants.c_row * sums[0];
    force[3 * i + 1] = constants.c_row * sums[1];
    force[3 * i + 2] = constants.c_row * sums[2];
    if constexpr (Energy) tally.strain_energy += 0.5 * v.volume[i] * sums[3];
    if (newly) book_breaks(L, v, i, newly, tally);
  }
}
#endif

template <ModelKind K, bool Conical, bool Linear, bool Hard, bool Energy>
void loop(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t n, double* force,
          BondTally& t) {
#if defined(PERI_AVX512)
  if constexpr (!Hard)
    if (v.patterns) return loop_avx512<K, Conical, Linear, Energy>(law, v, rows, n, force, t);
#elif defined(PERI_AVX2)
  if constexpr (!Hard)
    if (v.patterns) return loop_avx2<K, Conical, Linear, Energy>(law, v, rows, n, force, t);
#endif
  loop_scalar<K, Conical, Linear, Hard, Energy>(law, v, rows, n, force, t);
}

template <ModelKind K, bool Conical, bool Linear, bool Hard>
void dispatch_tail(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t n,
                   double* force, bool energy, BondTally& t) {
  if (energy) loop<K, Conical, Linear, Hard, true>(law, v, rows, n, force, t);
  else loop<K, Conical, Linear, Hard, false>(law, v, rows, n, force, t);
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

const char* bond_kernel_isa() {
#if defined(PERI_AVX512)
  return "avx512";
#elif defined(PERI_AVX2)
  return "avx2";
#else
  return "portable";
#endif
}

void current_positions(const double* X, const double* u, std::int32_t begin, std::int32_t end, double* x) {
  for (std::int64_t i = begin; i < end; ++i) {
    for (int c = 0; c < 3; ++c) x[4 * i + c] = X[3 * i + c] + u[3 * i + c];
    x[4 * i + 3] = 0.0;
  }
}

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
