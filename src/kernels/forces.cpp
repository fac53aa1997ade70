#include "peri/kernels/forces.hpp"

#include <algorithm>
#if defined(__AVX2__) && defined(__FMA__)
#define PERI_AVX2 1
#include <immintrin.h>
#if defined(__AVX512F__) && defined(__AVX512VL__)
#define PERI_AVX512VL 1  // eight-lane blocks, and PMB's 1/|y| from the rsqrt14 estimate
#endif
#endif
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>
#include <utility>
#include <vector>

namespace peri {
namespace {

// Flag value: bit 0 = broken.
constexpr std::uint8_t kBroken = 1;

// w_0 = w(lambda_0) w V_j, the energy a bond of reference length^2 s2 and measure w V_j holds
// when it breaks (eqs. 26-27). A bond is detected at the first step past lambda_0; booking w at
// that step's larger stretch would gain energy systematically (first order in dt), w_0 is unbiased.
inline double breaking_energy(const BondLaw& L, double s2, double measure) { return L.critical_energy(s2) * measure; }

// Books `newly` bonds of row i broken during this call, holding `diss` (their breaking_energy
// summed in CSR order), half per end.
inline void book_row(const BondView& v, std::int32_t i, int newly, double diss, BondTally& tally) {
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
    double f0 = 0, f1 = 0, f2 = 0, w = 0, diss = 0;
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
      flag[b] = static_cast<std::uint8_t>(was | (fresh * kBroken));
      newly += fresh;
      const bool intact = !((was & kBroken) | fresh);
      const double scale = v.measure(i, b);
      if (fresh) diss += breaking_energy(L, s2, scale);
      const double k = intact ? L.coefficient(s2, y2) * scale : 0.0;
      f0 += k * d0;
      f1 += k * d1;
      f2 += k * d2;
      if constexpr (Energy) w += intact ? L.energy(s2, y2) * scale : 0.0;
    }
    force[3 * i] = f0;
    force[3 * i + 1] = f1;
    force[3 * i + 2] = f2;
    if constexpr (Energy) {
      tally.strain_energy += 0.5 * v.volume[i] * w;
      if (v.energy_density) v.energy_density[i] = 0.5 * w;
    }
    if (newly) book_row(v, i, newly, diss, tally);
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

// The operations the law uses, on W = 4 lanes (AVX2; lane masks as vectors) or W = 8 (AVX-512;
// lane masks as mask registers). Every lane of either computes the same operations in the same
// order, so a bond's coefficient is the same bits whichever width evaluates it (on AMD Zen 4 an
// eight-lane operation is one instruction over two cycles: twice the bonds in flight for the same
// scheduler entries, which is what bounds this loop's long dependency chain).
struct Simd4 {
  static constexpr int W = 4;
  using V = __m256d;
  using M = __m256d;
  static V zero() { return _mm256_setzero_pd(); }
  static V set1(double a) { return _mm256_set1_pd(a); }
  static V broadcast(const double* a) { return _mm256_broadcast_sd(a); }
  static V loadu(const double* a) { return _mm256_loadu_pd(a); }
  static void storeu(double* a, V x) { _mm256_storeu_pd(a, x); }
  static V add(V a, V b) { return _mm256_add_pd(a, b); }
  static V sub(V a, V b) { return _mm256_sub_pd(a, b); }
  static V mul(V a, V b) { return _mm256_mul_pd(a, b); }
  static V div(V a, V b) { return _mm256_div_pd(a, b); }
  static V min(V a, V b) { return _mm256_min_pd(a, b); }
  static V max(V a, V b) { return _mm256_max_pd(a, b); }
  static V sqrt(V a) { return _mm256_sqrt_pd(a); }
  static V fmadd(V a, V b, V c) { return _mm256_fmadd_pd(a, b, c); }
  static V fnmadd(V a, V b, V c) { return _mm256_fnmadd_pd(a, b, c); }
#if defined(PERI_AVX512VL)
  static V rsqrt14(V a) { return _mm256_rsqrt14_pd(a); }
#endif
  static M ge(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_GE_OQ); }
  static M le(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_LE_OQ); }
  static unsigned bits(M m) { return static_cast<unsigned>(_mm256_movemask_pd(m)); }
  static M with_lanes(M m, unsigned lanes) { return _mm256_or_pd(m, lane_mask(lanes)); }
  static V zero_where(M m, V a) { return _mm256_andnot_pd(m, a); }
  static V fnmadd_or_zero(M m, V a, V b, V c) { return zero_where(m, fnmadd(a, b, c)); }
};
#if defined(PERI_AVX512VL)
struct Simd8 {
  static constexpr int W = 8;
  using V = __m512d;
  using M = __mmask8;
  static V zero() { return _mm512_setzero_pd(); }
  static V set1(double a) { return _mm512_set1_pd(a); }
  static V broadcast(const double* a) { return _mm512_set1_pd(*a); }
  static V loadu(const double* a) { return _mm512_loadu_pd(a); }
  static void storeu(double* a, V x) { _mm512_storeu_pd(a, x); }
  static V add(V a, V b) { return _mm512_add_pd(a, b); }
  static V sub(V a, V b) { return _mm512_sub_pd(a, b); }
  static V mul(V a, V b) { return _mm512_mul_pd(a, b); }
  static V div(V a, V b) { return _mm512_div_pd(a, b); }
  static V min(V a, V b) { return _mm512_min_pd(a, b); }
  static V max(V a, V b) { return _mm512_max_pd(a, b); }
  static V sqrt(V a) { return _mm512_sqrt_pd(a); }
  static V fmadd(V a, V b, V c) { return _mm512_fmadd_pd(a, b, c); }
  static V fnmadd(V a, V b, V c) { return _mm512_fnmadd_pd(a, b, c); }
  static V rsqrt14(V a) { return _mm512_rsqrt14_pd(a); }
  static M ge(V a, V b) { return _mm512_cmp_pd_mask(a, b, _CMP_GE_OQ); }
  static M le(V a, V b) { return _mm512_cmp_pd_mask(a, b, _CMP_LE_OQ); }
  static unsigned bits(M m) { return m; }
  static M with_lanes(M m, unsigned lanes) { return static_cast<M>(m | lanes); }
  static V zero_where(M m, V a) { return _mm512_maskz_mov_pd(static_cast<M>(~m), a); }
  static V fnmadd_or_zero(M m, V a, V b, V c) { return _mm512_maskz_fnmadd_pd(static_cast<M>(~m), a, b, c); }
};
using SimdWide = Simd8;
#else
using SimdWide = Simd4;
#endif

// W bonds, lane l the k-th bond of row l: y = x_j - x_i and the family pattern's slots.
template <class S>
struct Bonds {
  typename S::V d0, d1, d2;
  typename S::V xi2, measure, inv_xi, measure_per_xi2;  // |xi|^2, w V_j, 1/|xi|, w V_j / |xi|^2
  typename S::V y2_floor, y2_break;  // the law's limits on y^2 (VecLaw::limits)
  typename S::V weight, weight_per_xi;  // PMB: g w V_j and g w V_j / |xi| (VecLaw::limits)
  typename S::V xi_len, energy_weight;  // energy calls: |xi| and the slot's energy factor (VecLaw::limits)
  unsigned dead;  // bit l: lane l's bond is broken already, or lane l is idle
};
using Bonds4 = Bonds<Simd4>;

// One bond law on the lanes of S.
// Membrane (eq. 15): f_hat / y = 2 c g (1 - r^2) w V_j / xi^2 with r = xi^2 / y^2 = lambda^-2:
// one division, no square root, and the failure test (eq. 11) is r <= lambda_0^-2.
// PMB: f_hat / y = c g (1/xi - 1/y). The law's constant c multiplies the row's sum (c_row).
template <class S, ModelKind K, bool Conical, bool Linear, bool Energy>
struct VecLaw {
  using Simd = S;
  using V = typename S::V;
  using M = typename S::M;
  static constexpr int W = S::W;
  static constexpr bool kEnergy = Energy;
  double c_row, tiny_s, crit0_s, crit_slope_s, c_energy_s, inv_horizon_s;
  V zero, one, half, rsqrt_c2, rsqrt_c3, tiny, r_max, crit0, crit0_sq, inv_crit0_sq, crit_slope, inv_horizon;
  explicit VecLaw(const BondLaw& L)
      : c_row(K == ModelKind::Membrane ? 2.0 * L.c : L.c),
        tiny_s(1e-12),
        crit0_s(L.critical0),
        crit_slope_s(Linear ? (L.critical_delta - L.critical0) / L.horizon : 0.0),
        c_energy_s(K == ModelKind::Membrane ? L.c : 0.5 * L.c),
        inv_horizon_s(1.0 / L.horizon),
        zero(S::zero()),
        one(S::set1(1.0)),
        half(S::set1(0.5)),
        rsqrt_c2(S::set1(0.375)),
        rsqrt_c3(S::set1(0.3125)),
        tiny(S::set1(1e-12)),
        r_max(S::set1(1e12)),
        crit0(S::set1(L.critical0)),
        crit0_sq(S::set1(L.critical0 * L.critical0)),
        inv_crit0_sq(S::set1(1.0 / (L.critical0 * L.critical0))),  // 0 if unbreakable
        crit_slope(S::set1(crit_slope_s)),
        inv_horizon(S::set1(1.0 / L.horizon)) {}

