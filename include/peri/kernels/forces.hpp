// Forces: the loop layer. Walks the CSR families of a list of owned rows, applies one BondLaw per
// body, writes force densities into a flat array, and updates the broken flags. No MPI, no PETSc:
// the caller passes local arrays (owned nodes first, ghosts after).
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "peri/bonds/bonds.hpp"
#include "peri/core/simd.hpp"
#include "peri/partition/domain.hpp"
#include "peri/models/law.hpp"

namespace peri {

/// Read/write view of what the bond loop needs (all local arrays).
struct BondView {
  const double* X = nullptr;        ///< 3 * local reference positions
  const double* u = nullptr;        ///< 3 * local displacements
  const double* volume = nullptr;   ///< local measures
  const std::int64_t* offsets = nullptr;
  const std::int32_t* neighbor = nullptr;
  std::uint8_t* broken = nullptr;
  const FamilyPatterns* patterns = nullptr;  ///< nullptr: |xi|^2 from X, measure V_j (weight 1), as free rows
  const double* x = nullptr;        ///< current positions, three planes (bond_forces only)
  std::int64_t x_stride = 0;        ///< doubles from one plane of x to the next
  std::uint8_t* row_broken = nullptr;  ///< BondFamilies::row_broken, or nullptr: flags are read
  /// Energy calls of bond_forces: where each row's strain energy density 1/2 sum_j w V_j
  /// [J/m^3] is written (frames), or nullptr.
  double* energy_density = nullptr;
  /// Per-bond history of laws that keep one (BondFamilies::history): history_stride values per
  /// ordered bond, or nullptr; commit_history: this force pass may change it.
  double* history = nullptr;
  int history_stride = 0;
  bool commit_history = false;
  /// The incremental crack-tip advance (kernels/tip_advance.hpp), or nullptr: per local node,
  /// whether it may break a bond now. A bond reaching the failure test with neither end allowed
  /// stays intact. Only the portable walk reads it (the caller routes the rows that may break
  /// there).
  const std::uint8_t* may_break = nullptr;

