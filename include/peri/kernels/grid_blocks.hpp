// The SIMD accelerator's block loops over rows with family patterns (fast_loop.hpp walks a plan
// and calls them): a block of four or eight rows a constant stride apart, one per lane, with one
// pattern (intact: software-pipelined, stopping where a bond breaks; damaged: the flagging loop
// over the dead-lane cache), and any one to four rows gathered element by element (the rest).
// A row's force is the same bits as the portable walk's. Needs AVX2 + FMA (PERI_AVX2).
#pragma once
#include "peri/core/simd.hpp"

#if defined(PERI_AVX2)
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "peri/kernels/bond_loop.hpp"
#include "peri/kernels/fast_lanes.hpp"
#include "peri/kernels/forces.hpp"

namespace peri::fast {
// Internal linkage in every file that instantiates the loop (fast_loop.hpp says why).
namespace {

using simd::Simd4;
using SimdWide = simd::Wide;

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

}  // namespace
}  // namespace peri::fast
#endif