  // A slot's limits on y^2, which depend on the slot alone: y2_floor = 1e-12 xi^2 (PMB: coincident
  // nodes), y2_break = (lambda_0(xi) xi)^2 (the failure test, eqs. 11 and 29); PMB: its weight;
  // for energy calls |xi| and the factor of the slot's energy (energy_factor). A plan computes
  // them once per family pattern of its runs and law (scalars: the same bits as lane by lane),
  // not once per block. The membrane law with a constant lambda_0 needs no limits outside
  // energy calls (its test is r <= lambda_0^-2).
  static constexpr bool kLimits = K == ModelKind::PMB || Linear || Energy;
  // c_energy_s g w V / |xi| (PMB) or / |xi|^4 (membrane): what a bond's energy density multiplies
  // (coefficient), per slot.
  double energy_factor(double xi_len, double inv_xi, double measure) const {
    const double g = Conical ? std::max(0.0, std::fma(-xi_len, inv_horizon_s, 1.0)) : 1.0;
    const double gm = Conical ? g * measure : measure;
    return K == ModelKind::Membrane ? c_energy_s * gm * ((inv_xi * inv_xi) * (inv_xi * inv_xi))
                                    : c_energy_s * gm * inv_xi;
  }
  // PMB: g w V_j, the slot's weight (g = 1 - |xi|/delta if conical, else 1), and weight / |xi|.
  double weight(double xi2, double inv_xi, double measure) const {
    return Conical ? std::max(0.0, std::fma(-(xi2 * inv_xi), inv_horizon_s, 1.0)) * measure : measure;
  }
  void limits(const double* xi2, const double* inv_xi, const double* measure, std::int64_t n, double* y2_floor,
              double* y2_break, double* weight_of, double* weight_per_xi, double* xi_len,
              double* energy_weight) const {
    for (std::int64_t k = 0; k < n; ++k) {
      const double lc = Linear ? std::fma(crit_slope_s, xi2[k] * inv_xi[k], crit0_s) : crit0_s;
      y2_floor[k] = tiny_s * xi2[k];
      y2_break[k] = Linear ? lc * lc * xi2[k] : (crit0_s * crit0_s) * xi2[k];
      if constexpr (K == ModelKind::PMB) {
        weight_of[k] = weight(xi2[k], inv_xi[k], measure[k]);
        weight_per_xi[k] = weight_of[k] * inv_xi[k];
      }
      xi_len[k] = xi2[k] * inv_xi[k];  // energy calls' (computed for all: cached per pattern)
      energy_weight[k] = energy_factor(xi_len[k], inv_xi[k], measure[k]);
    }
  }
  // The energy slots of gathered lanes (group_avx2), lane by lane as limits() computes them.
  void energy_slots(Bonds<S>& b, const double* xi2, const double* inv_xi, const double* measure,
                    const std::int64_t* slot) const {
    if constexpr (Energy) {
      alignas(64) double xl[W], ew[W];
      for (int l = 0; l < W; ++l) {
        xl[l] = xi2[slot[l]] * inv_xi[slot[l]];
        ew[l] = energy_factor(xl[l], inv_xi[slot[l]], measure[slot[l]]);
      }
      b.xi_len = S::loadu(xl);
      b.energy_weight = S::loadu(ew);
    }
  }
  void limits(Bonds<S>& b) const {
    b.y2_floor = S::mul(tiny, b.xi2);
    if constexpr (K == ModelKind::PMB) {  // as weight(), lane by lane
      b.weight = b.measure;
      if constexpr (Conical) b.weight = S::mul(S::max(zero, S::fnmadd(S::mul(b.xi2, b.inv_xi), inv_horizon, one)), b.measure);
      b.weight_per_xi = S::mul(b.weight, b.inv_xi);
    }
    if constexpr (Linear) {
      const V lc = S::fmadd(crit_slope, S::mul(b.xi2, b.inv_xi), crit0);
      b.y2_break = S::mul(S::mul(lc, lc), b.xi2);
    } else {
      b.y2_break = S::mul(crit0_sq, b.xi2);
    }
  }

  // Adds the four bonds to the lane sums f (force / c_row) and w (energy density); returns the
  // lanes whose bond reaches the failure test now (eq. 11; eq. 29 if linear), which add nothing.
  __attribute__((always_inline)) unsigned add(const Bonds<S>& b, V& f0, V& f1, V& f2,
                                              V& w) const {
    unsigned fresh;
    const V coef = coefficient(b, w, fresh);
    f0 = S::fmadd(coef, b.d0, f0);
    f1 = S::fmadd(coef, b.d1, f1);
    f2 = S::fmadd(coef, b.d2, f2);
    return fresh;
  }

  // What a bond's coefficient needs before its long-latency step, and that step's result: y^2
  // (PMB: floored), and the membrane's r = xi^2 / y^2 or PMB's 1/y estimate (or y itself without
  // AVX-512). A loop may compute the next slot's front while it finishes this one (intact_blocks:
  // software pipelining), the same operations on the same values either way.
  struct Front {
    V y2, y2g, r;
  };
  __attribute__((always_inline)) Front front(const Bonds<S>& b) const {
    Front p;
    // (x^2 + z^2) + y^2: two independent products, a shorter dependency chain than nested FMAs.
    p.y2 = S::add(S::fmadd(b.d2, b.d2, S::mul(b.d0, b.d0)), S::mul(b.d1, b.d1));
    p.y2g = p.y2;
    // Membrane: r = xi^2 / y^2, capped for coincident nodes (as y^2 >= 1e-12 xi^2 in ScalarLoop).
    if constexpr (K == ModelKind::Membrane) {
      p.r = S::min(S::div(b.xi2, p.y2), r_max);
    } else {
      p.y2g = S::max(p.y2, b.y2_floor);
#if defined(PERI_AVX512VL)
      p.r = S::rsqrt14(p.y2g);
#else
      p.r = S::sqrt(p.y2g);
#endif
    }
    return p;
  }

  // The four bonds' f_hat / (y c_row), zero where the bond adds nothing; adds their energy
  // density to w; `fresh`: the lanes whose bond reaches the failure test now.
  __attribute__((always_inline)) V coefficient(const Bonds<S>& b, V& w, unsigned& fresh) const {
    return coefficient(b, front(b), w, fresh);
  }
  __attribute__((always_inline)) V coefficient(const Bonds<S>& b, const Front& p, V& w, unsigned& fresh) const {
    const V s2 = b.xi2;
    const V y2 = p.y2, y2g = p.y2g;
    V xi = zero, g = one;
    // |xi| = |xi|^2 / |xi|: a multiplication by the pattern's 1/|xi|, not a square root.
    if constexpr (Conical && K == ModelKind::Membrane) {  // (PMB: in the slot's weight)
      xi = S::mul(s2, b.inv_xi);
      g = S::max(zero, S::fnmadd(xi, inv_horizon, one));
    }
    V ratio = one;
    if constexpr (K == ModelKind::Membrane) ratio = p.r;
    M reached;
    if constexpr (K == ModelKind::Membrane && !Linear) reached = S::le(ratio, inv_crit0_sq);
    else reached = S::ge(y2g, b.y2_break);
    fresh = static_cast<unsigned>(S::bits(reached)) & ~b.dead & ((1u << W) - 1u);
    const M dead = S::with_lanes(reached, b.dead);  // all ones where the bond adds nothing
    V coef;
    if constexpr (K == ModelKind::Membrane) {
      V a = b.measure_per_xi2;
      if constexpr (Conical) a = S::mul(g, a);
      coef = S::zero_where(dead, S::fnmadd(a, S::mul(ratio, ratio), a));  // g wV/xi^2 (1 - r^2)
      if constexpr (Energy) {  // eq. (13): c (lambda^2 + lambda^-2 - 2) g = c g ((y^2 - xi^2) / xi^2)^2 r
        // (no division beyond r's; c g w V / xi^4 is the slot's energy_weight)
        const V e = S::sub(y2, s2);
        w = S::add(w, S::zero_where(dead, S::mul(b.energy_weight, S::mul(S::mul(e, e), ratio))));
      }
    } else {
#if defined(PERI_AVX512VL)
      // 1/y from AVX-512VL's 14-bit reciprocal square root estimate r and one correction of
      // third order: with e = 1 - y^2 r^2 (|e| < 2^-13), 1/y = r (1 - e)^-1/2
      // = r (1 + e (1/2 + e (3/8 + e 5/16))) + O(e^4 r) (truncation 2^-54: round-off). No square
      // root, no division, which bound this law (the divider alone: 13.3 cycles per four bonds),
      // and a shorter dependency chain than two Newton steps (which this loop's speed follows).
      const V r = p.r;
      const V e = S::fnmadd(y2g, S::mul(r, r), one);
      const V series = S::fmadd(e, S::fmadd(e, rsqrt_c3, rsqrt_c2), half);
      const V inv_y = S::fmadd(S::mul(r, e), series, r);
      const V y = S::mul(y2g, inv_y);
#else
      // 1/y as a square root and a division (AVX2 has no double-precision reciprocal square
      // root estimate; the single-precision one and three Newton steps ran at 0.64 of this).
      const V y = p.r;
      const V inv_y = S::div(one, y);
#endif
      coef = S::fnmadd_or_zero(dead, b.weight, inv_y, b.weight_per_xi);  // c g wV (1/xi - 1/y)
      if constexpr (Energy) {  // w = (c/2) g (y - xi)^2 / xi, (c/2) g w V / xi the slot's energy_weight
        const V stretch = S::sub(y, b.xi_len);
        w = S::add(w, S::zero_where(dead, S::mul(b.energy_weight, S::mul(stretch, stretch))));
      }
    }
    return coef;
  }

  // Writes the rows' force densities and energy (lanes first .. count-1: a run's last block
  // overlaps the one before it by `first` rows) and books their newly broken bonds (`newly`,
  // holding breaking energies `diss`, mark_fresh; nullptr where none can break).
  void finish(const BondView& v, const std::int32_t* rows, int count, V f0, V f1, V f2, V w, const int* newly,
              const double* diss, double* force, BondTally& tally, int first = 0) const {
    double s0[W], s1[W], s2[W], se[W];
    S::storeu(s0, f0);
    S::storeu(s1, f1);
    S::storeu(s2, f2);
    S::storeu(se, w);
    for (int l = first; l < count; ++l) {
      const std::int32_t i = rows[l];
      force[3 * i] = c_row * s0[l];
      force[3 * i + 1] = c_row * s1[l];
      force[3 * i + 2] = c_row * s2[l];
      if constexpr (Energy) {
        tally.strain_energy += 0.5 * v.volume[i] * se[l];
        if (v.energy_density) v.energy_density[i] = 0.5 * se[l];
      }
      // Every lane of a block that can break bonds: the rows' measures then load in order (a
      // row with a broken bond here and there missed the cache and held up the loop); a lane
      // with none adds 0 (the same sums).
      if (newly) {
        tally.dissipated += 0.5 * v.volume[i] * diss[l];
        tally.newly_broken += newly[l];
        if (newly[l] && v.row_broken) v.row_broken[i] = 1;
      }
    }
  }
};