  /// Whether row i's reference geometry comes from a family pattern (else from X and volume:
  /// FamilyPatterns' free rows, or no patterns at all).
  bool patterned(std::int32_t i) const noexcept { return patterns && !patterns->is_free(i); }
  /// Reference |xi|^2 of bond b of row i.
  double xi2(std::int32_t i, std::int64_t b) const noexcept {
    if (patterned(i)) return patterns->xi2[patterns->slot(i, b - offsets[i])];
    return free_xi2(&X[3 * static_cast<std::int64_t>(i)], &X[3 * static_cast<std::int64_t>(neighbor[b])]);
  }
  /// Quadrature measure w_ij V_j of bond b of row i [m^3].
  double measure(std::int32_t i, std::int64_t b) const noexcept {
    if (patterned(i)) return patterns->measure[patterns->slot(i, b - offsets[i])];
    return patterns ? patterns->free_measure(b, volume[neighbor[b]]) : volume[neighbor[b]];
  }
};

/// Doubles from one plane of current positions to the next for n local nodes: n rounded up to
/// 168 past a multiple of 512 (planes 1344 bytes apart modulo 4 KiB). With n planes a multiple of
/// 4 KiB apart (n = 64^3, or a rank's 126 974 nodes) a neighbour's x, y and z fall into one set of
/// the L1 cache, and so do those of every other neighbour line, and the bond loop lost a third of
/// its speed to conflict misses.
std::int64_t position_plane_stride(std::int64_t n);

/// Current positions x = X + u of local nodes [begin, end) as three planes, `stride` doubles apart
/// (x of every node, then y, then z: what bond_forces reads). The vector loop loads the x of four
/// consecutive nodes with one load.
void current_positions(const double* X, const double* u, std::int32_t begin, std::int32_t end,
                       std::int64_t stride, double* x);

/// Rows that the vector loop evaluates four or eight at a time (a block, one row per lane): rows
/// first + l * stride (l = 0 .. count-1, count >= 4; the last block ends at the run's end,
/// overlapping the one before, whose rows it evaluates again but does not write), one family
/// pattern, and for every k the k-th neighbour of row l is node j + l * stride, j that of row `first`. So the loop reads
/// one neighbour list for the whole run. Stride 1: interior runs of a grid row (in the natural
/// order a partition keeps), whose neighbours' positions the loop loads with one vector load per
/// coordinate. Larger strides: rows a grid row apart, e.g. along a body's edge, whose neighbours
/// it reads from the plan's mirror (RowBlocks::mirror_columns) or gathers.
struct RowRun {
  std::int32_t first;
  std::int32_t stride;
  std::int32_t count;
  /// -1, or (strided runs next to a partition boundary, whose ghost neighbours are numbered
  /// compactly) where in RowBlocks::slot_shifts this run's per-slot neighbour shifts start: the
  /// k-th neighbour of row l is then j + l t_k instead of j + l stride.
  std::int32_t slot_shifts = -1;
  /// -1, or (strided runs of eight rows or more) where in RowBlocks::mirror_slots this run's
  /// mirror places start: its rows' own positions, then those of each slot's neighbours.
  std::int32_t mirror = -1;
  /// -1, or the first of this run's entries in the plan's cache of dead lanes (RowBlocks).
  std::int32_t dead_cache = -1;
  /// Its family pattern among the plan's run patterns (RowBlocks::limits_at).
  std::int32_t limits = -1;
};

/// Nodes node + m step (m < length) of the local positions, copied to places at + m of a plan's
/// mirror (RowBlocks::mirror_columns).
struct MirrorColumn {
  std::int64_t node = 0;
  std::int32_t step = 0;
  std::int32_t length = 0;
  std::int64_t at = 0;
};

/// A slot k of a box's family pattern: how its bonds are shared between the box's rows.
struct BoxSlot {
  enum Kind : std::uint8_t { Own, Produce, Consume };
  Kind kind = Own;       ///< Own: each end evaluates the bond; Produce / Consume: see RowBox
  std::int32_t lane = 0;   ///< the partner's lane offset (rows along a line)
  std::int32_t line = 0;   ///< the partner's line offset (> 0 for Produce, < 0 for Consume)
  std::int32_t column = 0; ///< the pair's column of the box's coefficient buffer
};

/// Stride-1 runs (`RowBlocks::runs[run_begin, run_end)`, its lines) of one family pattern and
/// width whose first rows are a constant stride apart and whose neighbour lists are the first line's
/// shifted by that stride: the interior of a 2D grid body (plan_rows makes a box only where at
/// least a quarter of the slots are produced for a partner inside it: not in a 3D block, whose
/// planes produce 9%). Row
/// (line b, lane a) and its partner of slot k (line b + line, lane a + lane) see each other's bond
/// as slots k and k' with the same |xi|^2 and w V, so the bond's scalar coefficient is the same
/// bits from both ends (their y^2 agree, x_i - x_j being exactly -(x_j - x_i)). The loop
/// evaluates such a bond once, at the end whose line comes first (Produce), keeps the
/// coefficient in a ring of `window` lines, and the other end (Consume) multiplies it by its own
/// bond vector in its own CSR order: each row's sum, and so every force, is the same bits as with
/// every bond evaluated from both ends. Pairs within one line (line offset 0) stay Own.
struct RowBox {
  std::size_t run_begin = 0, run_end = 0;
  std::int32_t width = 0;    ///< rows per line
  std::int32_t pad = 0;      ///< largest |lane| of a paired slot
  std::int32_t window = 0;   ///< largest line offset of a paired slot + 1
  std::int32_t columns = 0;  ///< paired bonds per row
  std::vector<BoxSlot> slots;  ///< one per slot of the pattern
};

/// A list of owned rows grouped for the vector loop: `runs`, `rest`, every other row with a
/// family pattern (corners, partition boundaries), sorted by pattern, whose lanes the loop gathers
/// element by element, and `free`, the rows without one. Each row's force is the same bits
/// either way.
struct RowBlocks {
  std::vector<RowRun> runs;
  std::vector<std::int32_t> rest;
  /// FamilyPatterns' free rows (irregular node sets), in the order given (a domain's: storage
  /// order, along a Morton curve: partition.hpp), by family size within windows of 16 rows:
  /// the loop evaluates them a vector width at a time, loading the neighbours' node lines
  /// (Scratch::records: current and reference positions, measure) and computing each bond's
  /// reference slot from them.
  std::vector<std::int32_t> free;
  std::int64_t free_nodes = 0;  ///< local nodes the free rows read: 0 .. free_nodes-1
  /// The free rows' neighbours as the SIMD loop reads them, group by group of the loop's W
  /// rows (`free` in order), slot-major: lane l's k-th neighbour j as 8 j (its node record's
  /// offset in Scratch::records) at free_lanes[free_lanes_at[group] + k W + l], for k up to
  /// the group's longest family (a lane past its row's end repeats its last neighbour; a row
  /// without bonds, itself). One load from one stream per lane and slot, where the CSR lists
  /// cost a pointer per lane that the loop could not keep in registers (the 400 x 400 mesh
  /// 1.3 times as fast). 4 bytes per ordered bond: kept only for free rows without weights
  /// (FamilyPatterns::free_weight empty), whose bonds then take about 9.5 bytes, not 13, and
  /// up to 2^28 local nodes. Both empty otherwise or without the SIMD loop.
  std::vector<std::int32_t> free_lanes;
  std::vector<std::int64_t> free_lanes_at;
  /// The free rows' loop asks for the node lines of slot k + kLineAhead while at slot k (on a
  /// body larger than the cache the lines came late: the 400 x 400 mesh 1.10 times as fast,
  /// performance.md); free_lanes holds kLineAhead W entries (0) past its last group for it.
  static constexpr std::int64_t kLineAhead = 24;
  /// Bytes the plan keeps per bond it covers beyond the bond arrays (free_lanes).
  std::size_t extra_bytes() const { return free_lanes.size() * sizeof(std::int32_t) + free_lanes_at.size() * sizeof(std::int64_t); }
  std::vector<RowBox> boxes;  ///< runs whose bonds are evaluated once per pair (RowBox)
  std::vector<std::int32_t> slot_shifts;  ///< per-slot neighbour shifts of some strided runs (RowRun)
  /// Strided runs read their neighbours' positions with one vector load per coordinate, as
  /// stride-1 runs do, from a mirror: each call of bond_forces first copies the positions of
  /// `mirror_columns` (nodes a stride apart, e.g. a body's x face along y) into consecutive places.
  /// A mirrored run's lane l then finds its own position at mirror_slots[run.mirror] + l and
  /// its k-th neighbour's at mirror_slots[run.mirror + 1 + k] + l. The runs of one stride share
  /// columns (the 64^3 block: 12 columns of 4096 nodes for 24 576 face rows).
  std::vector<MirrorColumn> mirror_columns;
  std::vector<std::int32_t> mirror_slots;
  std::int64_t mirror_stride = 0;  ///< doubles from one plane of the mirror to the next
  /// Blocks of eight rows (AVX-512; else pairs of four) holding broken bonds read their flags as
  /// lane bits, a byte per slot (bit l: lane l's bond broken). The plan keeps those bytes from
  /// call to call (dead_cache_entries entries, one per block of the vector width, allocated at
  /// the first such block) and updates them as the loop breaks bonds: a fragmenting body's
  /// blocks then read an eighth of the flag bytes' traffic (the 64^3 block of
  /// compare_lammps.py: 4 MB instead of 30 MB per call; its loop 1.16-1.19 times as fast at steps
  /// 15 and 50, as fast as on the intact block). Flags changed otherwise (precracks, a release
  /// stage, a restart, flags cleared in place) need forget_broken(); a call with another flag
  /// array than the last forgets by itself.
  std::int64_t dead_cache_entries = 0;
  /// The bond law's constants of each slot of the runs' family patterns (Scratch::slot_values),
  /// computed once per pattern and law: pattern p of the runs (RowRun::limits) at limits_at[p]
  /// .. limits_at[p + 1] of those arrays.
  std::vector<std::int64_t> limits_at;
  void forget_broken() const;
  /// The loop's working memory, sized by plan_rows and reused by every call (no allocation per
  /// step): for the boxes, the coefficient ring, which lines completed their Produce slots, and a
  /// line's slot kinds as segments of consecutive slots (for blocks away from the line's ends,
  /// and near them) and ring addresses; for blocks of runs with broken bonds, the broken flags
  /// of the block's rows as one byte of lane bits per slot, and the slots not broken on every
  /// lane; for each family pattern of the runs, the bond law's constants of each
  /// slot (and which patterns hold them); the mirror (three planes, mirror_stride apart).
  /// Most per-slot constants a vectorized law may keep (models/laws/: PMB keeps six).
  static constexpr int kLawSlots = 6;
  struct Scratch {
    struct Segment {
      BoxSlot::Kind kind;
      std::int32_t begin, end;
    };
    simd::AlignedVector<double> ring;
    std::vector<std::uint8_t> produced;
    std::vector<Segment> inner, edge;
    std::vector<double*> at;
    std::vector<std::uint8_t> dead_lanes;
    std::vector<std::uint32_t> live;
    /// The law's constants of each slot of the runs' patterns (law slot_values), kLawSlots arrays
    /// of limits_at.back() each, and which patterns hold them.
    std::vector<double> slot_values;
    std::vector<std::uint8_t> limits_known;  ///< per run pattern (RowBlocks::limits_at)
    /// The law the slot constants were computed for: its shape and the constants they depend on
    /// (a call with another law forgets them all).
    struct LimitsKey {
      const void* law = nullptr;
      std::array<double, 4> key{};
      bool operator==(const LimitsKey& o) const { return law == o.law && key == o.key; }
    };
    LimitsKey limits_of;
    simd::AlignedVector<double> mirror;
    /// The free rows' node records: per local node 0 .. free_nodes-1, one cache line
    /// [x, y, z, V, X, Y, Z, 0] (current position, measure, reference position); the current
    /// positions copied by each call, the rest where the view's X or volume differ from
    /// `records_of`.
    simd::AlignedVector<double> records;
    std::array<const double*, 2> records_of{nullptr, nullptr};
    std::vector<std::uint8_t> dead_cache, dead_known;  ///< lane bytes, and whether each entry holds them
    std::vector<std::uint32_t> live_cache;             ///< each entry's live slots (bits, live_words words)
    std::int64_t dead_stride = 0;                      ///< bytes per entry
    std::int64_t live_words = 0;                       ///< words of live-slot bits per entry
    const std::uint8_t* dead_flags = nullptr;          ///< the flags the cache describes
  };
  mutable Scratch scratch;
  std::size_t run_rows() const {
    std::size_t n = 0;
    for (const RowRun& r : runs) n += static_cast<std::size_t>(r.count);
    return n;
  }
  std::size_t rows() const { return run_rows() + rest.size() + free.size(); }
};

/// Groups `rows` into runs (first of consecutive rows in list order, then, among the others
/// sorted by pattern, of rows a constant stride apart) and the rest, and consecutive stride-1
/// runs into boxes (`pair_bonds`; the forces are the same bits without). O(bonds); the
/// bond topology never changes (bonds only break), so callers plan once and reuse the plan.
RowBlocks plan_rows(const BondView& view, const std::int32_t* rows, std::size_t nrows, bool pair_bonds = true);

/// Sums a bond loop produces (this rank's owned rows).
struct BondTally {
  double strain_energy = 0;   ///< sum_i V_i * 1/2 sum_j w_ij V_j  [J] (eq. 5), intact bonds
  double dissipated = 0;      ///< energy of bonds broken during this call, at breaking [J]
  std::int64_t newly_broken = 0;  ///< ordered bonds broken during this call
  double viscous_power = 0;   ///< power dissipated by lattice dashpots at this call [W]
  BondTally& operator+=(const BondTally& o) {
    strain_energy += o.strain_energy;
    dissipated += o.dissipated;
    viscous_power += o.viscous_power;
    newly_broken += o.newly_broken;
    return *this;
  }
};

/// The vector loop this build runs for bond laws without hardening: "avx512" (AVX-512 F and VL:
/// intact runs eight lanes at a time, PMB's 1/|y| from the rsqrt14 estimate), "avx2" (AVX2 + FMA,
/// four lanes) or "portable" (the scalar loop, which also serves hardening laws). Chosen at
/// compile time (-march); the paths agree to round-off, and each is bit-identical on any rank count.
const char* bond_kernel_isa();

/// Force densities (N/m^3) on `rows`, written to force[3*row..]; bonds reaching the failure test
/// are broken (irreversibly) first. With `with_energy`, strain energy is summed too. Reads the
/// current positions `view.x` (of the rows and their neighbours) and the family patterns.
void bond_forces(const BondLaw& law, const BondView& view, const RowBlocks& rows, double* force,
                 bool with_energy, BondTally& tally);
/// The same for a plain list of rows (plans it first: for tests and one-off calls).
void bond_forces(const BondLaw& law, const BondView& view, const std::int32_t* rows,
                 std::size_t nrows, double* force, bool with_energy, BondTally& tally);

/// Same loop that only sums the strain energy of intact bonds (no forces, no breaking). With
/// `density`, also writes each row's strain energy density 1/2 sum_j w_ij V_j [J/m^3] to density[i].
double bond_energy(const BondLaw& law, const BondView& view, const std::int32_t* rows,
                   std::size_t nrows, double* density = nullptr);

/// Damage of each row: broken fraction of its family, weighted by w_ij V_j (0 intact, 1 free).
void node_damage(const BondView& view, const std::int32_t* rows, std::size_t nrows, double* damage);

/// Stable explicit time step bound over `rows` (Silling & Askari 2005):
/// dt_i = sqrt(2 rho / sum_j w_ij V_j C_ij), C_ij = d f_hat/dy at the reference state.
double stable_time_step(const BondLaw& law, double density, const BondView& view,
                        const std::int32_t* rows, std::size_t nrows);

}  // namespace peri
