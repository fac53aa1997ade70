// Plans of the bond loop: a list of rows grouped into runs (consecutive rows, or rows a constant
// stride apart, sharing one family pattern and a shifted neighbour list), boxes of runs whose
// bonds are evaluated once per pair, mirrors of strided runs, and the rest. O(bonds), made once:
// the bond topology never changes (bonds only break). The accelerator (fast_loop.hpp) reads them;
// the portable walk takes their rows in order.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>
#include <utility>
#include <vector>

#include "peri/kernels/bond_loop.hpp"
#include "peri/kernels/fast_loop.hpp"
#include "peri/kernels/forces.hpp"

namespace peri {
#if defined(PERI_AVX2)
using fast::kWideBlocks;
using fast::kWideRows;
#endif

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

#if defined(PERI_AVX2)
// RowBlocks::free_lanes of the plan's free rows, W lanes a group.
void interleave_free_lanes(const BondView& v, RowBlocks& plan, int W) {
  const std::size_t nfree = plan.free.size();
  plan.free_lanes_at = lane_group_starts(v, plan.free.data(), nfree, static_cast<std::size_t>(W));
  // (kLineAhead W entries more: the loop's requests for the lines ahead read past the last group.)
  const std::int64_t pad = nfree > 0 ? RowBlocks::kLineAhead * W : 0;
  plan.free_lanes.assign(static_cast<std::size_t>(plan.free_lanes_at.back() + pad), 0);
  for (std::size_t r = 0, g = 0; r < nfree; r += W, ++g) {
    std::int32_t* at = plan.free_lanes.data() + plan.free_lanes_at[g];
    const std::int64_t slots = (plan.free_lanes_at[g + 1] - plan.free_lanes_at[g]) / W;
    for (int l = 0; l < W; ++l) {
      const std::int32_t i = plan.free[std::min(r + l, nfree - 1)];  // idle lanes repeat the last row
      const std::int64_t b0 = v.offsets[i], n = v.offsets[i + 1] - b0;
      for (std::int64_t k = 0; k < slots; ++k) at[k * W + l] = 8 * (n > 0 ? v.neighbor[b0 + std::min(k, n - 1)] : i);
    }
  }
}
#endif

}  // namespace

RowBlocks plan_rows(const BondView& v, const std::int32_t* rows, std::size_t nrows, bool pair_bonds) {
  RowBlocks plan;
  if (!v.patterns) {
    plan.rest.assign(rows, rows + nrows);
    return plan;
  }
  const FamilyPatterns& P = *v.patterns;
  // Free rows (no pattern: irregular node sets) go to their own list.
  std::vector<std::int32_t> patterned;
  if (P.has_free) {
    patterned.reserve(nrows);
    for (std::size_t r = 0; r < nrows; ++r) (P.is_free(rows[r]) ? plan.free : patterned).push_back(rows[r]);
    rows = patterned.data();
    nrows = patterned.size();
    // In the order given (a domain's rows: storage order, a Morton curve through an irregular
    // body: partition.hpp), so that consecutive rows share most neighbours in cache and a vector
    // group's rows read their neighbour lists and flags nearly as one stream; by family size
    // only within windows of 16 rows, so that the rows of a group end at nearly the same slot.
    // (Sorting the rows along the curve here, over node numbers in file order, and by size within
    // windows of 256 scattered those reads: 0.83-0.87 times as fast on the jittered
    // cloud, 0.68 on the jittered mesh: bench_kernels, 3 rounds alternating.)
    constexpr std::size_t kFreeWindow = 16;
    auto size_of = [&](std::int32_t i) { return v.offsets[i + 1] - v.offsets[i]; };
    for (std::size_t w = 0; w < plan.free.size(); w += kFreeWindow)
      std::stable_sort(plan.free.begin() + static_cast<std::ptrdiff_t>(w),
                       plan.free.begin() + static_cast<std::ptrdiff_t>(std::min(plan.free.size(), w + kFreeWindow)),
                       [&](std::int32_t a, std::int32_t b) { return size_of(a) < size_of(b); });
    for (const std::int32_t i : plan.free) {
      plan.free_nodes = std::max<std::int64_t>(plan.free_nodes, i + 1);
      for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b)
        plan.free_nodes = std::max<std::int64_t>(plan.free_nodes, v.neighbor[b] + 1);
    }
#if defined(PERI_AVX2)
    // (The records' offsets, 8 j, held in 32 bits: up to 2^28 local nodes.)
    if (P.free_weight.empty() && plan.free_nodes <= std::numeric_limits<std::int32_t>::max() / 8)
      interleave_free_lanes(v, plan, simd::Wide::W);
#endif
  }
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
    scratch.slot_values.assign(RowBlocks::kLawSlots * slots, 0.0);
    scratch.limits_known.assign(index.size(), 0);
  }
  return plan;
}

void RowBlocks::forget_broken() const { std::fill(scratch.dead_known.begin(), scratch.dead_known.end(), 0); }

}  // namespace peri