// Flags the fresh lanes' bonds (bond k of lane l's row, CSR position flag_row[l] + k) as broken
// and adds their breaking energy w0(l) to the lane's sum: summed as the bonds break, a row's sum
// is in CSR order.
template <int W, class BreakingEnergy>
inline void mark_fresh(unsigned fresh, std::uint8_t* const* flag_row, std::int64_t k, BreakingEnergy w0, int* newly,
                       double* diss) {
  for (int l = 0; l < W; ++l)
    if (fresh >> l & 1) {
      // A store, not a read-modify-write: the flags of the bonds this loop evaluates are 0 or
      // kBroken (other bits mark lattice bonds), and a fresh bond's is 0. Blocks that keep their
      // dead lanes (RowBlocks::dead_cache_entries) read no flag bytes, so the line is seldom
      // cached, and a load waiting for it held up the loop (with the next change, the fragmenting
      // 64^3 block's step 1.05 times as fast).
      flag_row[l][k] = kBroken;
      ++newly[l];
      diss[l] += w0(l);
    }
}

// Rows first + l stride of a block.
struct RowStep {
  std::int32_t first, stride;
};

// Where an intact block stopped (the slot whose bond reached the failure test) and its lanes'
// sums up to and with that slot (force components, energy; the broken lanes add nothing there),
// per block of W lanes.
template <class S>
struct LaneSums {
  typename S::V f0, f1, f2, w;
};
template <class S, int G>
struct Resume {
  std::int64_t k = 0;   // the slot that broke; the sums hold it (its broken lanes add nothing)
  unsigned fresh[G];    // its broken lanes
  LaneSums<S> sums[G];
};

// What the blocks of one run (RowRun) share: the neighbour list of its first row (n bonds), its
// family pattern's slots and the law's limits of each slot (run_slots).
struct RunSlots {
  const std::int32_t* __restrict neighbor;
  std::int64_t n;
  const double *xi2, *measure, *inv_xi, *measure_per_xi2, *y2_floor, *y2_break, *weight, *weight_per_xi, *xi_len,
      *energy_weight;
  // Slot k on every lane of b (`Energy`: the energy slots too).
  template <bool Energy, class S>
  __attribute__((always_inline)) void broadcast(Bonds<S>& b, std::int64_t k) const {
    b.xi2 = S::broadcast(xi2 + k);
    b.measure = S::broadcast(measure + k);
    b.inv_xi = S::broadcast(inv_xi + k);
    b.measure_per_xi2 = S::broadcast(measure_per_xi2 + k);
    b.y2_floor = S::broadcast(y2_floor + k);
    b.y2_break = S::broadcast(y2_break + k);
    b.weight = S::broadcast(weight + k);
    b.weight_per_xi = S::broadcast(weight_per_xi + k);
    if constexpr (Energy) {
      b.xi_len = S::broadcast(xi_len + k);
      b.energy_weight = S::broadcast(energy_weight + k);
    }
  }
};

// A block of a run: rows i + l s, the k-th neighbours of the four rows nodes j + shift + l s with
// j the run's k-th neighbour. Per four bonds: the neighbours' positions (one vector load of each
// coordinate plane if s = 1, `Unit`; else four loads each), the pattern's slots broadcast, the
// four flag bytes as lane bits unless the block has no broken bond (`Intact`). The first `skip`
// rows were written by the block before (a run's last block ends at the run's end): evaluated
// again, the same bits (their bonds broken there are flagged now), but not written. A strided
// run may shift its neighbours per slot (`slot_shift`, RowRun::slot_shifts; nullptr: by the
// stride): the k-th neighbours of the block are then j + (at + l) t_k, `at` = shift / stride.
template <bool Intact, bool Unit, class Law>
void block_avx2(const Law& law_of, const BondLaw& L, const BondView& v, const RunSlots& run_of, std::int32_t i,
                std::int32_t stride, std::int64_t shift, int skip, double* force, BondTally& tally,
                const std::int32_t* slot_shift = nullptr) {
  const Law law = law_of;  // local copies, as in damaged_block
  const RunSlots run = run_of;
  const double* __restrict px = v.x + shift;
  const double* __restrict py = v.x + v.x_stride + shift;
  const double* __restrict pz = v.x + 2 * v.x_stride + shift;
  const std::int64_t s = Unit ? 1 : stride;
  const std::int32_t rows[4] = {i, static_cast<std::int32_t>(i + s), static_cast<std::int32_t>(i + 2 * s),
                                static_cast<std::int32_t>(i + 3 * s)};
  auto lanes = [](const double* p, std::int64_t at, std::int64_t t) {
    if constexpr (Unit) return _mm256_loadu_pd(p + at);
    else return _mm256_setr_pd(p[at], p[at + t], p[at + 2 * t], p[at + 3 * t]);
  };
  const std::int64_t block_at = Unit || !slot_shift ? 0 : shift / stride;
  const std::int64_t n = run.n;
  const std::int32_t* __restrict nbr = run.neighbor;
  std::uint8_t* const flag_row[4] = {v.broken + v.offsets[rows[0]], v.broken + v.offsets[rows[1]],
                                     v.broken + v.offsets[rows[2]], v.broken + v.offsets[rows[3]]};
  const std::uint8_t *fl0 = flag_row[0], *fl1 = flag_row[1], *fl2 = flag_row[2], *fl3 = flag_row[3];
  const __m256d xi0 = lanes(v.x, i, s), xi1 = lanes(v.x + v.x_stride, i, s), xi2 = lanes(v.x + 2 * v.x_stride, i, s);
  __m256d f0 = law.zero, f1 = law.zero, f2 = law.zero, w = law.zero;
  int newly[4] = {0, 0, 0, 0};
  double diss[4] = {0, 0, 0, 0};
  for (std::int64_t k = 0; k < n; ++k) {
    std::int64_t j = nbr[k], t = s;
    if (!Unit && slot_shift) {  // positions relative to v.x itself: px - shift
      t = slot_shift[k];
      j += block_at * t - shift;
    }
    Bonds4 b;
    b.d0 = _mm256_sub_pd(lanes(px, j, t), xi0);
    b.d1 = _mm256_sub_pd(lanes(py, j, t), xi1);
    b.d2 = _mm256_sub_pd(lanes(pz, j, t), xi2);
    run.template broadcast<Law::kEnergy>(b, k);
    if constexpr (Intact) b.dead = 0;
    else b.dead = (fl0[k] & kBroken) | (fl1[k] & kBroken) << 1 | (fl2[k] & kBroken) << 2 | (fl3[k] & kBroken) << 3;
    const unsigned fresh = law.add(b, f0, f1, f2, w);
    if (fresh) [[unlikely]] {
      const double w0 = breaking_energy(L, run.xi2[k], run.measure[k]);  // the slot's, for every lane
      mark_fresh<4>(fresh, flag_row, k, [w0](int) { return w0; }, newly, diss);
    }
  }
  law.finish(v, rows, 4, f0, f1, f2, w, newly, diss, force, tally, skip);
}

using SlotSegment = RowBlocks::Scratch::Segment;

// Slots k = next(), next(), ... (-1: none left) of one block, software-pipelined: the next slot's
// bond vectors and front (VecLaw::front: up to the law's long-latency step, from start(k, b)) are
// computed before this slot is finished (finish(k, b, front); false stops the loop, as do the
// slots running out). The same operations on the same values as slot by slot, in a different
// order: fewer operations wait on one slot's long dependency chain at once, and the out-of-order
// window, not the FMA ports, bounds this loop (the intact 64^3 block: 1.08 times as fast; the
// 400^2 membrane's boxes, Produce slots included: 1.03-1.04). The empty asm pins the next slot's
// front before this slot's finish; without it the compiler sinks it back into the next
// iteration. Returns false if finish stopped the loop.
template <class Law, class Next, class Start, class Finish>
__attribute__((always_inline)) inline bool pipelined_slots(Next next, Start start, Finish finish) {
  using Front = typename Law::Front;
  std::int64_t k = next();
  if (k < 0) return true;
  Bonds<typename Law::Simd> b;
  Front p = start(k, b);
  for (std::int64_t after = next(); after >= 0; after = next()) {
    Bonds<typename Law::Simd> b_next;
    Front p_next = start(after, b_next);
    __asm__ volatile("" : "+v"(p_next.r), "+v"(p_next.y2g), "+v"(b_next.d0), "+v"(b_next.d1), "+v"(b_next.d2));
    if (!finish(k, b, p)) return false;
    k = after;
    b = b_next;
    p = p_next;
  }
  return finish(k, b, p);
}

