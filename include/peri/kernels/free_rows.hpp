// The SIMD accelerator's free rows: the rows of irregular bodies (meshes, point clouds, spheres), which
// keep no family pattern (FamilyPatterns' free rows). Up to W rows at a time, one per lane: per
// slot each lane's neighbour's node record is loaded as one cache line, the W lines are transposed
// into vectors, the bond's reference slot is computed from them (free_slot, bond_loop.hpp) and the
// law evaluated as in a grid block (fast_lanes.hpp). A row's force is the same bits as the portable
// walk's. Needs AVX2 + FMA (PERI_AVX2).
#pragma once
#include "peri/core/simd.hpp"

#if defined(PERI_AVX2)
#include <algorithm>
#include <cstdint>

#include "peri/kernels/bond_loop.hpp"
#include "peri/kernels/fast_lanes.hpp"
#include "peri/kernels/forces.hpp"

namespace peri::fast {
// Internal linkage in every file that instantiates the loop (fast_loop.hpp says why).
namespace {

// Slot k of a block of free rows, its bond vectors and reference slot set (free_slot): the law's
// slot constants, the law, and each bond that reaches the failure test now flagged with its
// lane's critical energy (free rows have a slot of their own on every lane).
template <class Law, class C>
__attribute__((always_inline)) inline void add_free_bond(const Law& law, const C& L, typename Law::Bonds& bonds,
                                                         unsigned dead, std::int64_t k, typename Law::V& f0,
                                                         typename Law::V& f1, typename Law::V& f2, typename Law::V& w,
                                                         std::uint8_t* const* flag_row, int* newly, double* diss) {
  using S = typename Law::Pack;
  constexpr int W = S::W;
  fill_slots<S>(law, bonds);
  bonds.dead = dead;
  const unsigned fresh = add_bond(law, bonds, f0, f1, f2, w);
  if (fresh) [[unlikely]] {
    double x2[W], m[W];
    S::storeu(x2, bonds.xi2);
    S::storeu(m, bonds.measure);
    mark_fresh<W>(fresh, flag_row, k, [&](int l) { return L.critical_energy(x2[l]) * m[l]; }, newly, diss);
  }
}

// The free rows' node records (RowBlocks::Scratch::records): the current positions of nodes
// 0 .. free_nodes-1 copied in, and where the view's reference positions or measures are not
// those the records hold, those too.
inline void refresh_records(const BondView& v, const RowBlocks& plan) {
  RowBlocks::Scratch& scratch = plan.scratch;
  const std::int64_t n = plan.free_nodes;
  if (n == 0) return;
  double* __restrict rec = nullptr;
  if (scratch.records.size() != static_cast<std::size_t>(8 * n) || scratch.records_of[0] != v.X ||
      scratch.records_of[1] != v.volume) {
    scratch.records.assign(static_cast<std::size_t>(8 * n), 0.0);
    rec = scratch.records.data();
    for (std::int64_t j = 0; j < n; ++j) {
      rec[8 * j + 3] = v.volume[j];
      for (int c = 0; c < 3; ++c) rec[8 * j + 4 + c] = v.X[3 * j + c];
    }
    scratch.records_of = {v.X, v.volume};
  }
  rec = scratch.records.data();
  const double* __restrict x = v.x;
  const double* __restrict y = v.x + v.x_stride;
  const double* __restrict z = v.x + 2 * v.x_stride;
  for (std::int64_t j = 0; j < n; ++j) {
    rec[8 * j] = x[j];
    rec[8 * j + 1] = y[j];
    rec[8 * j + 2] = z[j];
  }
}

// Asks for the neighbour lists of up to W free rows ahead of their walk. Each lane reads its own
// row's list, W lists at a time, and on a body larger than the cache the hardware's prefetchers
// missed many of them: the loop over groups of rows asks for the lists of a later group.
inline void prefetch_lists(const BondView& v, const std::int32_t* rows, int count) {
  for (int l = 0; l < count; ++l) {
    const std::int64_t b0 = v.offsets[rows[l]], b1 = v.offsets[rows[l] + 1];
    for (std::int64_t b = b0; b < b1; b += 16) __builtin_prefetch(v.neighbor + b);
    if (b1 > b0) __builtin_prefetch(v.neighbor + b1 - 1);
  }
}

// A block's node records (lane l's at rec[l], [x, y, z, V, X, Y, Z, 0]) as seven vectors of the
// lanes' x, y, z, V, X, Y, Z.
template <class S>
struct Records {
  typename S::V x, y, z, V, X, Y, Z;
};
#if defined(PERI_AVX512VL)
// Eight records: each half of a record loaded into a half of a vector (lanes l and l + 4 in one:
// the insert may run on either vector port), then two stages of shuffles (15).
__attribute__((always_inline)) inline Records<simd::Simd8> transpose_records(const double* const rec[8]) {
  __m512d a[4], b[4];
  for (int l = 0; l < 4; ++l) {
    a[l] = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(rec[l])), _mm256_load_pd(rec[l + 4]), 1);
    b[l] = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(rec[l] + 4)), _mm256_load_pd(rec[l + 4] + 4), 1);
  }
  // Pairs of lanes per 128-bit part: [x0 x1 | z0 z1 | x4 x5 | z4 z5], [y0 y1 | V0 V1 | y4 y5 | V4 V5], ...
  const __m512d t0 = _mm512_unpacklo_pd(a[0], a[1]), t1 = _mm512_unpackhi_pd(a[0], a[1]);
  const __m512d t2 = _mm512_unpacklo_pd(a[2], a[3]), t3 = _mm512_unpackhi_pd(a[2], a[3]);
  const __m512d u0 = _mm512_unpacklo_pd(b[0], b[1]), u1 = _mm512_unpackhi_pd(b[0], b[1]);
  const __m512d u2 = _mm512_unpacklo_pd(b[2], b[3]), u3 = _mm512_unpackhi_pd(b[2], b[3]);
  const __m512i even = _mm512_setr_epi64(0, 1, 8, 9, 4, 5, 12, 13), odd = _mm512_setr_epi64(2, 3, 10, 11, 6, 7, 14, 15);
  Records<simd::Simd8> o;
  o.x = _mm512_permutex2var_pd(t0, even, t2);
  o.z = _mm512_permutex2var_pd(t0, odd, t2);
  o.y = _mm512_permutex2var_pd(t1, even, t3);
  o.V = _mm512_permutex2var_pd(t1, odd, t3);
  o.X = _mm512_permutex2var_pd(u0, even, u2);
  o.Z = _mm512_permutex2var_pd(u0, odd, u2);
  o.Y = _mm512_permutex2var_pd(u1, even, u3);
  return o;
}
#else
// Four records: per pair of fields, lanes 0 and 2 (1 and 3) in the halves of one vector (an
// insert from memory), then one unpack per field (8 inserts, 7 unpacks: no gathers, which took
// most of the loop's time on the AVX2 cores measured).
__attribute__((always_inline)) inline Records<simd::Simd4> transpose_records(const double* const rec[4]) {
  auto pair = [&](int l, int c) {
    return _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_load_pd(rec[l] + c)), _mm_load_pd(rec[l + 2] + c), 1);
  };
  Records<simd::Simd4> o;
  __m256d p = pair(0, 0), q = pair(1, 0);  // [x0 y0 | x2 y2], [x1 y1 | x3 y3]
  o.x = _mm256_unpacklo_pd(p, q);
  o.y = _mm256_unpackhi_pd(p, q);
  p = pair(0, 2), q = pair(1, 2);
  o.z = _mm256_unpacklo_pd(p, q);
  o.V = _mm256_unpackhi_pd(p, q);
  p = pair(0, 4), q = pair(1, 4);
  o.X = _mm256_unpacklo_pd(p, q);
  o.Y = _mm256_unpackhi_pd(p, q);
  o.Z = _mm256_unpacklo_pd(pair(0, 6), pair(1, 6));
  return o;
}
#endif

