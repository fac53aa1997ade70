// The one walk over bonds: a row's family in CSR order (`family(view, i)`), and the passes built
// on it for any bond law of models/laws/ (forces with breaking, energy, the SNES tangent's block
// rows). These are the portable loop: every law runs here one bond at a time (Scalar pack), and
// laws with a vector form also run in the SIMD accelerator (fast_loop.hpp), whose rows are the
// same bits (the same operations in the same order, bond by bond and row by row).
#pragma once
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "peri/core/simd.hpp"
#include "peri/kernels/forces.hpp"
#include "peri/models/laws/bond_lanes.hpp"

namespace peri {

/// Whether law lanes E read 1/|xi| (a member `kReadsInverseLength`; a law without one is taken to).
template <class E>
constexpr bool reads_inverse_length() {
  if constexpr (requires { E::kReadsInverseLength; }) return E::kReadsInverseLength;
  else return true;
}

/// The reference slot of a free row's bond (FamilyPatterns) on the lanes of pack P, from its
/// reference vector e = X_j - X_i and its measure w_ij V_j (FamilyPatterns::free_measure):
/// |xi|^2 = free_length2(e), 1/|xi| by simd::Root (as the laws' 1/y: on AVX-512 the estimate
/// and its correction, no division), and w V / |xi|^2 = (w V / |xi|) / |xi|; for laws that do
/// not read 1/|xi| (`InverseLength` false), w V / |xi|^2 by one division instead, so that their
/// loop takes no square root of |xi|^2 (on every instruction set). The vector loop's lanes and
/// the portable walk compute the same bits.
template <class P, bool InverseLength = true, class B>
__attribute__((always_inline)) inline void free_slot(const simd::Root<P>& root, typename P::V e0, typename P::V e1,
                                                     typename P::V e2, typename P::V measure, B& b) {
  b.xi2 = free_length2<P>(e0, e1, e2);
  typename P::V xi;
  root.finish(b.xi2, root.front(b.xi2), xi, b.inv_xi);
  b.measure = measure;
  if constexpr (!InverseLength) {
    b.measure_per_xi2 = P::div(measure, b.xi2);
    return;
  }
  b.measure_per_xi2 = P::mul(P::mul(measure, b.inv_xi), b.inv_xi);
}

/// One bond of a row's family: its CSR position, neighbour and reference slot (slot -1: none, the
/// reference geometry from the positions; `free`: a free row's, free_slot).
class FamilyBond {
 public:
  FamilyBond(const BondView& v, std::int32_t i, std::int64_t b, std::int64_t slot, bool free = false)
      : v_(&v), i_(i), b_(b), slot_(slot), free_(free) {}
  std::int64_t at() const { return b_; }  ///< CSR position
  std::int32_t j() const { return v_->neighbor[b_]; }
  bool broken() const { return v_->broken[b_] & kBrokenFlag; }
  std::uint8_t& flag() const { return v_->broken[b_]; }
  /// |xi|^2 (the family pattern's, or from the reference positions: free rows, no patterns).
  double xi2() const { return slot_ >= 0 ? v_->patterns->xi2[slot_] : v_->xi2(i_, b_); }
  /// w_ij V_j [m^3].
  double measure() const { return slot_ >= 0 ? v_->patterns->measure[slot_] : v_->measure(i_, b_); }
  /// The reference slot as the laws read it: |xi|^2, 1/|xi|, w V and w V / |xi|^2, each computed
  /// once (a pattern's stored slot; a free row's by free_slot, as the vector loop's lanes; else
  /// from the positions).
  struct Reference {
    double xi2, inv_xi, measure, measure_per_xi2;
  };
  /// `InverseLength`: whether the law reads 1/|xi| (free_slot).
  template <bool InverseLength = true>
  Reference reference() const {
    if (slot_ >= 0) {
      const FamilyPatterns& p = *v_->patterns;
      return {p.xi2[slot_], p.inv_xi[slot_], p.measure[slot_], p.measure_per_xi2[slot_]};
    }
    const double xi2 = v_->xi2(i_, b_), m = v_->measure(i_, b_);
    if (!free_) return {xi2, 1.0 / std::sqrt(xi2), m, m / xi2};
    const double* Xi = v_->X + 3 * static_cast<std::int64_t>(i_);
    const double* Xj = v_->X + 3 * static_cast<std::int64_t>(j());
    Reference s;
    free_slot<simd::Scalar, InverseLength>(simd::Root<simd::Scalar>{}, Xj[0] - Xi[0], Xj[1] - Xi[1], Xj[2] - Xi[2], m, s);
    s.xi2 = xi2;  // the view's |xi|^2 (free_xi2), as xi2() gives it
    return s;
  }