// G blocks of W = Law::W rows of an intact run side by side, rows rows_at.first + l rows_at.stride
// (l < G W) at lanes a .. a + G W - 1 of the run, their own positions at `own` .. of v.x (the rows
// themselves in a stride-1 run; a mirrored run's places, RowBlocks::mirror_slots): per slot one neighbour index and one broadcast of each
// pattern slot serve G W bonds, each lane's arithmetic that of block_avx2. The slots come in
// `segments` of one kind, in CSR order (a run outside boxes: one Own segment of all its slots; a
// line of a box, RowBox: in the natural order a few long ones). Own and Produce slots are
// evaluated (Produce also stores the coefficients at at[k] + a, the partners' places in the box's
// ring); Consume slots load the coefficients their partners stored. Returns false, having
// written nothing but ring entries, if a bond reaches the failure test: the caller takes these
// rows through the flagging loop, from the start (boxes) or, with `resume` (runs outside boxes:
// one Own segment), after that slot k with the lane sums up to it, booking its broken lanes
// (damaged_block: the same sums, no slot evaluated twice). The first `skip` rows were written
// already.
template <int G, class Law>
bool intact_blocks(const Law& law, const BondView& v, const RunSlots& run,
                   const SlotSegment* segments, std::size_t nsegments, double* const* at, RowStep rows_at,
                   std::int64_t own, std::int64_t a, int skip, double* force, BondTally& tally,
                   Resume<typename Law::Simd, G>* resume = nullptr) {
  const double* __restrict px = v.x + a;
  const double* __restrict py = v.x + v.x_stride + a;
  const double* __restrict pz = v.x + 2 * v.x_stride + a;
  const std::int32_t* __restrict nbr = run.neighbor;
  using S = typename Law::Simd;
  using V = typename S::V;
  constexpr int W = S::W;
  V x0[G], x1[G], x2[G], f0[G], f1[G], f2[G], w[G];
  for (int g = 0; g < G; ++g) {
    x0[g] = S::loadu(v.x + own + W * g);
    x1[g] = S::loadu(v.x + v.x_stride + own + W * g);
    x2[g] = S::loadu(v.x + 2 * v.x_stride + own + W * g);
    f0[g] = f1[g] = f2[g] = w[g] = law.zero;
  }
  // One block (G = 1), slots [k0, k1) (Produce: storing their coefficients too): pipelined_slots.
  auto evaluate_pipelined = [&](std::int64_t k0, std::int64_t k1, auto produce) __attribute__((always_inline)) {
    const V o0 = x0[0], o1 = x1[0], o2 = x2[0];
    V s0 = f0[0], s1 = f1[0], s2 = f2[0], sw = w[0];
    std::int64_t k_next = k0;
    const bool whole = pipelined_slots<Law>(
        [&]() -> std::int64_t { return k_next < k1 ? k_next++ : -1; },
        [&](std::int64_t k, Bonds<S>& b) __attribute__((always_inline)) {
          const std::int64_t j = nbr[k];
          run.template broadcast<Law::kEnergy>(b, k);
          b.dead = 0;
          b.d0 = S::sub(S::loadu(px + j), o0);
          b.d1 = S::sub(S::loadu(py + j), o1);
          b.d2 = S::sub(S::loadu(pz + j), o2);
          return law.front(b);
        },
        [&](std::int64_t k, const Bonds<S>& b, const typename Law::Front& p) __attribute__((always_inline)) {
          unsigned lanes;
          const V coef = law.coefficient(b, p, sw, lanes);
          if constexpr (decltype(produce)::value) S::storeu(at[k] + a, coef);
          s0 = S::fmadd(coef, b.d0, s0);
          s1 = S::fmadd(coef, b.d1, s1);
          s2 = S::fmadd(coef, b.d2, s2);
          if (lanes) [[unlikely]] {  // the sums hold slot k (its broken lanes add nothing)
            if (resume) {
              resume->k = k;
              resume->fresh[0] = lanes;
            }
            return false;
          }
          return true;
        });
    f0[0] = s0;
    f1[0] = s1;
    f2[0] = s2;
    w[0] = sw;
    return whole;
  };
  // Evaluates slots [k0, k1) (Produce: storing their coefficients too); false if one breaks.
  auto evaluate = [&](std::int32_t k0, std::int32_t k1, auto produce) {
    if constexpr (G == 1) {
      return evaluate_pipelined(k0, k1, produce);
    } else {  // several blocks side by side (AVX2's two of four lanes)
      for (std::int64_t k = k0; k < k1; ++k) {
        const std::int64_t j = nbr[k];
        Bonds<S> b;
        run.template broadcast<Law::kEnergy>(b, k);
        b.dead = 0;
        unsigned fresh = 0;
        for (int g = 0; g < G; ++g) {
          b.d0 = S::sub(S::loadu(px + j + W * g), x0[g]);
          b.d1 = S::sub(S::loadu(py + j + W * g), x1[g]);
          b.d2 = S::sub(S::loadu(pz + j + W * g), x2[g]);
          unsigned lanes;
          const V coef = law.coefficient(b, w[g], lanes);
          fresh |= lanes;
          if constexpr (decltype(produce)::value) S::storeu(at[k] + a + W * g, coef);
          f0[g] = S::fmadd(coef, b.d0, f0[g]);
          f1[g] = S::fmadd(coef, b.d1, f1[g]);
          f2[g] = S::fmadd(coef, b.d2, f2[g]);
        }
        if (fresh) [[unlikely]] {
          if (resume) {  // the lanes that broke, group by group (the same bits again)
            resume->k = k;
            for (int g = 0; g < G; ++g) {
              b.d0 = S::sub(S::loadu(px + j + W * g), x0[g]);
              b.d1 = S::sub(S::loadu(py + j + W * g), x1[g]);
              b.d2 = S::sub(S::loadu(pz + j + W * g), x2[g]);
              V scratch = law.zero;
              law.coefficient(b, scratch, resume->fresh[g]);
            }
          }
          return false;
        }
      }
      return true;
    }
  };
  for (std::size_t s = 0; s < nsegments; ++s) {
    const SlotSegment seg = segments[s];
    if (seg.kind == BoxSlot::Consume) {
      for (std::int64_t k = seg.begin; k < seg.end; ++k) {
        const std::int64_t j = nbr[k];
        for (int g = 0; g < G; ++g) {
          const V coef = S::loadu(at[k] + a + W * g);
          f0[g] = S::fmadd(coef, S::sub(S::loadu(px + j + W * g), x0[g]), f0[g]);
          f1[g] = S::fmadd(coef, S::sub(S::loadu(py + j + W * g), x1[g]), f1[g]);
          f2[g] = S::fmadd(coef, S::sub(S::loadu(pz + j + W * g), x2[g]), f2[g]);
        }
      }
    } else if (seg.kind == BoxSlot::Produce) {
      if (!evaluate(seg.begin, seg.end, std::true_type{})) return false;
    } else if (!evaluate(seg.begin, seg.end, std::false_type{})) {
      if (resume)
        for (int g = 0; g < G; ++g) resume->sums[g] = {f0[g], f1[g], f2[g], w[g]};
      return false;
    }
  }
  for (int g = 0; g < G; ++g) {
    std::int32_t rows[W];
    for (int l = 0; l < W; ++l) rows[l] = rows_at.first + (W * g + l) * rows_at.stride;
    law.finish(v, rows, W, f0[g], f1[g], f2[g], w[g], nullptr, nullptr, force, tally, std::clamp(skip - W * g, 0, W));
  }
  return true;
}

// The broken flags of W rows of a run (n bonds each, row l's at flag_row[l]) as one byte per
// slot k, bit l set if lane l's bond is broken: 32 slots at a time (a flag byte masked to its
// broken bit, shifted by l within its 16-bit word, stays in its byte), the last 32 ending at n
// (overlapping the ones before: the same bytes again); fewer than 32 slots one by one.
template <int W>
inline void dead_lanes(std::uint8_t* const* flag_row, std::int64_t n, std::uint8_t* dead) {
  const __m256i broken = _mm256_set1_epi8(static_cast<char>(kBroken));
  auto chunk = [&](std::int64_t k) {
    __m256i acc = _mm256_setzero_si256();
    for (int l = 0; l < W; ++l) {
      const __m256i f = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(flag_row[l] + k));
      acc = _mm256_or_si256(acc, _mm256_slli_epi16(_mm256_and_si256(f, broken), l));
    }
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(dead + k), acc);
  };
  std::int64_t k = 0;
  for (; k + 32 <= n; k += 32) chunk(k);
  if (k < n && n >= 32) {
    chunk(n - 32);
    return;
  }
  for (; k < n; ++k) {
    unsigned d = 0;
    for (int l = 0; l < W; ++l) d |= static_cast<unsigned>(flag_row[l][k] & kBroken) << l;
    dead[k] = static_cast<std::uint8_t>(d);
  }
}

// The slots k < n not broken on every lane (dead[k] != all W bits) as bit masks, 32 slots per
// mask (live[k / 32] bit k % 32).
template <int W>
inline void live_slots(const std::uint8_t* dead, std::int64_t n, std::uint32_t* live) {
  const __m256i all = _mm256_set1_epi8(static_cast<char>((1u << W) - 1u));
  std::int64_t k = 0;
  for (; k + 32 <= n; k += 32) {
    const __m256i d = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(dead + k));
    live[k / 32] = ~static_cast<std::uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(d, all)));
  }
  if (k < n) {
    std::uint32_t bits = 0;
    for (std::int64_t q = k; q < n; ++q) bits |= static_cast<std::uint32_t>(dead[q] != (1u << W) - 1u) << (q - k);
    live[k / 32] = bits;
  }
}

