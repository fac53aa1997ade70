// Bonds: reference families within the horizon, as full (both-direction) CSR lists built in O(N)
// with a cell list. Structure of arrays: offsets, neighbour index (32-bit) and a flag byte per bond
// (broken). The reference geometry of a family (|xi|^2 and the quadrature measure w_ij V_j of each
// bond) is stored once per distinct family ("pattern"): on a grid every interior row has the same
// sequence, so the kernel reads it from a small table that stays in cache instead of gathering
// reference positions, measures and weights per bond.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "peri/core/simd.hpp"
#include "peri/geometry/discretization.hpp"

namespace peri {

/// Bit 0 of a bond's flag byte: broken (irreversibly; lattice bodies keep other bits beside it).
inline constexpr std::uint8_t kBrokenFlag = 1;

/// The neighbour offsets of a body whose nodes fill its grid (as discretize() places them):
/// every (grid step, quadrature weight) with a non-zero weight, in ascending natural-id order, so
/// a node's family is read off its grid index without a search. Hexagonal grids have one list per
/// row parity (odd rows are shifted by half a spacing).
struct LatticeStencil {
  struct Offset {
    std::int32_t di, dj, dk;  ///< grid steps along x, y (rows) and z
    std::int64_t step;        ///< natural id of the neighbour minus that of the node
    double weight;            ///< quadrature weight w_ij (the same bits as quadrature_weight)
    double xi2;               ///< |xi|^2 of the snapped reference offset (as reference_offset gives)
  };
  std::array<std::int64_t, 3> cells{1, 1, 1};  ///< the body's nodes per direction
  std::array<std::int64_t, 3> extent{0, 0, 0};  ///< largest |di|, |dj|, |dk| of any offset
  std::vector<Offset> by_parity[2];             ///< [row parity]; square and cubic grids use [0]
  bool uniform_volume = false;                  ///< every node of the body has the same measure
};

/// Uniform cell list over all nodes (natural ids), cell size >= the largest reach of any body;
/// and the lattice stencil of every body whose nodes fill their grid, which neighbours_of uses
/// instead of the cells (the same families, about ten times faster to list at 1M nodes).
class CellList {
 public:
  /// `stencils` false: every body is searched through the cells (the reference the stencils are
  /// tested against).
  CellList(const Nodes& nodes, double reach, bool stencils = true);
  /// Cells alone over n points x (3 each; ids 0..n-1), e.g. current positions.
  CellList(const double* x, std::int64_t n, double reach);
  /// The stencil of body b, or nullptr where its nodes are searched through the cells.
  const LatticeStencil* stencil(int body) const {
    return static_cast<std::size_t>(body) < stencils_.size() && !stencils_[body].by_parity[0].empty()
               ? &stencils_[body]
               : nullptr;
  }
  /// Visit every node id in the cells around point x (3x3x3 block), in cell order.
  template <class F>
  void for_each_candidate(const double* x, F&& visit) const {
    const auto c = cell_of(x);
    for (std::int64_t k = std::max<std::int64_t>(c[2] - 1, 0); k <= std::min(c[2] + 1, dims_[2] - 1); ++k)
      for (std::int64_t j = std::max<std::int64_t>(c[1] - 1, 0); j <= std::min(c[1] + 1, dims_[1] - 1); ++j)
        for (std::int64_t i = std::max<std::int64_t>(c[0] - 1, 0); i <= std::min(c[0] + 1, dims_[0] - 1); ++i) {
          const std::int64_t cell = (k * dims_[1] + j) * dims_[0] + i;
          for (std::int64_t p = start_[cell]; p < start_[cell + 1]; ++p) visit(sorted_[p]);
        }
  }