// Up to W free rows (FamilyPatterns: no family pattern), one per lane of the law's pack (`count`
// rows; idle lanes repeat the last row, flagged dead): per slot k each lane loads its k-th
// neighbour's node record, the W are transposed into vectors, the reference slot computed from
// them (free_slot) and the law evaluated as in a block. A lane past its row's end repeats its last
// bond, flagged dead. `Intact`: the rows have no broken bond (no flag bytes read); `Weighted`:
// the measures carry the bonds' weights (FamilyPatterns::free_weight); `lanes`: the group's
// neighbours interleaved (RowBlocks::free_lanes; unweighted rows), else each lane reads its row's
// list. The same bits as the
// portable walk's rows (the same operations in CSR order). The vector ports bound this
// loop: per slot the transpose (on AVX-512 15 shuffles and 8 inserts) and the reference slot (15
// operations) come on top of the law's own work, about three times a grid block's operations per
// bond.
template <bool Intact, bool Weighted, class Law, class C>
void free_records(const Law& law_of, const C& L, const BondView& v, const double* rec, const std::int32_t* group,
                  int count, double* force, BondTally& tally, const std::int32_t* lanes = nullptr) {
  using S = typename Law::Pack;
  constexpr int W = S::W;
  const Law law = law_of;  // a local copy, as in damaged_block
  const simd::Root<S> root;
  std::int32_t rows[W];
  std::int64_t n[W];
  const std::int32_t* nbr[W];
  std::uint8_t* flag_row[W];
  std::int64_t nmin = INT64_MAX, nmax = 0;
  const double* own_rec[W];
  const float* weight[W];
  for (int l = 0; l < W; ++l) {
    rows[l] = group[std::min(l, count - 1)];
    const std::int64_t b0 = v.offsets[rows[l]];
    n[l] = v.offsets[rows[l] + 1] - b0;
    nbr[l] = v.neighbor + b0;
    if constexpr (Weighted) weight[l] = v.patterns->free_weight.data() + b0;
    flag_row[l] = v.broken + b0;
    nmin = std::min(nmin, n[l]);
    nmax = std::max(nmax, n[l]);
    own_rec[l] = rec + 8 * static_cast<std::int64_t>(rows[l]);
  }
  const unsigned idle = ((1u << W) - 1u) & ~((1u << count) - 1u);
  const Records<S> own = transpose_records(own_rec);
  typename S::V f0 = S::zero(), f1 = S::zero(), f2 = S::zero(), w = S::zero();
  int newly[W] = {};
  double diss[W] = {};
  for (std::int64_t k = 0; k < nmax; ++k) {
    unsigned dead = idle;
    const double* r[W];
    float wk[W];
    // (Each address pinned to a general register: GCC otherwise packs the eight into a vector and
    // extracts them one by one, 0.6 times as fast.)
    if (!Weighted && lanes) {  // (RowBlocks::free_lanes: the records' offsets, lane by lane)
      for (int l = 0; l < W; ++l) {
        r[l] = rec + lanes[k * W + l];
        __asm__("" : "+r"(r[l]));
      }
      // The node lines kLineAhead slots on (the stream is padded past its last group).
      for (int l = 0; l < W; ++l) __builtin_prefetch(rec + lanes[(k + RowBlocks::kLineAhead) * W + l]);
      if (k >= nmin) [[unlikely]]
        for (int l = 0; l < W; ++l) dead |= static_cast<unsigned>(k >= n[l]) << l;
    } else if (k < nmin) [[likely]] {
      for (int l = 0; l < W; ++l) {
        r[l] = rec + 8 * static_cast<std::int64_t>(nbr[l][k]);
        __asm__("" : "+r"(r[l]));
        if constexpr (Weighted) wk[l] = weight[l][k];
      }
      if (k + RowBlocks::kLineAhead < nmin)
        for (int l = 0; l < W; ++l) __builtin_prefetch(rec + 8 * static_cast<std::int64_t>(nbr[l][k + RowBlocks::kLineAhead]));
    } else {  // a lane past its row's end repeats its last bond (without bonds, its own record)
      for (int l = 0; l < W; ++l) {
        dead |= static_cast<unsigned>(k >= n[l]) << l;
        const std::int64_t kk = std::min(k, n[l] - 1);
        r[l] = rec + 8 * static_cast<std::int64_t>(n[l] > 0 ? nbr[l][kk] : rows[l]);
        __asm__("" : "+r"(r[l]));
        if constexpr (Weighted) wk[l] = n[l] > 0 ? weight[l][kk] : 0.0f;
      }
    }
    const Records<S> o = transpose_records(r);
    typename S::V measure = o.V;
    if constexpr (Weighted) {
#if defined(PERI_AVX512VL)
      measure = S::mul(_mm512_cvtps_pd(_mm256_loadu_ps(wk)), measure);
#else
      measure = S::mul(_mm256_cvtps_pd(_mm_loadu_ps(wk)), measure);
#endif
    }
    if constexpr (!Intact)
      for (int l = 0; l < W; ++l) dead |= static_cast<unsigned>(k < n[l] ? flag_row[l][k] & kBrokenFlag : 0) << l;
    typename Law::Bonds bonds;
    bonds.d0 = S::sub(o.x, own.x);
    bonds.d1 = S::sub(o.y, own.y);
    bonds.d2 = S::sub(o.z, own.z);
    free_slot<S, reads_inverse_length<Law>()>(root, S::sub(o.X, own.X), S::sub(o.Y, own.Y), S::sub(o.Z, own.Z), measure, bonds);
    add_free_bond(law, L, bonds, dead, k, f0, f1, f2, w, flag_row, newly, diss);
  }
  finish_rows(law, v, rows, count, f0, f1, f2, w, newly, diss, force, tally);
}

}  // namespace
}  // namespace peri::fast
#endif