// W = Law::W rows of a run with broken bonds among them, rows.first + l rows.stride, at lanes
// a .. of the run, their own positions at `own` .. of v.x (the rows themselves in a stride-1 run;
// a mirrored run's places, RowBlocks::mirror_slots): each lane's arithmetic that of block_avx2
// (a broken bond adds nothing; a fully broken slot is skipped), the flags read once per block as
// lane bits (dead_lanes; the slots left, live_slots); bonds reaching the failure test are flagged
// (mark_fresh). The first `skip` rows were written by the block before (a run's last block).
// `entry`: the block's place in the plan's cache of dead lanes (RowBlocks::Scratch::dead_cache,
// with the live slots' bits in live_cache), or -1: the lane bits and live slots come from there
// once known, else from the flags (and are kept there).
// `from` (an intact block that stopped at a breaking slot, intact_blocks): the rows had no broken
// bond before this call; the loop books that slot's broken lanes and goes on after it with the
// sums so far.
template <class Law>
void damaged_block(const Law& law_of, const BondLaw& L, const BondView& v, const RunSlots& run_of, RowStep rows_at,
                   std::int64_t own, std::int64_t a, int skip, RowBlocks::Scratch& scratch, std::int64_t entry,
                   double* force, BondTally& tally, const LaneSums<typename Law::Simd>* from = nullptr,
                   std::int64_t from_k = 0, unsigned from_fresh = 0) {
  // Local copies of the law's constants and the run's slot pointers: booking a broken bond writes
  // flag bytes, which may alias anything, and the compiler then reloaded both on every slot.
  const Law law = law_of;
  const RunSlots run = run_of;
  using S = typename Law::Simd;
  using V = typename S::V;
  constexpr int W = S::W;
  const std::int64_t n = run.n;
  std::int32_t rows[W];
  std::uint8_t* flag_row[W];
  for (int l = 0; l < W; ++l) {
    rows[l] = rows_at.first + l * rows_at.stride;
    flag_row[l] = v.broken + v.offsets[rows[l]];
  }
  std::uint8_t* __restrict dead =
      entry >= 0 ? scratch.dead_cache.data() + entry * scratch.dead_stride : scratch.dead_lanes.data();
  std::uint32_t* __restrict live = entry >= 0 ? scratch.live_cache.data() + entry * scratch.live_words : scratch.live.data();
  if (entry < 0 || !scratch.dead_known[static_cast<std::size_t>(entry)]) {
    if (from) std::fill(dead, dead + n, std::uint8_t{0});  // intact rows
    else dead_lanes<W>(flag_row, n, dead);
    live_slots<W>(dead, n, live);
    if (entry >= 0) scratch.dead_known[static_cast<std::size_t>(entry)] = 1;
  }
  const double* __restrict px = v.x + a;
  const double* __restrict py = v.x + v.x_stride + a;
  const double* __restrict pz = v.x + 2 * v.x_stride + a;
  const std::int32_t* __restrict nbr = run.neighbor;
  const V x0 = S::loadu(v.x + own), x1 = S::loadu(v.x + v.x_stride + own), x2 = S::loadu(v.x + 2 * v.x_stride + own);
  V f0 = law.zero, f1 = law.zero, f2 = law.zero, w = law.zero;
  int newly[W] = {};
  double diss[W] = {};
  // Flags and books slot k's bonds breaking now on lanes `fresh`, and keeps the lane bits.
  auto book_fresh = [&](std::int64_t k, unsigned fresh) {
    const double w0 = breaking_energy(L, run.xi2[k], run.measure[k]);  // the slot's, for every lane
    mark_fresh<W>(fresh, flag_row, k, [w0](int) { return w0; }, newly, diss);
    dead[k] = static_cast<std::uint8_t>(dead[k] | fresh);
    if (dead[k] == (1u << W) - 1u) live[k / 32] &= ~(std::uint32_t{1} << (k % 32));  // broken on every lane now
  };
  auto slot = [&](std::int64_t k) __attribute__((always_inline)) {
    const std::int64_t j = nbr[k];
    Bonds<S> b;
    b.d0 = S::sub(S::loadu(px + j), x0);
    b.d1 = S::sub(S::loadu(py + j), x1);
    b.d2 = S::sub(S::loadu(pz + j), x2);
    run.template broadcast<Law::kEnergy>(b, k);
    b.dead = dead[k];
    const unsigned fresh = law.add(b, f0, f1, f2, w);
    if (fresh) [[unlikely]] book_fresh(k, fresh);
  };
  // The live slots' bits one by one (no branch per slot, which a fully broken slot here and there
  // mispredicts), kept with the cached lanes from call to call. (AB_STATE on the 64^3 block of
  // compare_lammps.py, steps 15 and 50: 1.03 times as fast as a choice per block between these
  // bits and a branch per slot, whose two loops made each other's code worse.)
  if (from) {
    f0 = from->f0;
    f1 = from->f1;
    f2 = from->f2;
    w = from->w;
    if (from_fresh) book_fresh(from_k, from_fresh);
    for (std::int64_t k = from_k + 1; k < n; ++k) slot(k);  // no slot broken before this call
  } else {
    for (std::int64_t c = 0; c < n; c += 32)
      for (std::uint32_t bits = live[c / 32]; bits; bits &= bits - 1) slot(c + __builtin_ctz(bits));
  }
  law.finish(v, rows, W, f0, f1, f2, w, newly, diss, force, tally, skip);
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
void group_avx2(const Law& law_of, const BondLaw& L, const BondView& v, const std::int32_t* group, int count,
                double* force, BondTally& tally) {
  const Law law = law_of;  // a local copy, as in damaged_block
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
  double diss[4] = {0, 0, 0, 0};
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
    law.limits(bonds);
    law.energy_slots(bonds, P.xi2.data(), P.inv_xi.data(), P.measure.data(), s);
    bonds.dead = dead;
    const unsigned fresh = law.add(bonds, f0, f1, f2, w);
    if (fresh) [[unlikely]]
      mark_fresh<4>(fresh, flag_row, k, [&](int l) { return breaking_energy(L, P.xi2[s[l]], P.measure[s[l]]); },
                    newly, diss);
  }
  law.finish(v, rows, count, f0, f1, f2, w, newly, diss, force, tally);
}

// Whether rows first + l s (l < count) have no broken bond: from the rows' summary bytes
// (BondFamilies::row_broken) where the view has them, else from the flags; for s = 1 either is
// one range.
inline bool rows_intact(const BondView& v, std::int32_t first, std::int32_t s, std::int32_t count) {
  if (s == 1)
    return v.row_broken ? !any_flag(v.row_broken + first, v.row_broken + first + count)
                        : !any_flag(v.broken + v.offsets[first], v.broken + v.offsets[first + count]);
  for (std::int32_t l = 0; l < count; ++l) {
    const std::int32_t r = first + l * s;
    if (v.row_broken ? v.row_broken[r] != 0 : any_flag(v.broken + v.offsets[r], v.broken + v.offsets[r + 1]))
      return false;
  }
  return true;
}

// The run's slots, and the law's limits of each (into the plan's scratch: RowBlocks::Scratch).
template <class Law>
RunSlots run_slots(const Law& law, const BondView& v, const RowBlocks& plan, const RowRun& run) {
  const FamilyPatterns& P = *v.patterns;
  RowBlocks::Scratch& scratch = plan.scratch;
  const std::int64_t b0 = v.offsets[run.first], n = v.offsets[run.first + 1] - b0;
  const std::int64_t slot0 = P.begin[P.of_row[run.first]];
  const std::int64_t at = plan.limits_at[static_cast<std::size_t>(run.limits)];
  if constexpr (Law::kLimits) {
    // Once per pattern and law (the runs of a 3D block switch patterns at every face line: with
    // the last pattern's limits alone, the 32^3 block of compare_lammps.py computed them 2.7% of
    // its step).
    const RowBlocks::Scratch::LimitsKey key{law.crit0_s, law.crit_slope_s, law.c_energy_s, law.inv_horizon_s};
    if (!(key == scratch.limits_of)) {
      std::fill(scratch.limits_known.begin(), scratch.limits_known.end(), 0);
      scratch.limits_of = key;
    }
    if (!scratch.limits_known[static_cast<std::size_t>(run.limits)]) {
      law.limits(P.xi2.data() + slot0, P.inv_xi.data() + slot0, P.measure.data() + slot0, n,
                 scratch.y2_floor.data() + at, scratch.y2_break.data() + at, scratch.weight.data() + at,
                 scratch.weight_per_xi.data() + at, scratch.xi_len.data() + at, scratch.energy_weight.data() + at);
      scratch.limits_known[static_cast<std::size_t>(run.limits)] = 1;
    }
  }
  return {v.neighbor + b0,          n,
          P.xi2.data() + slot0,     P.measure.data() + slot0,
          P.inv_xi.data() + slot0,  P.measure_per_xi2.data() + slot0,
          scratch.y2_floor.data() + at,  scratch.y2_break.data() + at,
          scratch.weight.data() + at,    scratch.weight_per_xi.data() + at,
          scratch.xi_len.data() + at,    scratch.energy_weight.data() + at};
}

// The current positions of the plan's mirror columns (RowBlocks::mirror_columns), copied.
inline void refresh_mirror(const BondView& v, const RowBlocks& plan) {
  double* const mirror = plan.scratch.mirror.data();
  for (const MirrorColumn& c : plan.mirror_columns)
    for (int d = 0; d < 3; ++d) {
      const double* __restrict from = v.x + d * v.x_stride + c.node;
      double* __restrict to = mirror + d * plan.mirror_stride + c.at;
      for (std::int64_t m = 0; m < c.length; ++m) to[m] = from[m * c.step];
    }
}

// The laws of one loop: four lanes (every block) and the widest this CPU has (blocks of intact
// stride-1 runs).
template <ModelKind K, bool Conical, bool Linear, bool Energy>
struct Laws {
  VecLaw<Simd4, K, Conical, Linear, Energy> narrow;
  VecLaw<SimdWide, K, Conical, Linear, Energy> wide;
  explicit Laws(const BondLaw& L) : narrow(L), wide(L) {}
};

// Rows of an intact run evaluated at once: eight, as one block of eight lanes (AVX-512) or two
// blocks of four side by side (AVX2; ab_forces.sh on a 400 x 400 membrane: two blocks 1.15-1.18
// times as fast as one, three 0.91 times two: the lane sums then spill). Eight lanes against two
// blocks of four, AVX-512 on AMD Zen 4: 1.29 (PMB).
constexpr int kWideRows = 8;
constexpr int kWideBlocks = kWideRows / SimdWide::W;

// Rows q .. of a stride-1 run, four at a time, the last block ending at the run's end. `intact`:
// these rows had no broken bond when the call began (the rows an overlapping last block shares
// with the block before may have some now).
template <class Law>
void narrow_blocks(const Law& law, const BondLaw& L, const BondView& v, const RunSlots& slots, const RowRun& run,
                   std::int32_t q, bool intact, double* force, BondTally& tally) {
  for (; q < run.count; q += 4) {
    const std::int32_t at = std::min(q, run.count - 4), i = run.first + at;
    if ((intact && at == q) || rows_intact(v, i, 1, 4)) block_avx2<true, true>(law, L, v, slots, i, 1, at, q - at, force, tally);
    else block_avx2<false, true>(law, L, v, slots, i, 1, at, q - at, force, tally);
  }
}

// One run, block by block. Blocks without a broken bond (most, in most runs) skip the flag bytes;
// stride-1 blocks of eight rows take the widest lanes either way.
// Entry e of the run's blocks in the plan's cache of dead lanes (-1 where it has none), allocated
// at the first damaged block (a body that never breaks holds none).
inline std::int64_t cache_entry(const RowBlocks& plan, const RowRun& run, std::int32_t e) {
  if (run.dead_cache < 0) return -1;
  RowBlocks::Scratch& scratch = plan.scratch;
  if (scratch.dead_known.empty()) {
    scratch.dead_known.assign(static_cast<std::size_t>(plan.dead_cache_entries), 0);
    scratch.dead_cache.assign(static_cast<std::size_t>(plan.dead_cache_entries * scratch.dead_stride), 0);
    scratch.live_cache.assign(static_cast<std::size_t>(plan.dead_cache_entries * scratch.live_words), 0);
  }
  return run.dead_cache + e;
}

