// The bond loop's SIMD accelerator: the rows of a plan (RowBlocks: runs, boxes, mirrors, the rest,
// the free rows) evaluated four or eight at a time, one row per lane, for a law with a vector form.
// Each lane walks its row's bonds in CSR order with the law's operations on the pack
// (models/laws/), so a row's force is the same bits as the portable walk's (bond_loop.hpp) and as
// any other grouping's.
//
// This file walks the plan: the grouping of rows into runs and boxes by plan_rows
// (kernels/plan.cpp), the ring of coefficients a box's lines produce and consume, the mirror of
// strided runs, the per-slot law constants cached per pattern. The loops over a block of rows
// are grid_blocks.hpp's (rows with family patterns) and free_rows.hpp's (irregular bodies' rows,
// which keep none); what both share is fast_lanes.hpp's. It needs AVX2 + FMA (PERI_AVX2); without
// them every law runs in the portable walk.
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
// In this order (the block loops, the free rows, then the walk below) the definitions are in the
// order they had as one file, and the machine code is that file's (with the free rows' group loop
// in a function of its own, GCC inlined other calls into forces() and the grid cases measured
// 0.8-0.9).
#include "peri/kernels/fast_lanes.hpp"
#include "peri/kernels/grid_blocks.hpp"
#include "peri/kernels/free_rows.hpp"

namespace peri::fast {
// Internal linkage in every file that instantiates the loop (laws.cpp, and a test's own law): the
// compiler then sees every call of these templates and inlines and specializes them as it did
// when they were one file's static functions (as weak templates, the intact boxes ran at 0.8).
namespace {

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
  constexpr std::size_t kAhead = 2 * W;  // the lists of the group two groups on
  for (std::size_t r = 0; r < nfree; r += W) {
    const std::int32_t* group = rows.free.data() + r;
    const int count = static_cast<int>(std::min<std::size_t>(W, nfree - r));
    if (r + kAhead < nfree && rows.free_lanes_at.empty())
      prefetch_lists(v, group + kAhead, static_cast<int>(std::min<std::size_t>(W, nfree - r - kAhead)));
    bool intact = true;
    for (int l = 0; l < count && intact; ++l)
      intact = v.row_broken ? !v.row_broken[group[l]] : !any_flag(v.broken + v.offsets[group[l]], v.broken + v.offsets[group[l] + 1]);
    if (P.free_weight.empty()) {
      const std::int32_t* lanes = rows.free_lanes_at.empty() ? nullptr : rows.free_lanes.data() + rows.free_lanes_at[r / W];
      if (intact) free_records<true, false>(laws.wide, L, v, rec, group, count, force, tally, lanes);
      else free_records<false, false>(laws.wide, L, v, rec, group, count, force, tally, lanes);
    } else {
      if (intact) free_records<true, true>(laws.wide, L, v, rec, group, count, force, tally);
      else free_records<false, true>(laws.wide, L, v, rec, group, count, force, tally);
    }
  }
}

}  // namespace
}  // namespace peri::fast
#endif
