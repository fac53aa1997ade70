// Prototype microelastic brittle (PMB) bonds: scalar force f = c s g(|xi|), bond strain
// s = y/|xi| - 1, micropotential w = c s^2 |xi| g / 2, failure at s >= s_0 (the papers' "critical
// stretch", here lambda_0 = 1 + s_0, linear in |xi| with eq. 29). Used by examples 7.3-7.6 and
// for 3D solids. Per bond, over the row factor c:
//   coefficient = f w V / (c y) = g w V (1/|xi| - 1/y)
// with g w V and g w V / |xi| per slot (no square root of |xi|; 1/y by simd::Root).
#pragma once
#include <algorithm>
#include <cmath>

#include "peri/core/simd.hpp"
#include "peri/models/laws/bond_lanes.hpp"

namespace peri {

struct PmbLaw {
  double c = 0;          ///< micromodulus [N/m^6]
  double horizon = 0;    ///< delta [m]
  bool conical = false;  ///< g = 1 - |xi|/delta instead of 1
  StretchFailure failure;

  double delta() const noexcept { return horizon; }
  bool breaks() const noexcept { return failure.breaks; }
  double influence(double xi) const noexcept { return conical ? std::max(0.0, 1.0 - xi / horizon) : 1.0; }
  double critical_stretch(double xi) const noexcept {
    return failure.linear() ? failure.critical0 + (failure.critical_delta - failure.critical0) * xi / horizon
                            : failure.critical0;
  }
  /// w(lambda_0(|xi|)) per unit measure: what a bond holds when it breaks (eqs. 26-27), in
  /// closed form from s_0 itself.
  double critical_energy(double xi2) const noexcept {
    const double xi = std::sqrt(xi2), s = critical_stretch(xi) - 1.0;
    return 0.5 * c * s * s * xi * influence(xi);
  }
  /// d f / dy at the reference state [N/m^7] (stable step, Silling & Askari 2005): c g / |xi|.
  double reference_stiffness(double xi2) const noexcept {
    const double xi = std::sqrt(xi2);
    return c * influence(xi) / xi;
  }

  static constexpr bool kVectorized = true;
  /// The law on the lanes of pack P, for a shape (StretchShape: conical g, linear lambda_0) and
  /// for calls with or without the strain energy.
  template <class P, class Shape, bool Energy>
  struct Lanes {
    static constexpr bool Conical = Shape::conical, Linear = Shape::linear;
    using Pack = P;
    using V = typename P::V;
    using M = typename P::M;
    static constexpr int W = P::W;
    static constexpr bool kEnergy = Energy;
    enum { kFloor, kBreak, kWeight, kWeightPerXi, kXiLen, kEnergyWeight, kSlots };
    using Bonds = BondLanes<P, Energy ? kSlots : kXiLen>;  // (the energy's slots last)
    /// The per-slot constants are needed in every call (weights, floor, failure test).
    static constexpr bool kSlotValues = true;
    double c_row, crit0_s, crit_slope_s, c_energy_s, inv_horizon_s;
    V zero, one, tiny, crit0, crit0_sq, crit_slope, inv_horizon;
    simd::Root<P> root;  // (its constants: loop invariants)
    explicit Lanes(const PmbLaw& L)
        : c_row(L.c),
          crit0_s(L.failure.critical0),
          crit_slope_s(Linear ? (L.failure.critical_delta - L.failure.critical0) / L.horizon : 0.0),
          c_energy_s(0.5 * L.c),
          inv_horizon_s(1.0 / L.horizon),
          zero(P::zero()),
          one(P::set1(1.0)),
          tiny(P::set1(1e-12)),
          crit0(P::set1(L.failure.critical0)),
          crit0_sq(P::set1(L.failure.critical0 * L.failure.critical0)),
          crit_slope(P::set1(crit_slope_s)),
          inv_horizon(P::set1(1.0 / L.horizon)) {}
    double row_factor() const { return c_row; }
    /// Identifies the constants slot_values depends on (a plan's cache of them, per pattern).
    /// One address per law and shape (the slot constants do not depend on the pack or Energy).
    static const void* slot_tag() { return &Lanes<simd::Scalar, Shape, false>::slot_tag_storage; }
    static inline const char slot_tag_storage = 0;
    std::array<double, 4> slot_key() const { return {crit0_s, crit_slope_s, c_energy_s, inv_horizon_s}; }

