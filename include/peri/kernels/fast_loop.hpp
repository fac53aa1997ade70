// The bond loop's SIMD accelerator: the rows of a plan (RowBlocks: runs, boxes, mirrors, the rest)
// evaluated four or eight at a time, one row per lane, for a law with a vector form. Each lane
// walks its row's bonds in CSR order with the law's operations on the pack (models/laws/), so a
// row's force is the same bits as the portable walk's (bond_loop.hpp) and as any other grouping's.
//
// This header is long (about 800 lines) because it is one mechanism: the grouping of rows into
// runs and boxes by plan_rows (kernels/plan.cpp) and the block loops that exploit it share their
// invariants (lane order, the ring of produced coefficients, the dead-lane cache) and read best
// together. It needs AVX2 + FMA (PERI_AVX2); without them every law runs in the portable walk.
#pragma once
#include "peri/core/simd.hpp"

#if defined(PERI_AVX2)
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <vector>

#include "peri/kernels/bond_loop.hpp"
#include "peri/kernels/forces.hpp"

namespace peri::fast {
// Internal linkage in every file that instantiates the loop (laws.cpp, and a test's own law): the
// compiler then sees every call of these templates and inlines and specializes them as it did
// when they were one file's static functions (as weak templates, the intact boxes ran at 0.8).
namespace {

using simd::Simd4;
using SimdWide = simd::Wide;
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

// Rows first + l stride of a block.
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
// What the blocks of one run (RowRun) share: the neighbour list of its first row (n bonds), its
// family pattern's slots and the law's constants of each slot (run_slots).
struct RunSlots {
  const std::int32_t* __restrict neighbor;
  std::int64_t n;
  const double *xi2, *measure, *inv_xi, *measure_per_xi2;
  std::array<const double*, RowBlocks::kLawSlots> slot{};
  // Slot k on every lane of b (`Values`: the law's slot constants too).
  template <bool Values, class B>
  __attribute__((always_inline)) void broadcast(B& b, std::int64_t k) const {
    using P = typename B::Pack;
    b.xi2 = P::broadcast(xi2 + k);
    b.measure = P::broadcast(measure + k);
    b.inv_xi = P::broadcast(inv_xi + k);
    b.measure_per_xi2 = P::broadcast(measure_per_xi2 + k);
    if constexpr (Values)
      for (int s = 0; s < B::kSlots; ++s) b.slot[s] = P::broadcast(slot[s] + k);
  }
};

template <bool Intact, bool Unit, class Law, class C>
void block_avx2(const Law& law_of, const C& L, const BondView& v, const RunSlots& run_of, std::int32_t i,
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
  using S = simd::Simd4;
  static_assert(Law::W == 4, "block_avx2: one block of four lanes");
  auto lanes = [](const double* p, std::int64_t at, std::int64_t t) {
    if constexpr (Unit) return S::loadu(p + at);
    else return S::strided(p, at, t);
  };
  const std::int64_t block_at = Unit || !slot_shift ? 0 : shift / stride;
  const std::int64_t n = run.n;
  const std::int32_t* __restrict nbr = run.neighbor;
  std::uint8_t* const flag_row[4] = {v.broken + v.offsets[rows[0]], v.broken + v.offsets[rows[1]],
                                     v.broken + v.offsets[rows[2]], v.broken + v.offsets[rows[3]]};
  const std::uint8_t *fl0 = flag_row[0], *fl1 = flag_row[1], *fl2 = flag_row[2], *fl3 = flag_row[3];
  const S::V xi0 = lanes(v.x, i, s), xi1 = lanes(v.x + v.x_stride, i, s), xi2 = lanes(v.x + 2 * v.x_stride, i, s);
  S::V f0 = S::zero(), f1 = S::zero(), f2 = S::zero(), w = S::zero();
  int newly[4] = {0, 0, 0, 0};
  double diss[4] = {0, 0, 0, 0};
  for (std::int64_t k = 0; k < n; ++k) {
    std::int64_t j = nbr[k], t = s;
    if (!Unit && slot_shift) {  // positions relative to v.x itself: px - shift
      t = slot_shift[k];
      j += block_at * t - shift;
    }
    typename Law::Bonds b;
    b.d0 = S::sub(lanes(px, j, t), xi0);
    b.d1 = S::sub(lanes(py, j, t), xi1);
    b.d2 = S::sub(lanes(pz, j, t), xi2);
    run.template broadcast<Law::kSlotValues>(b, k);
    if constexpr (Intact) b.dead = 0;
    else b.dead = (fl0[k] & kBrokenFlag) | (fl1[k] & kBrokenFlag) << 1 | (fl2[k] & kBrokenFlag) << 2 | (fl3[k] & kBrokenFlag) << 3;
    const unsigned fresh = add_bond(law, b, f0, f1, f2, w);
    if (fresh) [[unlikely]] {
      const double w0 = L.critical_energy(run.xi2[k]) * run.measure[k];  // the slot's, for every lane
      mark_fresh<4>(fresh, flag_row, k, [w0](int) { return w0; }, newly, diss);
    }
  }
  finish_rows(law, v, rows, 4, f0, f1, f2, w, newly, diss, force, tally, skip);
}

using SlotSegment = RowBlocks::Scratch::Segment;

// Slots k = next(), next(), ... (-1: none left) of one block, software-pipelined: the next slot's
// bond vectors and front (the law's front: up to its's long-latency step, from start(k, b)) are
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
  typename Law::Bonds b;
  Front p = start(k, b);
  for (std::int64_t after = next(); after >= 0; after = next()) {
    typename Law::Bonds b_next;
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
bool intact_blocks(const Law& law_of, const BondView& v, const RunSlots& run_of,
                   const SlotSegment* segments, std::size_t nsegments, double* const* at, RowStep rows_at,
                   std::int64_t own, std::int64_t a, int skip, double* force, BondTally& tally,
                   Resume<typename Law::Pack, G>* resume = nullptr) {
  // Local copies, as in damaged_block: Produce slots store coefficients, which may alias
  // anything reached through a reference, and the compiler then reloaded the slot pointers and
  // the law's constants on every slot.
  const Law law = law_of;
  const RunSlots run = run_of;
  const double* __restrict px = v.x + a;
  const double* __restrict py = v.x + v.x_stride + a;
  const double* __restrict pz = v.x + 2 * v.x_stride + a;
  const std::int32_t* __restrict nbr = run.neighbor;
  using S = typename Law::Pack;
  using V = typename S::V;
  constexpr int W = S::W;
  V x0[G], x1[G], x2[G], f0[G], f1[G], f2[G], w[G];
  for (int g = 0; g < G; ++g) {
    x0[g] = S::loadu(v.x + own + W * g);
    x1[g] = S::loadu(v.x + v.x_stride + own + W * g);
    x2[g] = S::loadu(v.x + 2 * v.x_stride + own + W * g);
    f0[g] = f1[g] = f2[g] = w[g] = S::zero();
  }
  // One block (G = 1), slots [k0, k1) (Produce: storing their coefficients too): pipelined_slots.
  auto evaluate_pipelined = [&](std::int64_t k0, std::int64_t k1, auto produce) __attribute__((always_inline)) {
    // What the loop reads, in locals of this call (the compiler may keep this lambda out of line;
    // through its captures, every Produce store would reload them).
    const Law lw = law;
    const RunSlots rs = run;
    const double* __restrict qx = px;
    const double* __restrict qy = py;
    const double* __restrict qz = pz;
    const std::int32_t* __restrict nb = nbr;
    double* const* ring = at;
    const std::int64_t lane0 = a;
    const V o0 = x0[0], o1 = x1[0], o2 = x2[0];
    V s0 = f0[0], s1 = f1[0], s2 = f2[0], sw = w[0];
    std::int64_t k_next = k0;
    const bool whole = pipelined_slots<Law>(
        [&]() -> std::int64_t { return k_next < k1 ? k_next++ : -1; },
        [&](std::int64_t k, typename Law::Bonds& b) __attribute__((always_inline)) {
          const std::int64_t j = nb[k];
          rs.template broadcast<Law::kSlotValues>(b, k);
          b.dead = 0;
          b.d0 = S::sub(S::loadu(qx + j), o0);
          b.d1 = S::sub(S::loadu(qy + j), o1);
          b.d2 = S::sub(S::loadu(qz + j), o2);
          return lw.front(b, squared_length<S>(b));
        },
        [&](std::int64_t k, const typename Law::Bonds& b, const typename Law::Front& p) __attribute__((always_inline)) {
          unsigned lanes;
          const V coef = lw.coefficient(b, p, sw, lanes);
          if constexpr (decltype(produce)::value) S::storeu(ring[k] + lane0, coef);
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
  auto evaluate = [&](std::int32_t k0, std::int32_t k1, auto produce) __attribute__((always_inline)) {
    if constexpr (G == 1) {
      return evaluate_pipelined(k0, k1, produce);
    } else {  // several blocks side by side (AVX2's two of four lanes)
      for (std::int64_t k = k0; k < k1; ++k) {
        const std::int64_t j = nbr[k];
        typename Law::Bonds b;
        run.template broadcast<Law::kSlotValues>(b, k);
        b.dead = 0;
        unsigned fresh = 0;
        for (int g = 0; g < G; ++g) {
          b.d0 = S::sub(S::loadu(px + j + W * g), x0[g]);
          b.d1 = S::sub(S::loadu(py + j + W * g), x1[g]);
          b.d2 = S::sub(S::loadu(pz + j + W * g), x2[g]);
          unsigned lanes;
          const V coef = law.coefficient(b, law.front(b, squared_length<S>(b)), w[g], lanes);
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
              V scratch = S::zero();
              law.coefficient(b, law.front(b, squared_length<S>(b)), scratch, resume->fresh[g]);
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
      // Block by block, the sums in locals (the arrays, whose addresses the lambdas above take,
      // stayed in memory: a store and a reload per slot).
      for (int g = 0; g < G; ++g) {
        V s0 = f0[g], s1 = f1[g], s2 = f2[g];
        const V o0 = x0[g], o1 = x1[g], o2 = x2[g];
        for (std::int64_t k = seg.begin; k < seg.end; ++k) {
          const std::int64_t j = nbr[k] + W * g;
          const V coef = S::loadu(at[k] + a + W * g);
          s0 = S::fmadd(coef, S::sub(S::loadu(px + j), o0), s0);
          s1 = S::fmadd(coef, S::sub(S::loadu(py + j), o1), s1);
          s2 = S::fmadd(coef, S::sub(S::loadu(pz + j), o2), s2);
        }
        f0[g] = s0;
        f1[g] = s1;
        f2[g] = s2;
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
    finish_rows(law, v, rows, W, f0[g], f1[g], f2[g], w[g], nullptr, nullptr, force, tally, std::clamp(skip - W * g, 0, W));
  }
  return true;
}

// The broken flags of W rows of a run (n bonds each, row l's at flag_row[l]) as one byte per
// slot k, bit l set if lane l's bond is broken: 32 slots at a time (a flag byte masked to its
// broken bit, shifted by l within its 16-bit word, stays in its byte), the last 32 ending at n
// (overlapping the ones before: the same bytes again); fewer than 32 slots one by one.
template <int W>
inline void dead_lanes(std::uint8_t* const* flag_row, std::int64_t n, std::uint8_t* dead) {
  const __m256i broken = _mm256_set1_epi8(static_cast<char>(kBrokenFlag));
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
    for (int l = 0; l < W; ++l) d |= static_cast<unsigned>(flag_row[l][k] & kBrokenFlag) << l;
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
template <class Law, class C>
void damaged_block(const Law& law_of, const C& L, const BondView& v, const RunSlots& run_of, RowStep rows_at,
                   std::int64_t own, std::int64_t a, int skip, RowBlocks::Scratch& scratch, std::int64_t entry,
                   double* force, BondTally& tally, const LaneSums<typename Law::Pack>* from = nullptr,
                   std::int64_t from_k = 0, unsigned from_fresh = 0) {
  // Local copies of the law's constants and the run's slot pointers: booking a broken bond writes
  // flag bytes, which may alias anything, and the compiler then reloaded both on every slot.
  const Law law = law_of;
  const RunSlots run = run_of;
  using S = typename Law::Pack;
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
  V f0 = S::zero(), f1 = S::zero(), f2 = S::zero(), w = S::zero();
  int newly[W] = {};
  double diss[W] = {};
  // Flags and books slot k's bonds breaking now on lanes `fresh`, and keeps the lane bits.
  auto book_fresh = [&](std::int64_t k, unsigned fresh) {
    const double w0 = L.critical_energy(run.xi2[k]) * run.measure[k];  // the slot's, for every lane
    mark_fresh<W>(fresh, flag_row, k, [w0](int) { return w0; }, newly, diss);
    dead[k] = static_cast<std::uint8_t>(dead[k] | fresh);
    if (dead[k] == (1u << W) - 1u) live[k / 32] &= ~(std::uint32_t{1} << (k % 32));  // broken on every lane now
  };
  auto slot = [&](std::int64_t k) __attribute__((always_inline)) {
    const std::int64_t j = nbr[k];
    typename Law::Bonds b;
    b.d0 = S::sub(S::loadu(px + j), x0);
    b.d1 = S::sub(S::loadu(py + j), x1);
    b.d2 = S::sub(S::loadu(pz + j), x2);
    run.template broadcast<Law::kSlotValues>(b, k);
    b.dead = dead[k];
    const unsigned fresh = add_bond(law, b, f0, f1, f2, w);
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
  finish_rows(law, v, rows, W, f0, f1, f2, w, newly, diss, force, tally, skip);
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
template <bool Shared, class Law, class C>
void group_avx2(const Law& law_of, const C& L, const BondView& v, const std::int32_t* group, int count,
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
  using S = simd::Simd4;
  static_assert(Law::W == 4, "group_avx2: four lanes");
  const S::V xi0 = S::gather(px, rows), xi1 = S::gather(py, rows), xi2 = S::gather(pz, rows);
  S::V f0 = S::zero(), f1 = S::zero(), f2 = S::zero(), w = S::zero();
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
      dead |= (static_cast<unsigned>(k != kk) | (v.broken[b[l]] & kBrokenFlag)) << l;
    }
    auto slots = [&](const std::vector<double>& a) {
      if constexpr (Shared) return S::broadcast(a.data() + s[0]);
      else return S::gather(a.data(), s);
    };
    typename Law::Bonds bonds;
    bonds.d0 = S::sub(S::gather(px, j), xi0);
    bonds.d1 = S::sub(S::gather(py, j), xi1);
    bonds.d2 = S::sub(S::gather(pz, j), xi2);
    bonds.xi2 = slots(P.xi2);
    bonds.measure = slots(P.measure);
    bonds.inv_xi = slots(P.inv_xi);
    bonds.measure_per_xi2 = slots(P.measure_per_xi2);
    // The law's slot constants lane by lane (the same operations as once per pattern for runs).
    fill_slots<S>(law, bonds);
    bonds.dead = dead;
    const unsigned fresh = add_bond(law, bonds, f0, f1, f2, w);
    if (fresh) [[unlikely]]
      mark_fresh<4>(fresh, flag_row, k, [&](int l) { return L.critical_energy(P.xi2[s[l]]) * P.measure[s[l]]; },
                    newly, diss);
  }
  finish_rows(law, v, rows, count, f0, f1, f2, w, newly, diss, force, tally);
}

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
// the measures carry the bonds' weights (FamilyPatterns::free_weight). The same bits as the
// portable walk's rows (the same operations in CSR order). The vector ports bound this
// loop: per slot the transpose (on AVX-512 15 shuffles and 8 inserts) and the reference slot (15
// operations) come on top of the law's own work, about three times a grid block's operations per
// bond.
template <bool Intact, bool Weighted, class Law, class C>
void free_records(const Law& law_of, const C& L, const BondView& v, const double* rec, const std::int32_t* group,
                  int count, double* force, BondTally& tally) {
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
    if (k < nmin) [[likely]] {
      for (int l = 0; l < W; ++l) {
        r[l] = rec + 8 * static_cast<std::int64_t>(nbr[l][k]);
        __asm__("" : "+r"(r[l]));
        if constexpr (Weighted) wk[l] = weight[l][k];
      }
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
// The run's slots, and the law's constants of each (in the plan's scratch, computed once per
// pattern and law: RowBlocks::Scratch).
template <class Law>
RunSlots run_slots(const Law& law, const BondView& v, const RowBlocks& plan, const RowRun& run) {
  const FamilyPatterns& P = *v.patterns;
  RowBlocks::Scratch& scratch = plan.scratch;
  const std::int64_t b0 = v.offsets[run.first], n = v.offsets[run.first + 1] - b0;
  const std::int64_t slot0 = P.begin[P.of_row[run.first]];
  RunSlots r{v.neighbor + b0, n, P.xi2.data() + slot0, P.measure.data() + slot0, P.inv_xi.data() + slot0,
             P.measure_per_xi2.data() + slot0};
  if constexpr (Law::kSlotValues) {
    static_assert(Law::kSlots <= RowBlocks::kLawSlots);
    const std::int64_t at = plan.limits_at[static_cast<std::size_t>(run.limits)];
    const std::int64_t stride = plan.limits_at.back();
    // Once per pattern and law (the runs of a 3D block switch patterns at every face line: with
    // the last pattern's constants alone, the 32^3 block of compare_lammps.py computed them 2.7%
    // of its step).
    const RowBlocks::Scratch::LimitsKey key{Law::slot_tag(), law.slot_key()};
    if (!(key == scratch.limits_of)) {
      std::fill(scratch.limits_known.begin(), scratch.limits_known.end(), 0);
      scratch.limits_of = key;
    }
    double* values = scratch.slot_values.data();
    if (!scratch.limits_known[static_cast<std::size_t>(run.limits)]) {
      double out[Law::kSlots];
      for (std::int64_t k = 0; k < n; ++k) {
        law.template slot_values<simd::Scalar>(r.xi2[k], r.inv_xi[k], r.measure[k], r.measure_per_xi2[k], out);
        for (int s = 0; s < Law::kSlots; ++s) values[s * stride + at + k] = out[s];
      }
      scratch.limits_known[static_cast<std::size_t>(run.limits)] = 1;
    }
    for (int s = 0; s < Law::kSlots; ++s) r.slot[s] = values + s * stride + at;
  }
  return r;
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


// The law of one loop on four lanes (every block) and on the widest this CPU has (blocks of
// intact stride-1 runs).
template <class C, class Shape, bool Energy>
struct Laws {
  typename C::template Lanes<Simd4, Shape, Energy> narrow;
  typename C::template Lanes<SimdWide, Shape, Energy> wide;
  explicit Laws(const C& L) : narrow(L), wide(L) {}
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
template <class Law, class C>
void narrow_blocks(const Law& law, const C& L, const BondView& v, const RunSlots& slots, const RowRun& run,
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
template <class Laws, class C>
void mirrored_run(const Laws& laws, const C& L, const BondView& v, const RowBlocks& plan, const RowRun& run,
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

template <class Laws, class C>
void run_avx2(const Laws& laws, const C& L, const BondView& v, const RowBlocks& plan, const RowRun& run,
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
template <class Laws, class C>
void box_avx2(const Laws& laws, const C& L, const BondView& v, const RowBlocks& rows, const RowBox& box,
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
/// Forces (and with Energy the strain energy) of a plan's rows under law L of a shape: the
/// accelerator's entry point.
template <class C, class Shape, bool Energy>
void forces(const C& L, const BondView& v, const RowBlocks& rows, double* force, BondTally& tally) {
  const Laws<C, Shape, Energy> laws(L);
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
  constexpr int W = SimdWide::W;
  const std::size_t nfree = rows.free.size();
  refresh_records(v, rows);
  const double* rec = rows.scratch.records.data();
  for (std::size_t r = 0; r < nfree; r += W) {
    const std::int32_t* group = rows.free.data() + r;
    const int count = static_cast<int>(std::min<std::size_t>(W, nfree - r));
    bool intact = true;
    for (int l = 0; l < count && intact; ++l)
      intact = v.row_broken ? !v.row_broken[group[l]] : !any_flag(v.broken + v.offsets[group[l]], v.broken + v.offsets[group[l] + 1]);
    if (P.free_weight.empty()) {
      if (intact) free_records<true, false>(laws.wide, L, v, rec, group, count, force, tally);
      else free_records<false, false>(laws.wide, L, v, rec, group, count, force, tally);
    } else {
      if (intact) free_records<true, true>(laws.wide, L, v, rec, group, count, force, tally);
      else free_records<false, true>(laws.wide, L, v, rec, group, count, force, tally);
    }
  }
}

}  // namespace
}  // namespace peri::fast
#endif