 private:
  std::array<std::int64_t, 3> cell_of(const double* x) const;
  void build(const double* x, std::int64_t n, double reach);
  std::array<double, 3> lo_{};
  double size_ = 1.0;
  std::array<std::int64_t, 3> dims_{1, 1, 1};
  std::vector<std::int64_t> start_;   // ncells + 1
  std::vector<std::int64_t> sorted_;  // node ids grouped by cell, natural order inside a cell
  std::vector<LatticeStencil> stencils_;  // per body (empty lists: no stencil)
};

/// Reference bond vector xi = X_j - X_i snapped to the body's lattice: each component the nearest
/// integer multiple of the grid's unit along it (dx on square and cubic grids; dx/2 and
/// dx sqrt(3)/2 along x and y on hexagonal ones). The raw differences of the stored coordinates
/// vary in their last bits from row to row; snapped, every row of a grid sees the same offsets,
/// weights and family patterns bit for bit wherever it sits, and xi(j, i) == -xi(i, j). Fibers
/// have no grid: their offsets are the raw differences (still antisymmetric bit for bit).
void reference_offset(const BodyGeometry& g, const double* Xi, const double* Xj, double xi[3]);

/// Quadrature weight of neighbour j (reference offset xi from i) in body geometry g: the fraction
/// of j's cell inside the horizon disc/ball of i (1 for Quadrature::Full inside, 0 outside).
/// Symmetric: weight(xi) == weight(-xi) bit for bit.
double quadrature_weight(const BodyGeometry& g, const double xi[3]);

/// Exact area of the intersection of the disc |p| <= r with the rectangle [x0,x1] x [y0,y1].
double disc_rectangle_area(double r, double x0, double x1, double y0, double y1);

/// Neighbours (natural ids, ascending) of node i within its body's horizon, with their weights;
/// and, where `xi2` is given, |xi|^2 of each bond's snapped reference offset (reference_offset).
void neighbours_of(const Nodes& nodes, const CellList& cells, std::int64_t i,
                   std::vector<std::int64_t>& ids, std::vector<double>& weights,
                   std::vector<double>* xi2 = nullptr);

/// A key shared by nodes whose families are the same sequence of (|xi|^2, weight, measure): on a
/// lattice stencil, the body, the row parity and how near the node is to each face (up to the
/// stencil's extent). -1 where no such key is known (a body searched through the cells).
std::int64_t family_class(const Nodes& nodes, const CellList& cells, std::int64_t i);

/// Largest distance at which a body may have a bond (horizon + cell half-diagonal).
double reach(const BodyGeometry& g);

/// True when the reference segment a-b meets the crack, end points included: a slit in the xy
/// projection (segments_cross), a polygon in space (segment_meets_triangle on its fan), both in
/// exact arithmetic (crossing.hpp has the rules and their degenerate cases). Symmetric in (a, b):
/// both ends of a bond see the same answer. Which bodies a crack cuts: Crack::cuts_dimension.
bool crosses(const double* a, const double* b, const Crack& crack);

/// Reference geometry of bond families, one copy per distinct family. Row r's bond b (CSR
/// position) has slot `begin[of_row[r]] + (b - offsets[r])`. |xi|^2 is rounded to a multiple of
/// 2^-46 of the horizon squared (below the round-off of the stored reference positions), so rows
/// whose families differ only by round-off share a pattern, and both ends of a bond, on any
/// rank, see the same |xi|^2 bit for bit.
///
/// Rows of irregular node sets (meshes, point clouds, geodesic spheres: BodyGeometry::irregular)
/// share few families,
/// and a pattern of their own would cost 32 bytes per bond. They keep none: *free* rows (of_row
/// kFree), whose reference slots the loop computes from the reference positions and measures it
/// loads (|xi|^2 = free_xi2, not rounded, the same bits from either end; 1/|xi| as the loop's 1/y:
/// kernels/bond_loop.hpp free_slot), with w V = w_ij V_j from the bond's weight kept as a float
/// (free_weight: 4 bytes per bond, the precision patterns keep weights in) where some free row
/// has a partial weight, else w V = V_j.
struct FamilyPatterns {
  static constexpr std::int32_t kFree = -1;
  std::vector<std::int32_t> of_row;     ///< row -> pattern, or kFree
  bool has_free = false;                ///< some row is free
  /// Per ordered bond (CSR position): the quadrature weight w_ij of a free row's bond (1 for the
  /// other rows' bonds); empty when every free row's bonds weigh 1.
  std::vector<float> free_weight;
  /// w_ij V_j of bond b (CSR position) of a free row, V_j its neighbour's measure.
  double free_measure(std::int64_t b, double volume_j) const {
    return free_weight.empty() ? volume_j : static_cast<double>(free_weight[b]) * volume_j;
  }
  std::vector<std::int64_t> begin{0};   ///< pattern -> first slot (patterns + 1)
  std::vector<double> xi2;              ///< slot -> |xi|^2 [m^2]
  std::vector<double> inv_xi;           ///< slot -> 1 / |xi| [1/m] (from the rounded |xi|^2)
  std::vector<double> measure;          ///< slot -> w_ij V_j (quadrature weight x measure) [m^3]
  std::vector<double> measure_per_xi2;  ///< slot -> w_ij V_j / |xi|^2 [m] (membrane coefficient)
  std::int64_t patterns() const { return static_cast<std::int64_t>(begin.size()) - 1; }
  bool is_free(std::int32_t row) const { return of_row[row] == kFree; }
  /// Slot of a row's bond (not for free rows).
  std::int64_t slot(std::int32_t row, std::int64_t offset_in_family) const {
    return begin[of_row[row]] + offset_in_family;
  }
};

/// |xi|^2 of a free row's bond on the lanes of pack P from its reference vector e = X_j - X_i:
/// (e2 e2 + e0 e0) + e1 e1 with a fused multiply-add (as the law loop's y^2). The same bits from
/// either end.
template <class P>
inline typename P::V free_length2(typename P::V e0, typename P::V e1, typename P::V e2) {
  return P::add(P::fmadd(e2, e2, P::mul(e0, e0)), P::mul(e1, e1));
}
/// free_length2 of the bond from Xi to Xj (free rows, and bonds without patterns).
inline double free_xi2(const double* Xi, const double* Xj) {
  return free_length2<simd::Scalar>(Xj[0] - Xi[0], Xj[1] - Xi[1], Xj[2] - Xi[2]);
}

/// Builds FamilyPatterns row by row, sharing identical families.
class PatternBuilder {
 public:
  PatternBuilder();
  ~PatternBuilder();
  PatternBuilder(const PatternBuilder&) = delete;
  PatternBuilder& operator=(const PatternBuilder&) = delete;
  /// Appends the next row: its bonds' raw |xi|^2 and measures w_ij V_j, in CSR order;
  /// `horizon` sets the rounding of |xi|^2.
  void add_row(const std::vector<double>& xi2, const std::vector<double>& measure, double horizon);
  /// Appends the next row with the pattern of an earlier one (last_pattern() after its add_row).
  void repeat_pattern(std::int32_t pattern, std::int64_t bonds) {
    p_.of_row.push_back(pattern);
    bonds_ += bonds;
  }
  /// Appends the next row as a free one (FamilyPatterns): its bonds' quadrature weights, kept
  /// as floats (the measures add_row would store are float(w) V_j).
  void add_free_row(const std::vector<double>& weights);
  std::int32_t last_pattern() const { return p_.of_row.back(); }
  FamilyPatterns finish();