    /// Per-slot constants on pack Q (scalar once per pattern, or on gathered lanes; the same
    /// operations): 1e-12 |xi|^2 (coincident nodes), (lambda_0 |xi|)^2 (eqs. 11, 29), g w V and
    /// g w V / |xi|, |xi| and (c/2) g w V / |xi| (energy).
    template <class Q>
    void slot_values(typename Q::V xi2, typename Q::V inv_xi, typename Q::V measure, typename Q::V,
                     typename Q::V* out) const {
      using U = typename Q::V;
      const U q_one = Q::set1(1.0);
      out[kFloor] = Q::mul(Q::set1(1e-12), xi2);
      const U xi_len = Q::mul(xi2, inv_xi);
      if constexpr (Linear) {
        const U lc = Q::fmadd(Q::set1(crit_slope_s), xi_len, Q::set1(crit0_s));
        out[kBreak] = Q::mul(Q::mul(lc, lc), xi2);
      } else {
        out[kBreak] = Q::mul(Q::set1(crit0_s * crit0_s), xi2);
      }
      U g = q_one;
      if constexpr (Conical) g = Q::max(Q::zero(), Q::fnmadd(xi_len, Q::set1(inv_horizon_s), q_one));
      const U gm = Conical ? Q::mul(g, measure) : measure;
      out[kWeight] = gm;
      out[kWeightPerXi] = Q::mul(gm, inv_xi);
      out[kXiLen] = xi_len;
      out[kEnergyWeight] = Q::mul(Q::mul(Q::set1(c_energy_s), gm), inv_xi);
    }

    /// The long-latency start of a bond's evaluation: y^2 floored, and simd::Root's first stage.
    struct Front {
      V y2, y2g, r;
    };
    __attribute__((always_inline)) Front front(const Bonds& b, V y2) const {
      Front p;
      p.y2 = y2;
      p.y2g = P::max(y2, b.slot[kFloor]);
      p.r = root.front(p.y2g);
      return p;
    }
    /// The lanes' coefficients (zero where dead or breaking now); `fresh`: lanes whose bond
    /// reaches the failure test now; with Energy, adds w w V to `w`.
    __attribute__((always_inline)) V coefficient(const Bonds& b, const Front& p, V& w, unsigned& fresh) const {
      const M reached = P::ge(p.y2g, b.slot[kBreak]);
      fresh = P::bits(reached) & ~b.dead & ((1u << W) - 1u);
      const M dead = P::with_lanes(reached, b.dead);
      V y, inv_y;
      root.finish(p.y2g, p.r, y, inv_y);
      const V coef = P::fnmadd_or_zero(dead, b.slot[kWeight], inv_y, b.slot[kWeightPerXi]);  // g wV (1/xi - 1/y)
      if constexpr (Energy) {  // w = (c/2) g (y - xi)^2 / xi
        const V stretch = P::sub(y, b.slot[kXiLen]);
        w = P::add(w, P::zero_where(dead, P::mul(b.slot[kEnergyWeight], P::mul(stretch, stretch))));
      }
      return coef;
    }
    /// d coefficient / d(y^2) of an intact bond: g w V / (2 y^3) (the SNES tangent).
    V slope(const Bonds& b, const Front& p) const {
      V y, inv_y;
      root.finish(p.y2g, p.r, y, inv_y);
      return P::mul(P::mul(P::set1(0.5), b.slot[kWeight]), P::mul(inv_y, P::mul(inv_y, inv_y)));
    }
  };

  /// Calls f(StretchShape<conical, linear>{}) with this law's shape as compile-time constants.
  template <class F>
  decltype(auto) visit_shape(F&& f) const { return visit_stretch_shape(conical, failure.linear(), f); }
  /// The same law whose bonds never fail.
  void make_intact() { failure = StretchFailure{}; }
};

}  // namespace peri
