// What a bond law sees of W bonds at once (one per lane of a pack, core/simd.hpp): the current
// bond vectors y = x_j - x_i, the reference slot of the family pattern (|xi|^2, 1/|xi|, the
// quadrature measure w_ij V_j and w_ij V_j / |xi|^2), the law's own per-slot constants (computed
// once per pattern by the law's slot_values), and which lanes are dead (bond broken already, or
// the lane idle). A law adds nothing for a dead lane.
//
// Conventions of every bond law (models/laws/*.hpp). The force density on node i from bond
// (i, j) is  row_factor * coefficient * (x_j - x_i)  [N/m^3], i.e. coefficient = f_hat w V_j / y
// over the law's row factor (eq. 7: the force is parallel to the current bond); the strain energy
// density of row i is 1/2 sum_j w_ij V_j w(y) (eq. 5), a law giving w w_ij V_j per bond. The
// bond loop sums a row's coefficients times y in CSR order (fused multiply-adds) and multiplies
// the sums by the row factor at the end.
#pragma once
#include <array>
#include <cmath>

namespace peri {

/// Slots: how many of the law's per-slot constants this evaluation reads (the first ones of the
/// law's list: a law lists those of energy calls last, and a call without energy carries none of
/// them, nor anything its shape does not read: the loop copies a bond's lanes from slot to slot).
/// One flat struct (no base, no member initializers), which the compiler keeps in registers.
template <class P, int Slots>
struct BondLanes {
  using Pack = P;
  using V = typename P::V;
  static constexpr int kSlots = Slots;
  V d0, d1, d2;                             ///< y = x_j - x_i
  V xi2, inv_xi, measure, measure_per_xi2;  ///< the pattern's slot
  V slot[Slots];                            ///< the law's per-slot constants
  unsigned dead;                            ///< bit l: lane l adds nothing
};
template <class P>
struct BondLanes<P, 0> {
  using Pack = P;
  using V = typename P::V;
  static constexpr int kSlots = 0;
  V d0, d1, d2;
  V xi2, inv_xi, measure, measure_per_xi2;
  unsigned dead;
};

/// What a law with per-bond history (L::kHistory values per ordered bond, models/law.hpp) sees of
/// a bond beside its lanes, on the Scalar pack (such laws run in the portable walk): the bond's
/// history values (nullptr: none kept, read as zeros), whether this evaluation may change them
/// (the force pass of an explicit step or of a quasi-static break pass; never an energy, tangent
/// or residual evaluation), and where it books the energy it dissipates (per unit measure times
/// the bond's measure w_ij V_j, summed over the row like the critical energies of breaking bonds;
/// nullptr: not booked).
struct BondHistory {
  double* values = nullptr;
  bool commit = false;
  double* dissipated = nullptr;
};

/// The lanes of a law with per-bond history: BondLanes and the bond's BondHistory.
template <class P, int Slots>
struct HistoryBondLanes : BondLanes<P, Slots> {
  BondHistory history;
};

/// Per-bond history values of law L (its kHistory; 0 for laws without).
template <class L>
constexpr int law_history() {
  if constexpr (requires { L::kHistory; })
    return L::kHistory;
  else
    return 0;
}

/// Sets b's slot constants (those b carries) from its reference slot, with law E's slot_values on
/// pack Q (Scalar once per bond, or the lanes of a gathered group).
template <class Q, class E, class B>
inline void fill_slots(const E& law, B& b) {
  if constexpr (B::kSlots > 0) {
    typename Q::V all[E::kSlots];
    law.template slot_values<Q>(b.xi2, b.inv_xi, b.measure, b.measure_per_xi2, all);
    for (int s = 0; s < B::kSlots; ++s) b.slot[s] = all[s];
  }
}

/// Linear critical stretch of eq. (29) and the influence function g(|xi|) of eq. (13), shared by
/// the stretch-based laws: a bond fails when y >= lambda_0(|xi|) |xi| (eqs. 11, 22), lambda_0
/// linear from critical0 at |xi| = 0 to critical_delta at |xi| = delta (constant if equal).
struct StretchFailure {
  bool breaks = false;
  double critical0 = INFINITY;       ///< lambda_0 at |xi| = 0 (PMB: 1 + s_0)
  double critical_delta = INFINITY;  ///< lambda_0 at |xi| = delta
  bool linear() const { return critical_delta != critical0; }
};

/// The compile-time shape of a stretch-based law's evaluation.
template <bool Conical, bool Linear>
struct StretchShape {
  static constexpr bool conical = Conical, linear = Linear;
};
template <class F>
decltype(auto) visit_stretch_shape(bool conical, bool linear, F&& f) {
  if (conical) return linear ? f(StretchShape<true, true>{}) : f(StretchShape<true, false>{});
  return linear ? f(StretchShape<false, true>{}) : f(StretchShape<false, false>{});
}

}  // namespace peri