 private:
  const BondView* v_;
  std::int32_t i_;
  std::int64_t b_, slot_;
  bool free_;
};

/// The bonds of row i in CSR order: `for (const FamilyBond& bond : family(view, i))`.
class Family {
 public:
  Family(const BondView& v, std::int32_t i)
      : v_(&v), i_(i), begin_(v.offsets[i]), end_(v.offsets[i + 1]),
        slot0_(v.patterned(i) ? v.patterns->begin[v.patterns->of_row[i]] : -1),
        free_(v.patterns && v.patterns->is_free(i)) {}
  struct iterator {
    const Family* f;
    std::int64_t b;
    FamilyBond operator*() const {
      return {*f->v_, f->i_, b, f->slot0_ < 0 ? -1 : f->slot0_ + (b - f->begin_), f->free_};
    }
    iterator& operator++() {
      ++b;
      return *this;
    }
    bool operator!=(const iterator& o) const { return b != o.b; }
  };
  iterator begin() const { return {this, begin_}; }
  iterator end() const { return {this, end_}; }
  std::int64_t size() const { return end_ - begin_; }

 private:
  const BondView* v_;
  std::int32_t i_;
  std::int64_t begin_, end_, slot0_;
  bool free_;
};
inline Family family(const BondView& v, std::int32_t i) { return Family(v, i); }

/// Rows rows[0 .. nrows-1] in groups of W, their bonds slot-major (slot k of the group's lane l at
/// starts[g] + k W + l; the vector loops' interleaved lists, RowBlocks::free_lanes and
/// DashpotLanes): each group's first slot, then the end; a group holds W times its longest
/// family's slots.
inline std::vector<std::int64_t> lane_group_starts(const BondView& v, const std::int32_t* rows, std::size_t nrows,
                                                   std::size_t W) {
  std::vector<std::int64_t> starts{0};
  for (std::size_t r = 0; r < nrows; r += W) {
    std::int64_t slots = 0;
    for (std::size_t l = r; l < std::min(nrows, r + W); ++l) slots = std::max(slots, v.offsets[rows[l] + 1] - v.offsets[rows[l]]);
    starts.push_back(starts.back() + slots * static_cast<std::int64_t>(W));
  }
  return starts;
}

namespace law_loop {

/// Bond `bond` of row i as one lane of law E (E::Bonds on the Scalar pack): y = x_j - x_i from
/// the view's position planes, the reference slot, and the law's slot constants.
template <class E>
typename E::Bonds scalar_bond(const E& law, const BondView& v, std::int32_t i, const FamilyBond& bond) {
  typename E::Bonds b;
  const std::int32_t j = bond.j();
  b.d0 = v.x[j] - v.x[i];
  b.d1 = v.x[v.x_stride + j] - v.x[v.x_stride + i];
  b.d2 = v.x[2 * v.x_stride + j] - v.x[2 * v.x_stride + i];
  const FamilyBond::Reference r = bond.reference<reads_inverse_length<E>()>();
  b.xi2 = r.xi2;
  b.inv_xi = r.inv_xi;
  b.measure = r.measure;
  b.measure_per_xi2 = r.measure_per_xi2;
  fill_slots<simd::Scalar>(law, b);
  b.dead = bond.broken() ? 1u : 0u;
  if constexpr (requires { b.history; })  // a law with per-bond history: read only, unless forces() commits
    b.history = BondHistory{v.history ? v.history + bond.at() * v.history_stride : nullptr, false, nullptr};
  return b;
}

/// y^2 = (y_z^2 + y_x^2) + y_y^2: two independent products (the vector loop's order).
template <class P, class B>
inline typename P::V squared_length(const B& b) {
  return P::add(P::fmadd(b.d2, b.d2, P::mul(b.d0, b.d0)), P::mul(b.d1, b.d1));
}

/// The micropotential w w_ij V_j bond `bond` of row i holds now, as an intact bond of law L.
template <class Law>
double stored_energy(const Law& constants, const BondView& v, std::int32_t i, const FamilyBond& bond) {
  Law intact = constants;
  intact.make_intact();
  return intact.visit_shape([&](auto shape) {
    const typename Law::template Lanes<simd::Scalar, decltype(shape), true> law(intact);
    const auto b = scalar_bond(law, v, i, bond);
    double w = 0;
    unsigned fresh = 0;
    law.coefficient(b, law.front(b, squared_length<simd::Scalar>(b)), w, fresh);
    return w;
  });
}

/// Force densities of rows (law E on the Scalar pack): each row's bonds in CSR order, a bond
/// reaching the failure test flagged and its energy at failure (critical_energy) booked. A law
/// with per-bond history updates it here when the view commits, and books what it dissipates.
template <class E, class Law>
void forces(const E& law, const Law& constants, const BondView& v, const std::int32_t* rows, std::size_t n,
            double* force, BondTally& tally) {
  const double c_row = law.row_factor();
  for (std::size_t r = 0; r < n; ++r) {
    const std::int32_t i = rows[r];
    double f0 = 0, f1 = 0, f2 = 0, w = 0, diss = 0;
    int newly = 0;
    for (const FamilyBond& bond : family(v, i)) {
      typename E::Bonds b = scalar_bond(law, v, i, bond);
      if constexpr (requires { b.history; }) {
        b.history.commit = v.commit_history;
        b.history.dissipated = &diss;
      }
      const auto p = law.front(b, squared_length<simd::Scalar>(b));
      unsigned fresh = 0;
      const double w_before = w;
      double coef = law.coefficient(b, p, w, fresh);
      if (fresh && v.may_break && !(v.may_break[i] | v.may_break[bond.j()])) [[unlikely]] {
        // The crack tip may not advance here (tip_advance): the bond stays intact.
        Law held_constants = constants;
        held_constants.make_intact();
        const E held(held_constants);
        const typename E::Bonds h = scalar_bond(held, v, i, bond);
        w = w_before;
        coef = held.coefficient(h, held.front(h, squared_length<simd::Scalar>(h)), w, fresh);
      }
      if (fresh) {
        // Under the crack-tip rule a bond held past its failure test breaks later with more than
        // w at failure: it dissipates what it holds now.
        diss += v.may_break ? stored_energy(constants, v, i, bond) : constants.critical_energy(b.xi2) * b.measure;
        bond.flag() = kBrokenFlag;
        ++newly;
      }
      f0 = simd::Scalar::fmadd(coef, b.d0, f0);
      f1 = simd::Scalar::fmadd(coef, b.d1, f1);
      f2 = simd::Scalar::fmadd(coef, b.d2, f2);
    }
    force[3 * i] = c_row * f0;
    force[3 * i + 1] = c_row * f1;
    force[3 * i + 2] = c_row * f2;
    if constexpr (E::kEnergy) {
      tally.strain_energy += 0.5 * v.volume[i] * w;
      if (v.energy_density) v.energy_density[i] = 0.5 * w;
    }
    if (newly) {
      tally.dissipated += 0.5 * v.volume[i] * diss;
      tally.newly_broken += newly;
      if (v.row_broken) v.row_broken[i] = 1;
    } else if constexpr (requires(typename E::Bonds b) { b.history; }) {
      tally.dissipated += 0.5 * v.volume[i] * diss;  // a law with history dissipates without breaking too
    }
  }
}

/// Strain energy of rows (law E on the Scalar pack, its failure switched off by the caller: every
/// bond not flagged counts); with `density`, each row's 1/2 sum_j w_ij V_j w [J/m^3].
template <class E>
double energy(const E& law, const BondView& v, const std::int32_t* rows, std::size_t n, double* density) {
  double total = 0;
  for (std::size_t r = 0; r < n; ++r) {
    const std::int32_t i = rows[r];
    double w = 0;
    for (const FamilyBond& bond : family(v, i)) {
      const typename E::Bonds b = scalar_bond(law, v, i, bond);
      unsigned fresh = 0;
      law.coefficient(b, law.front(b, squared_length<simd::Scalar>(b)), w, fresh);
    }
    total += 0.5 * v.volume[i] * w;
    if (density) density[i] = 0.5 * w;
  }
  return total;
}

/// Block row of the tangent K = -d(F V)/du of owned row `row` over its intact bonds:
///   A_ij = V_i k_row [k I + 2 k' y y^T],  k the coefficient, k' = dk/d(y^2)
///   K_ii = sum_j A_ij,  K_ij = -A_ij.
/// `cols` gets the local columns (the row first, then one per intact bond), `blocks` the
/// 3 x 3 cols.size() row-major values (MatSetValuesBlocked's layout for one block row).
template <class E>
void row_tangent(const E& law, const BondView& v, std::int32_t row, std::vector<std::int32_t>& cols,
                 std::vector<double>& blocks) {
  cols.clear();
  cols.push_back(row);
  for (const FamilyBond& bond : family(v, row))
    if (!bond.broken()) cols.push_back(bond.j());
  blocks.assign(9 * cols.size(), 0.0);
  // The block row as a 3 x 3n matrix over `blocks` (MatSetValuesBlocked's row-major layout).
  Eigen::Map<Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::RowMajor>> K(blocks.data(), 3,
                                                                          3 * static_cast<Eigen::Index>(cols.size()));
  const double scale = v.volume[row] * law.row_factor();
  Eigen::Index col = 1;
  for (const FamilyBond& bond : family(v, row)) {
    if (bond.broken()) continue;
    const typename E::Bonds b = scalar_bond(law, v, row, bond);
    const auto p = law.front(b, squared_length<simd::Scalar>(b));
    double w = 0;
    unsigned fresh = 0;
    typename E::Bonds intact = b;
    intact.dead = 0;
    const double k = law.coefficient(intact, p, w, fresh), k2 = 2.0 * law.slope(intact, p);
    const Eigen::Vector3d y(b.d0, b.d1, b.d2);
    const Eigen::Matrix3d A = scale * (k * Eigen::Matrix3d::Identity() + (k2 * y) * y.transpose());
    K.block<3, 3>(0, 0) += A;         // K_ii
    K.block<3, 3>(0, 3 * col) = -A;  // K_ij
    ++col;
  }
}

}  // namespace law_loop
}  // namespace peri
