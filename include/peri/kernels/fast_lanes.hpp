// What the SIMD accelerator's loops share (grid_blocks.hpp: rows with family patterns;
// free_rows.hpp: the rows of irregular bodies; fast_loop.hpp walks the plan): a bond added to the
// lanes' sums, the rows' forces written, their fresh bonds flagged and booked. Needs AVX2 + FMA
// (PERI_AVX2).
#pragma once
#include "peri/core/simd.hpp"

#if defined(PERI_AVX2)
#include <cstdint>

#include "peri/kernels/bond_loop.hpp"
#include "peri/kernels/forces.hpp"

namespace peri::fast {
// Internal linkage in every file that instantiates the loop (fast_loop.hpp says why).
namespace {

using law_loop::squared_length;

/// An address unique to type T (keys the plan's cache of per-slot law constants).
template <class T>
const void* type_tag() {
  static const char tag = 0;
  return &tag;
}

// Adds the bonds to the lane sums f (force over the row factor) and w (energy density); returns
// the lanes whose bond reaches the failure test now, which add nothing.
template <class Law>
__attribute__((always_inline)) inline unsigned add_bond(const Law& law, const typename Law::Bonds& b,
                                                        typename Law::V& f0, typename Law::V& f1,
                                                        typename Law::V& f2, typename Law::V& w) {
  using P = typename Law::Pack;
  unsigned fresh;
  const typename Law::V coef = law.coefficient(b, law.front(b, squared_length<P>(b)), w, fresh);
  f0 = P::fmadd(coef, b.d0, f0);
  f1 = P::fmadd(coef, b.d1, f1);
  f2 = P::fmadd(coef, b.d2, f2);
  return fresh;
}

// Writes the rows' force densities (the row factor times the lane sums) and energy (lanes
// first .. count-1: a run's last block overlaps the one before it by `first` rows), and books
// their newly broken bonds (`newly`, holding breaking energies `diss`, mark_fresh; nullptr where
// none can break).
template <class Law>
void finish_rows(const Law& law, const BondView& v, const std::int32_t* rows, int count, typename Law::V f0,
                 typename Law::V f1, typename Law::V f2, typename Law::V w, const int* newly, const double* diss,
                 double* force, BondTally& tally, int first = 0) {
  using P = typename Law::Pack;
  constexpr int W = P::W;
  const double c_row = law.row_factor();
  double s0[W], s1[W], s2[W], se[W];
  P::storeu(s0, f0);
  P::storeu(s1, f1);
  P::storeu(s2, f2);
  P::storeu(se, w);
  for (int l = first; l < count; ++l) {
    const std::int32_t i = rows[l];
    force[3 * i] = c_row * s0[l];
    force[3 * i + 1] = c_row * s1[l];
    force[3 * i + 2] = c_row * s2[l];
    if constexpr (Law::kEnergy) {
      tally.strain_energy += 0.5 * v.volume[i] * se[l];
      if (v.energy_density) v.energy_density[i] = 0.5 * se[l];
    }
    // Every lane of a block that can break bonds: the rows' measures then load in order (a row
    // with a broken bond here and there missed the cache and held up the loop); a lane with none
    // adds 0 (the same sums).
    if (newly) {
      tally.dissipated += 0.5 * v.volume[i] * diss[l];
      tally.newly_broken += newly[l];
      if (newly[l] && v.row_broken) v.row_broken[i] = 1;
    }
  }
}

// Flags the fresh lanes' bonds (bond k of lane l's row, CSR position flag_row[l] + k) as broken
// and adds their breaking energy w0(l) to the lane's sum: summed as the bonds break, a row's sum
// is in CSR order.
template <int W, class BreakingEnergy>
inline void mark_fresh(unsigned fresh, std::uint8_t* const* flag_row, std::int64_t k, BreakingEnergy w0, int* newly,
                       double* diss) {
  for (int l = 0; l < W; ++l)
    if (fresh >> l & 1) {
      // A store, not a read-modify-write: the flags of the bonds this loop evaluates are 0 or
      // kBrokenFlag (other bits mark lattice bonds), and a fresh bond's is 0. Blocks that keep their
      // dead lanes (RowBlocks::dead_cache_entries) read no flag bytes, so the line is seldom
      // cached, and a load waiting for it held up the loop (with the next change, the fragmenting
      // 64^3 block's step 1.05 times as fast).
      flag_row[l][k] = kBrokenFlag;
      ++newly[l];
      diss[l] += w0(l);
    }
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

}  // namespace
}  // namespace peri::fast
#endif