 private:
  struct Index;
  FamilyPatterns p_;
  std::int64_t bonds_ = 0;  // of the rows so far
  bool weighted_ = false;   // free_weight kept (some free row has a partial weight)
  std::unique_ptr<Index> index_;
};

/// |xi|^2 rounded as FamilyPatterns stores it (see there).
double rounded_xi2(double xi2, double horizon);

/// Bond families of a set of rows in CSR form. Neighbour indices are whatever the builder maps
/// natural ids to (local indices on a rank).
struct BondFamilies {
  std::vector<std::int64_t> offsets{0};  ///< rows + 1
  std::vector<std::int32_t> neighbor;    ///< one per ordered bond
  std::vector<std::uint8_t> broken;      ///< 1 = broken (irreversible)
  /// Per row: 0 only if every flag byte of the row is 0 (1 may also mean none is). Whoever sets a
  /// flag sets its row's byte too (or calls summarize_rows); the vector loop then reads no flag
  /// bytes of rows whose byte is 0.
  std::vector<std::uint8_t> row_broken;
  FamilyPatterns patterns;               ///< reference |xi|^2 and w_ij V_j of every bond
  /// Per-bond history of laws that keep one (LawEntry::history): history_stride values per
  /// ordered bond, zero at the start; empty when no body's law keeps any.
  std::vector<double> history;
  int history_stride = 0;
  std::int64_t rows() const { return static_cast<std::int64_t>(offsets.size()) - 1; }
  std::int64_t size() const { return static_cast<std::int64_t>(neighbor.size()); }
  /// Recomputes row_broken from the flags.
  void summarize_rows();
  double bytes_per_bond() const;
};

}  // namespace peri