// A strided run of eight rows or more from the plan's mirror (RowBlocks::mirror_columns), as a
// stride-1 run: eight rows at a time (the last block ending at the run's end), the neighbours'
// positions one vector load per coordinate, fully broken slots skipped.
template <class Laws>
void mirrored_run(const Laws& laws, const BondLaw& L, const BondView& v, const RowBlocks& plan, const RowRun& run,
                  const RunSlots& slots, double* force, BondTally& tally) {
  BondView mv = v;
  mv.x = plan.scratch.mirror.data();
  mv.x_stride = plan.mirror_stride;
  RunSlots ms = slots;
  const std::int32_t* places = plan.mirror_slots.data() + run.mirror;
  ms.neighbor = places + 1;
  const SlotSegment all{BoxSlot::Own, 0, static_cast<std::int32_t>(slots.n)};
  for (std::int32_t q = 0; q < run.count; q += kWideRows) {
    const std::int32_t at = std::min(q, run.count - kWideRows);
    const int skip = q - at;
    const RowStep rows{run.first + at * run.stride, run.stride};
    Resume<SimdWide, kWideBlocks> resume;
    const bool intact = rows_intact(v, rows.first, rows.stride, kWideRows);
    if (intact && intact_blocks<kWideBlocks>(laws.wide, mv, ms, &all, 1, nullptr, rows, places[0] + at, at, skip,
                                             force, tally, &resume))
      continue;
    for (int g = 0; g < kWideBlocks; ++g) {
      const std::int32_t lane = at + g * SimdWide::W;
      damaged_block(laws.wide, L, mv, ms, RowStep{run.first + lane * run.stride, run.stride}, places[0] + lane, lane,
                    std::clamp(skip - g * SimdWide::W, 0, SimdWide::W), plan.scratch,
                    cache_entry(plan, run, q / kWideRows * kWideBlocks + g), force, tally,
                    intact ? &resume.sums[g] : nullptr, resume.k, intact ? resume.fresh[g] : 0u);
    }
  }
}

template <class Laws>
void run_avx2(const Laws& laws, const BondLaw& L, const BondView& v, const RowBlocks& plan, const RowRun& run,
              double* force, BondTally& tally) {
  RowBlocks::Scratch& scratch = plan.scratch;
  const std::int32_t* slot_shift = run.slot_shifts >= 0 ? plan.slot_shifts.data() + run.slot_shifts : nullptr;
  const auto& law = laws.narrow;
  const RunSlots slots = run_slots(law, v, plan, run);
  if (run.stride == 1) {
    const bool whole_run = rows_intact(v, run.first, 1, run.count);
    const SlotSegment all{BoxSlot::Own, 0, static_cast<std::int32_t>(slots.n)};
    std::int32_t q = 0;
    for (; q + kWideRows <= run.count; q += kWideRows) {
      const std::int32_t i = run.first + q;
      // A bond reaching the failure test in an intact block: the rest of the block flagging.
      Resume<SimdWide, kWideBlocks> resume;
      const bool intact = whole_run || rows_intact(v, i, 1, kWideRows);
      if (intact && intact_blocks<kWideBlocks>(laws.wide, v, slots, &all, 1, nullptr, RowStep{i, 1}, i, q, 0, force,
                                               tally, &resume))
        continue;
      for (int g = 0; g < kWideBlocks; ++g) {
        const std::int32_t ig = i + g * SimdWide::W;
        damaged_block(laws.wide, L, v, slots, RowStep{ig, 1}, ig, q + g * SimdWide::W, 0, scratch,
                      cache_entry(plan, run, q / kWideRows * kWideBlocks + g), force, tally,
                      intact ? &resume.sums[g] : nullptr, resume.k, intact ? resume.fresh[g] : 0u);
      }
    }
    narrow_blocks(law, L, v, slots, run, q, whole_run, force, tally);
  } else if (run.mirror >= 0) {
    mirrored_run(laws, L, v, plan, run, slots, force, tally);
  } else {
    for (std::int32_t q = 0; q < run.count; q += 4) {
      const std::int32_t at = std::min(q, run.count - 4), i = run.first + at * run.stride;
      const std::int64_t shift = static_cast<std::int64_t>(at) * run.stride;
      if (rows_intact(v, i, run.stride, 4))
        block_avx2<true, false>(law, L, v, slots, i, run.stride, shift, q - at, force, tally, slot_shift);
      else
        block_avx2<false, false>(law, L, v, slots, i, run.stride, shift, q - at, force, tally, slot_shift);
    }
  }
}

// The lines of a box in order. A line with a broken bond goes through run_avx2 and produces
// nothing; an intact line consumes the coefficients of the earlier lines that completed their
// Produce slots (blocks at least `pad` lanes from the line's ends: their partners are all box
// rows) and evaluates the rest. A bond reaching the failure test sends its block and the rest of
// its line through block_avx2, and that line's coefficients are not consumed.
template <class Laws>
void box_avx2(const Laws& laws, const BondLaw& L, const BondView& v, const RowBlocks& rows, const RowBox& box,
              double* force, BondTally& tally) {
  RowBlocks::Scratch& scratch = rows.scratch;
  const std::int64_t ring_width = box.width + 2 * box.pad;
  const std::size_t n = box.slots.size();
  for (std::size_t r = box.run_begin; r < box.run_end; ++r) {
    const RowRun& run = rows.runs[r];
    const std::int32_t line = static_cast<std::int32_t>(r - box.run_begin);
    scratch.produced[line] = 0;
    if (!rows_intact(v, run.first, 1, run.count)) {
      run_avx2(laws, L, v, rows, run, force, tally);
      continue;
    }
    // The line's slot kinds as segments: for blocks whose Consume partners all lie in the line,
    // and for blocks near its ends (whose Consume slots are evaluated instead).
    scratch.inner.clear();
    scratch.edge.clear();
    auto append = [](std::vector<SlotSegment>& list, BoxSlot::Kind kind, std::int32_t k) {
      if (!list.empty() && list.back().kind == kind && list.back().end == k) ++list.back().end;
      else list.push_back({kind, k, k + 1});
    };
    for (std::size_t k = 0; k < n; ++k) {
      const BoxSlot& s = box.slots[k];
      BoxSlot::Kind kind = s.kind;
      std::int32_t ring_line = line;
      std::int64_t lane = 0;
      if (kind == BoxSlot::Produce) {
        ring_line = line + s.line;
        lane = s.lane;
      } else if (kind == BoxSlot::Consume && !(line + s.line >= 0 && scratch.produced[line + s.line])) {
        kind = BoxSlot::Own;
      }
      append(scratch.inner, kind, static_cast<std::int32_t>(k));
      append(scratch.edge, kind == BoxSlot::Consume ? BoxSlot::Own : kind, static_cast<std::int32_t>(k));
      scratch.at[k] = scratch.ring.data() + ((ring_line % box.window) * box.columns + s.column) * ring_width + box.pad + lane;
    }
    const RunSlots slots = run_slots(laws.narrow, v, rows, run);
    // Blocks at lanes q .. q + rows - 1 whose Consume partners all lie in the line: pad <= q and
    // q + rows - 1 + pad < width. Eight rows at once where they fit and are inner, else four (a
    // block of eight near an end evaluates its Consume slots for all eight rows: 0.97-0.99 as fast).
    auto inner = [&](std::int32_t q, int rows) { return q >= box.pad && q + rows - 1 + box.pad < run.count; };
    // Rows q .. of the line are next; a block of four at `at` <= q (the line's last) writes rows q ..
    std::int32_t q = 0;
    while (q < run.count) {
      const bool wide = q + kWideRows <= run.count && inner(q, kWideRows);
      const std::int32_t at = wide ? q : std::min(q, run.count - 4);
      const std::vector<SlotSegment>& segments = inner(at, wide ? kWideRows : 4) ? scratch.inner : scratch.edge;
      const bool done =
          wide ? intact_blocks<kWideBlocks>(laws.wide, v, slots, segments.data(), segments.size(), scratch.at.data(),
                                            RowStep{run.first + q, 1}, run.first + q, q, 0, force, tally)
               : intact_blocks<1>(laws.narrow, v, slots, segments.data(), segments.size(), scratch.at.data(),
                                  RowStep{run.first + at, 1}, run.first + at, at, q - at, force, tally);
      if (!done) break;
      q = wide ? q + kWideRows : at + 4;
    }
    scratch.produced[line] = q >= run.count;
    narrow_blocks(laws.narrow, L, v, slots, run, q, true, force, tally);
  }
}

