// Rubbery membrane micropotential (Silling & Bobaru 2005): eq. (13) w = c (lambda^2 + lambda^-2 - 2)
// g(|xi|), lambda = y/|xi|; scalar force eq. (15) f = 2c/|xi| (lambda - lambda^-3) g; failure at
// lambda >= lambda_0 (eqs. 11, 22; linear in |xi| with eq. 29). Per bond, over the row factor 2c:
//   coefficient = f w V / (2c y) = g (w V / |xi|^2) (1 - r^2),   r = |xi|^2 / y^2 = lambda^-2
// (one division, no square root); the failure test is r <= lambda_0^-2, and
//   w w V = c g (w V / |xi|^4) (y^2 - |xi|^2)^2 r.
// Power-law hardening (eq. 16) is its own law (membrane_hardening.hpp).
#pragma once
#include <algorithm>
#include <cmath>
#include <type_traits>

#include "peri/core/simd.hpp"
#include "peri/models/laws/bond_lanes.hpp"

namespace peri {

struct MembraneLaw {
  double c = 0;          ///< micromodulus c of eq. (13) [J/m^6]
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
  /// eq. (13) at lambda = lambda_0(|xi|), per unit measure (eqs. 26-27).
  double critical_energy(double xi2) const noexcept {
    const double xi = std::sqrt(xi2), lc = critical_stretch(xi), l2 = lc * lc;
    return c * (l2 + 1.0 / l2 - 2.0) * influence(xi);
  }
  /// d f / dy at the reference state [N/m^7] (stable step): 8 c g / |xi|^2.
  double reference_stiffness(double xi2) const noexcept { return 8.0 * c * influence(std::sqrt(xi2)) / xi2; }

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
    enum { kBreak, kXiLen, kEnergyWeight, kSlots };
    using Bonds = BondLanes<P, Energy ? kSlots : Linear ? 1 : 0>;  // (a constant lambda_0 reads none)
    /// With a constant lambda_0 the failure test needs no per-slot constant (r <= lambda_0^-2).
    static constexpr bool kSlotValues = Linear || Energy;
    /// 1/|xi| is read by a conical g and a linear lambda_0 only (free_slot: w V / |xi|^2 by one
    /// division where it is not, whether or not the call sums the energy).
    static constexpr bool kReadsInverseLength = Conical || Linear;
    double c_row, crit0_s, crit_slope_s, c_energy_s, inv_horizon_s;
    V zero, one, r_max, inv_crit0_sq, inv_horizon;
    explicit Lanes(const MembraneLaw& L)
        : c_row(2.0 * L.c),
          crit0_s(L.failure.critical0),
          crit_slope_s(Linear ? (L.failure.critical_delta - L.failure.critical0) / L.horizon : 0.0),
          c_energy_s(L.c),
          inv_horizon_s(1.0 / L.horizon),
          zero(P::zero()),
          one(P::set1(1.0)),
          r_max(P::set1(1e12)),
          inv_crit0_sq(P::set1(1.0 / (L.failure.critical0 * L.failure.critical0))),  // 0 if unbreakable
          inv_horizon(P::set1(1.0 / L.horizon)) {}
    double row_factor() const { return c_row; }
    /// One address per law and shape (the slot constants do not depend on the pack or Energy).
    static const void* slot_tag() { return &Lanes<simd::Scalar, Shape, false>::slot_tag_storage; }
    static inline const char slot_tag_storage = 0;
    std::array<double, 4> slot_key() const { return {crit0_s, crit_slope_s, c_energy_s, inv_horizon_s}; }

    /// Per-slot constants: (lambda_0 |xi|)^2 (eq. 29), |xi|, and c g w V / |xi|^4 (energy).
    template <class Q>
    void slot_values(typename Q::V xi2, typename Q::V inv_xi, typename Q::V measure, typename Q::V,
                     typename Q::V* out) const {
      using U = typename Q::V;
      const U xi_len = Q::mul(xi2, inv_xi);
      if constexpr (Linear) {
        const U lc = Q::fmadd(Q::set1(crit_slope_s), xi_len, Q::set1(crit0_s));
        out[kBreak] = Q::mul(Q::mul(lc, lc), xi2);
      } else {
        out[kBreak] = Q::mul(Q::set1(crit0_s * crit0_s), xi2);
      }
      out[kXiLen] = xi_len;
      U gm = measure;
      if constexpr (Conical) gm = Q::mul(Q::max(Q::zero(), Q::fnmadd(xi_len, Q::set1(inv_horizon_s), Q::set1(1.0))), measure);
      out[kEnergyWeight] = Q::mul(Q::mul(Q::set1(c_energy_s), gm), Q::mul(Q::mul(inv_xi, inv_xi), Q::mul(inv_xi, inv_xi)));
    }

    struct Front {
      V y2, y2g, r;
    };
    /// r = |xi|^2 / y^2, capped for coincident nodes.
    __attribute__((always_inline)) Front front(const Bonds& b, V y2) const {
      Front p;
      p.y2 = p.y2g = y2;
      p.r = P::min(P::div(b.xi2, y2), r_max);
      return p;
    }
    __attribute__((always_inline)) V coefficient(const Bonds& b, const Front& p, V& w, unsigned& fresh) const {
      V g = one;
      if constexpr (Conical) g = P::max(zero, P::fnmadd(P::mul(b.xi2, b.inv_xi), inv_horizon, one));
      M reached;
      if constexpr (Linear) reached = P::ge(p.y2g, b.slot[kBreak]);
      else reached = P::le(p.r, inv_crit0_sq);
      fresh = P::bits(reached) & ~b.dead & ((1u << W) - 1u);
      const M dead = P::with_lanes(reached, b.dead);
      V a = b.measure_per_xi2;
      if constexpr (Conical) a = P::mul(g, a);
      const V coef = P::zero_where(dead, P::fnmadd(a, P::mul(p.r, p.r), a));  // g wV/xi^2 (1 - r^2)
      if constexpr (Energy) {  // c g ((y^2 - xi^2) / xi^2)^2 r: no division beyond r's
        const V e = P::sub(p.y2, b.xi2);
        w = P::add(w, P::zero_where(dead, P::mul(b.slot[kEnergyWeight], P::mul(P::mul(e, e), p.r))));
      }
      return coef;
    }
    /// d coefficient / d(y^2) of an intact bond: 2 g (w V / |xi|^2) r^2 / y^2 (the SNES tangent).
    V slope(const Bonds& b, const Front& p) const {
      V a = b.measure_per_xi2;
      if constexpr (Conical) a = P::mul(P::max(zero, P::fnmadd(P::mul(b.xi2, b.inv_xi), inv_horizon, one)), a);
      return P::div(P::mul(P::mul(P::set1(2.0), a), P::mul(p.r, p.r)), p.y2);
    }
  };

  /// Calls f(StretchShape<conical, linear>{}) with this law's shape as compile-time constants.
  template <class F>
  decltype(auto) visit_shape(F&& f) const { return visit_stretch_shape(conical, failure.linear(), f); }
  /// The same law whose bonds never fail.
  void make_intact() { failure = StretchFailure{}; }
};

}  // namespace peri