template <ModelKind K, bool Conical, bool Linear, bool Energy>
void loop_avx2(const BondLaw& L, const BondView& v, const RowBlocks& rows, double* force, BondTally& tally) {
  const Laws<K, Conical, Linear, Energy> laws(L);
  const auto& law = laws.narrow;
  const FamilyPatterns& P = *v.patterns;
  refresh_mirror(v, rows);
  if (v.broken != rows.scratch.dead_flags) {  // another set of flags than the cache describes
    rows.forget_broken();
    rows.scratch.dead_flags = v.broken;
  }
  // Boxes pair their bonds only in calls without energy (the energy would need a second ring).
  std::size_t box = Energy ? rows.boxes.size() : 0;
  for (std::size_t r = 0; r < rows.runs.size();) {
    // The next run's CSR offset and pattern (run_slots): rows far apart, each a cache miss that
    // held up the loop between runs (1-2% of a 64^3 block's call).
    if (r + 1 < rows.runs.size()) {
      __builtin_prefetch(v.offsets + rows.runs[r + 1].first);
      __builtin_prefetch(P.of_row.data() + rows.runs[r + 1].first);
    }
    if (box < rows.boxes.size() && rows.boxes[box].run_begin == r) {
      box_avx2(laws, L, v, rows, rows.boxes[box], force, tally);
      r = rows.boxes[box++].run_end;
    } else {
      run_avx2(laws, L, v, rows, rows.runs[r++], force, tally);
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
#if defined(PERI_AVX512VL)
  return "avx512";
#elif defined(PERI_AVX2)
  return "avx2";
#else
  return "portable";
#endif
}

std::int64_t position_plane_stride(std::int64_t n) {
  constexpr std::int64_t kPeriod = 512, kOffset = 168;  // 4 KiB, and about a third of it
  return n + ((kOffset - n % kPeriod) + kPeriod) % kPeriod;
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

namespace {

// The box of stride-1 runs runs[m0 ..] that continue runs[m0] line by line (RowBox), or a box
// with run_end == run_begin if it has fewer than two lines or no slot pairs across lines.
RowBox find_box(const BondView& v, const std::vector<RowRun>& runs, std::size_t m0) {
  RowBox box;
  box.run_begin = box.run_end = m0;
  const FamilyPatterns& P = *v.patterns;
  const RowRun& r0 = runs[m0];
  if (m0 + 1 >= runs.size() || r0.stride != 1) return box;
  const std::int64_t S = static_cast<std::int64_t>(runs[m0 + 1].first) - r0.first;
  const std::int64_t b0 = v.offsets[r0.first], n = v.offsets[r0.first + 1] - b0;
  if (S <= r0.count || S > std::numeric_limits<std::int32_t>::max()) return box;
  std::size_t m = m0 + 1;
  for (; m < runs.size(); ++m) {
    const RowRun& r = runs[m];
    const std::int64_t shift = static_cast<std::int64_t>(m - m0) * S;
    if (r.stride != 1 || r.count != r0.count || r.first != r0.first + shift || P.of_row[r.first] != P.of_row[r0.first])
      break;
    const std::int64_t b = v.offsets[r.first];
    if (v.offsets[r.first + 1] - b != n) break;
    bool shifted = true;
    for (std::int64_t k = 0; k < n && shifted; ++k) shifted = v.neighbor[b + k] == v.neighbor[b0 + k] + shift;
    if (!shifted) break;
  }
  if (m - m0 < 2) return box;
  // Slot k's partner: offset o_k = nbr[k] - first = line S + lane; the mirror slot has -o_k and,
  // for the coefficient to be the same bits from both ends, the same reference slots.
  const std::int64_t slot0 = P.begin[P.of_row[r0.first]];
  std::vector<std::pair<std::int64_t, std::int64_t>> by_offset;  // (offset, k)
  for (std::int64_t k = 0; k < n; ++k) by_offset.emplace_back(v.neighbor[b0 + k] - static_cast<std::int64_t>(r0.first), k);
  std::sort(by_offset.begin(), by_offset.end());
  box.slots.assign(static_cast<std::size_t>(n), BoxSlot{});
  for (std::int64_t k = 0; k < n; ++k) {
    const std::int64_t o = v.neighbor[b0 + k] - static_cast<std::int64_t>(r0.first);
    const std::int64_t line = o >= 0 ? (o + S / 2) / S : -((-o + S / 2) / S);
    const std::int64_t lane = o - line * S;
    // A partner beyond the box's last line (in 3D: another plane) would only fill the ring.
    if (line <= 0 || line >= static_cast<std::int64_t>(m - m0) || 2 * std::abs(lane) >= S) continue;
    const auto mirror = std::lower_bound(by_offset.begin(), by_offset.end(), std::make_pair(-o, std::int64_t{0}));
    if (mirror == by_offset.end() || mirror->first != -o) continue;
    const std::int64_t a = slot0 + k, b = slot0 + mirror->second;
    if (P.xi2[a] != P.xi2[b] || P.measure[a] != P.measure[b] || P.inv_xi[a] != P.inv_xi[b] ||
        P.measure_per_xi2[a] != P.measure_per_xi2[b])
      continue;
    const std::int32_t column = box.columns++;
    box.slots[k] = {BoxSlot::Produce, static_cast<std::int32_t>(lane), static_cast<std::int32_t>(line), column};
    box.slots[mirror->second] = {BoxSlot::Consume, static_cast<std::int32_t>(-lane), static_cast<std::int32_t>(-line), column};
    box.pad = std::max(box.pad, static_cast<std::int32_t>(std::abs(lane)));
    box.window = std::max(box.window, static_cast<std::int32_t>(line) + 1);
  }
  // Pairing pays where many bonds cross lines: a 2D grid (about 40% of its slots pair; eight
  // lanes with boxes 1.06-1.11 times as fast as without), not a 3D block, where only the bonds
  // within a plane pair (9% of a 122-bond family at delta = 3 dx; the box's segments and ring
  // then cost more than they save: 0.85 times as fast, a 64^3 block).
  if (box.columns == 0 || 4 * box.columns < n) return box;
  box.run_end = m;
  box.width = r0.count;
  return box;
}

// Mirror columns for the strided runs of kMirrorRows rows or more (RowBlocks::mirror_columns):
// slot k of such a run (and its rows' own positions) reads nodes j + l t on lane l, j its first
// row's k-th neighbour and t the run's stride or the slot's shift: the column of nodes
// (j mod t) + m t, places m = j / t .. j / t + count - 1 of it. Runs reading overlapping places
// of one column share them. None where the copy would outgrow four positions per mirrored row
// (irregular node sets), and none without the vector loop.
void plan_mirror(const BondView& v, RowBlocks& plan) {
#if defined(PERI_AVX2)
  constexpr std::int32_t kMirrorRows = 8;
  using Key = std::pair<std::int32_t, std::int64_t>;  // step, residue
  // Per column, the places its runs read, as intervals [lo, hi); overlapping ones merge (runs
  // along one face share their columns; a partition's rows need not make one interval per column).
  std::map<Key, std::vector<std::pair<std::int64_t, std::int64_t>>> span;
  auto each_column = [&](const RowRun& run, auto&& f) {
    const std::int64_t b0 = v.offsets[run.first], n = v.offsets[run.first + 1] - b0;
    f(static_cast<std::int64_t>(run.first), run.stride);
    for (std::int64_t k = 0; k < n; ++k)
      f(static_cast<std::int64_t>(v.neighbor[b0 + k]),
        run.slot_shifts >= 0 ? plan.slot_shifts[static_cast<std::size_t>(run.slot_shifts + k)] : run.stride);
  };
  auto mirrored = [&](const RowRun& run) { return run.stride >= 2 && run.count >= kMirrorRows; };
  std::int64_t rows = 0;
  for (const RowRun& run : plan.runs) {
    if (!mirrored(run)) continue;
    rows += run.count;
    each_column(run, [&](std::int64_t node, std::int32_t step) {
      span[Key{step, node % step}].emplace_back(node / step, node / step + run.count);
    });
  }
  std::int64_t places = 0;
  for (auto& [key, list] : span) {
    std::sort(list.begin(), list.end());
    std::size_t kept = 0;
    for (const auto& interval : list) {
      if (kept > 0 && interval.first <= list[kept - 1].second) list[kept - 1].second = std::max(list[kept - 1].second, interval.second);
      else list[kept++] = interval;
    }
    list.resize(kept);
    for (const auto& [lo, hi] : list) places += hi - lo;
  }
  if (rows == 0 || places > 4 * rows + 4096 || places > std::numeric_limits<std::int32_t>::max() / 4) return;
  // The mirror place of place m of a column: start of its interval + m - lo.
  std::map<Key, std::vector<std::int64_t>> start;
  places = 0;
  for (const auto& [key, list] : span) {
    std::vector<std::int64_t>& at = start[key];
    for (const auto& [lo, hi] : list) {
      plan.mirror_columns.push_back({key.second + lo * key.first, key.first, static_cast<std::int32_t>(hi - lo), places});
      at.push_back(places - lo);
      places += hi - lo;
    }
  }
  plan.mirror_stride = position_plane_stride(places);
  for (RowRun& run : plan.runs) {
    if (!mirrored(run)) continue;
    run.mirror = static_cast<std::int32_t>(plan.mirror_slots.size());
    each_column(run, [&](std::int64_t node, std::int32_t step) {
      const Key key{step, node % step};
      const auto& list = span[key];
      const std::int64_t m = node / step;
      // The merged interval holding [m, m + count): the last one starting at or before m.
      const std::size_t which = static_cast<std::size_t>(
          std::upper_bound(list.begin(), list.end(), std::make_pair(m, std::numeric_limits<std::int64_t>::max())) -
          list.begin() - 1);
      plan.mirror_slots.push_back(static_cast<std::int32_t>(start[key][which] + m));
    });
  }
  plan.scratch.mirror.assign(3 * static_cast<std::size_t>(plan.mirror_stride), 0.0);
#else
  (void)v;
  (void)plan;
#endif
}

}  // namespace

RowBlocks plan_rows(const BondView& v, const std::int32_t* rows, std::size_t nrows, bool pair_bonds) {
  RowBlocks plan;
  if (!v.patterns) {
    plan.rest.assign(rows, rows + nrows);
    return plan;
  }
  const FamilyPatterns& P = *v.patterns;
  // Whether list entries a[0 .. m-1] continue a run from row `first` with stride s whose next row
  // is its q-th: rows first + (q + l) s, first's pattern, neighbours those of first shifted by
  // (q + l) s, or with `t` by (q + l) t_k for slot k.
  auto continues = [&](std::int32_t first, std::int32_t s, std::int32_t q, const std::int32_t* a, std::size_t left,
                       std::int32_t m, const std::int32_t* t = nullptr) {
    if (left < static_cast<std::size_t>(m) || s <= 0) return false;
    const std::int64_t b0 = v.offsets[first], n = v.offsets[first + 1] - b0;
    for (std::int32_t l = 0; l < m; ++l) {
      const std::int64_t shift = static_cast<std::int64_t>(q + l) * s;
      if (a[l] != first + shift || P.of_row[a[l]] != P.of_row[first]) return false;
      const std::int64_t bl = v.offsets[a[l]];
      if (v.offsets[a[l] + 1] - bl != n) return false;
      for (std::int64_t k = 0; k < n; ++k)
        if (v.neighbor[bl + k] != v.neighbor[b0 + k] + (t ? static_cast<std::int64_t>(q + l) * t[k] : shift)) return false;
    }
    return true;
  };
  // Takes the longest run (of at least four rows) starting at list entry a[0] with stride s (0 if
  // there is none).
  // With `t`, neighbours shifted per slot: the run keeps t in plan.slot_shifts.
  auto take_run = [&](const std::int32_t* a, std::size_t left, std::int32_t s,
                      const std::vector<std::int32_t>* t = nullptr) {
    const std::int32_t* shifts = t ? t->data() : nullptr;
    std::int32_t count = 0;
    while (continues(a[0], s, count, a + count, left - static_cast<std::size_t>(count), 4, shifts)) count += 4;
    if (count == 0) return count;
    while (continues(a[0], s, count, a + count, left - static_cast<std::size_t>(count), 1, shifts)) ++count;
    RowRun run{a[0], s, count};
    if (t) {
      run.slot_shifts = static_cast<std::int32_t>(plan.slot_shifts.size());
      plan.slot_shifts.insert(plan.slot_shifts.end(), t->begin(), t->end());
    }
    plan.runs.push_back(run);
    return count;
  };
  // Rows next to a partition boundary have ghost neighbours, numbered compactly beyond the owned
  // ones: rows a stride apart may then shift their owned and their ghost neighbours differently,
  // but each slot by the same amount from row to row (t_k, from the first two rows): such runs
  // keep those shifts (RowRun::slot_shifts).
  std::vector<std::int32_t> t;
  auto take_shifted_run = [&](const std::int32_t* a, std::size_t left, std::int32_t s) {
    // Stride 1 stays uniform: its blocks load each slot's neighbours with one vector load.
    if (s < 2 || left < 4 || P.of_row[a[1]] != P.of_row[a[0]]) return 0;
    const std::int64_t b0 = v.offsets[a[0]], b1 = v.offsets[a[1]], n = v.offsets[a[0] + 1] - b0;
    if (v.offsets[a[1] + 1] - b1 != n) return 0;
    t.resize(static_cast<std::size_t>(n));
    for (std::int64_t k = 0; k < n; ++k) {
      const std::int64_t d = static_cast<std::int64_t>(v.neighbor[b1 + k]) - v.neighbor[b0 + k];
      if (d <= 0 || d > std::numeric_limits<std::int32_t>::max() / 8) return 0;
      t[static_cast<std::size_t>(k)] = static_cast<std::int32_t>(d);
    }
    return take_run(a, left, s, &t);
  };
  // Runs of consecutive rows in list order first (stride 1).
  std::vector<std::int32_t> others;
  for (std::size_t r = 0; r < nrows;) {
    if (const std::int32_t count = take_run(rows + r, nrows - r, 1)) r += static_cast<std::size_t>(count);
    else others.push_back(rows[r++]);
  }
  RowBlocks::Scratch& scratch = plan.scratch;
  std::vector<std::uint8_t> boxed(plan.runs.size(), 0);
  if (pair_bonds) {
    // Boxes among the stride-1 runs (all the runs so far, in list order), and their scratch.
    std::size_t ring = 0, lines = 0, slots = 0;
    for (std::size_t m = 0; m < plan.runs.size();) {
      RowBox box = find_box(v, plan.runs, m);
      if (box.run_end == box.run_begin) {
        ++m;
        continue;
      }
      m = box.run_end;
      ring = std::max(ring, static_cast<std::size_t>(box.window) * static_cast<std::size_t>(box.columns) *
                                static_cast<std::size_t>(box.width + 2 * box.pad));
      lines = std::max(lines, box.run_end - box.run_begin);
      slots = std::max(slots, box.slots.size());
      std::fill(boxed.begin() + static_cast<std::ptrdiff_t>(box.run_begin), boxed.begin() + static_cast<std::ptrdiff_t>(box.run_end), 1);
      plan.boxes.push_back(std::move(box));
    }
    scratch.ring.assign(ring, 0.0);
    scratch.produced.assign(lines, 0);
    scratch.inner.reserve(slots);
    scratch.edge.reserve(slots);
    scratch.at.assign(slots, nullptr);
  }
#if defined(PERI_AVX2)
  // Tails. A stride-1 run of 8 m + r rows (0 < r < 8) ends in one or two blocks of four lanes
  // (narrow_blocks), which cost about 0.65 of a block of eight each (the 64^3 block: 8% of its
  // loop for two rows per line). Where eight or more runs outside boxes line up (one length and
  // pattern, first rows a constant stride S apart: the x lines of a 3D block's interior), their
  // last r rows leave them and form r strided runs of stride S instead, mirrored (plan_mirror)
  // and taken eight rows at a time.
  {
    const std::size_t stride_one = plan.runs.size();
    std::vector<std::int32_t> tail;
    for (std::size_t m0 = 0; m0 < stride_one;) {
      const RowRun first = plan.runs[m0];
      std::size_t m1 = m0 + 1;
      const std::int64_t S = m1 < stride_one ? static_cast<std::int64_t>(plan.runs[m1].first) - first.first : 0;
      auto lined_up = [&](std::size_t m) {
        const RowRun& r = plan.runs[m];
        return !boxed[m] && r.count == first.count && P.of_row[r.first] == P.of_row[first.first] &&
               static_cast<std::int64_t>(r.first) - first.first == static_cast<std::int64_t>(m - m0) * S;
      };
      if (!boxed[m0] && S > first.count && S <= std::numeric_limits<std::int32_t>::max())
        while (m1 < stride_one && lined_up(m1)) ++m1;
      const std::int32_t r = first.count % kWideRows, keep = first.count - r;
      if (m1 - m0 < static_cast<std::size_t>(kWideRows) || r == 0 || keep < kWideRows) {
        m0 = m1;
        continue;
      }
      for (std::int32_t p = 0; p < r; ++p) {
        tail.clear();
        for (std::size_t m = m0; m < m1; ++m) tail.push_back(plan.runs[m].first + keep + p);
        for (std::size_t q = 0; q < tail.size();) {
          std::int32_t count = take_run(tail.data() + q, tail.size() - q, static_cast<std::int32_t>(S));
          if (count == 0) count = take_shifted_run(tail.data() + q, tail.size() - q, static_cast<std::int32_t>(S));
          if (count > 0) q += static_cast<std::size_t>(count);
          else others.push_back(tail[q++]);
        }
      }
      for (std::size_t m = m0; m < m1; ++m) plan.runs[m].count = keep;
      m0 = m1;
    }
  }
#endif
  // The others by family pattern and then reference x within windows of 4096 rows of the list
  // (stable: in list order among equals), so that rows a grid row apart along an edge meet
  // (strided runs), also where a few consecutive rows of one pattern cross x (next to a
  // partition boundary across the x lines), and most remaining groups of four share a pattern
  // (the loop broadcasts its slots), while a window's neighbours stay in cache. The order does
  // not change any row's sum.
  constexpr std::size_t kWindow = 4096;
  for (std::size_t w = 0; w < others.size(); w += kWindow)
    std::stable_sort(others.begin() + w, others.begin() + std::min(others.size(), w + kWindow),
                     [&](std::int32_t a, std::int32_t b) {
                       if (P.of_row[a] != P.of_row[b]) return P.of_row[a] < P.of_row[b];
                       return v.X[3 * static_cast<std::size_t>(a)] < v.X[3 * static_cast<std::size_t>(b)];
                     });
  for (std::size_t r = 0; r < others.size();) {
    const std::size_t left = others.size() - r;
    const std::int32_t s = left >= 2 ? others[r + 1] - others[r] : 0;
    std::int32_t count = s > 0 ? take_run(others.data() + r, left, s) : 0;
    if (count == 0 && s > 0) count = take_shifted_run(others.data() + r, left, s);
    if (count > 0) r += static_cast<std::size_t>(count);
    else plan.rest.push_back(others[r++]);
  }
  plan_mirror(v, plan);
  std::int64_t slots_per_row = 0;
  for (const RowRun& run : plan.runs) slots_per_row = std::max(slots_per_row, v.offsets[run.first + 1] - v.offsets[run.first]);
  scratch.dead_lanes.assign(static_cast<std::size_t>(slots_per_row), 0);
  scratch.live_words = slots_per_row / 32 + 1;
  scratch.live.assign(static_cast<std::size_t>(scratch.live_words), 0);
#if defined(PERI_AVX2)
  // The cache of dead lanes: an entry of slots_per_row bytes per wide damaged block (W rows) of
  // the stride-1 runs of eight rows or more and of the mirrored runs (run_avx2, mirrored_run).
  scratch.dead_stride = slots_per_row;
  for (RowRun& run : plan.runs) {
    const std::int64_t blocks = run.stride == 1 ? run.count / kWideRows
                                : run.mirror >= 0 ? (run.count + kWideRows - 1) / kWideRows
                                                  : 0;
    if (blocks == 0 || plan.dead_cache_entries + blocks * kWideBlocks > std::numeric_limits<std::int32_t>::max()) continue;
    run.dead_cache = static_cast<std::int32_t>(plan.dead_cache_entries);
    plan.dead_cache_entries += blocks * kWideBlocks;
  }
#endif
  // The runs' family patterns, each with its slots' place in the arrays of limits.
  {
    std::unordered_map<std::int32_t, std::int32_t> index;
    plan.limits_at.assign(1, 0);
    for (RowRun& run : plan.runs) {
      const auto [it, fresh] = index.emplace(P.of_row[run.first], static_cast<std::int32_t>(index.size()));
      if (fresh) plan.limits_at.push_back(plan.limits_at.back() + v.offsets[run.first + 1] - v.offsets[run.first]);
      run.limits = it->second;
    }
    const std::size_t slots = static_cast<std::size_t>(plan.limits_at.back());
    for (std::vector<double>* a : {&scratch.y2_floor, &scratch.y2_break, &scratch.weight, &scratch.weight_per_xi,
                                   &scratch.xi_len, &scratch.energy_weight})
      a->assign(slots, 0.0);
    scratch.limits_known.assign(index.size(), 0);
  }
  return plan;
}

void RowBlocks::forget_broken() const { std::fill(scratch.dead_known.begin(), scratch.dead_known.end(), 0); }

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

double bond_energy(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t nrows,
                   double* density) {
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
    if (density) density[i] = 0.5 * w;
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
  // A row's stiffness sum depends on its family pattern alone: each pattern's is summed once.
  std::vector<char> pattern_done(v.patterns ? static_cast<std::size_t>(v.patterns->patterns()) : 0, 0);
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    if (v.patterns) {
      char& done = pattern_done[v.patterns->of_row[i]];
      if (done) continue;
      done = 1;
    }
    double sum = 0;
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
      sum += law.reference_stiffness(v.xi2(i, b)) * v.measure(i, b);
    }
    if (sum > 0) dt = std::min(dt, std::sqrt(2.0 * density / sum));
  }
  return dt;
}

}  // namespace peri
