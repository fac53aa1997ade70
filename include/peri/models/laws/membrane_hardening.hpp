// The membrane micropotential with power-law hardening (Silling & Bobaru eq. 16): w gains
// c' (lambda^n - n lambda + n - 1) g (eq. 16 with the affine terms that keep the reference state
// stress-free), so f gains c' n (lambda^(n-1) - 1) g. Per bond, over a row factor of 1:
//   coefficient = 2c * membrane coefficient + c' n (lambda^(n-1) - 1) g w V / (|xi| y).
// Evaluated one bond at a time (pow has no vector form here): the bond loop's portable walk.
#pragma once
#include <cmath>

#include "peri/models/laws/membrane.hpp"

namespace peri {

struct MembraneHardeningLaw {
  MembraneLaw base;
  double hard_c = 0;  ///< c' [J/m^6]
  double hard_n = 2;  ///< n > 1

  double delta() const noexcept { return base.horizon; }
  bool breaks() const noexcept { return base.failure.breaks; }
  double critical_energy(double xi2) const noexcept {
    const double xi = std::sqrt(xi2), lc = base.critical_stretch(xi);
    return base.critical_energy(xi2) + hard_c * (std::pow(lc, hard_n) - hard_n * lc + hard_n - 1.0) * base.influence(xi);
  }
  double reference_stiffness(double xi2) const noexcept {
    return base.reference_stiffness(xi2) + hard_c * hard_n * (hard_n - 1.0) * base.influence(std::sqrt(xi2)) / xi2;
  }

  static constexpr bool kVectorized = false;
  template <class P, class Shape, bool Energy>
  struct Lanes {
    static_assert(P::W == 1, "hardening is evaluated one bond at a time");
    static constexpr bool Conical = Shape::conical;
    using Base = MembraneLaw::Lanes<P, Shape, Energy>;
    using Pack = P;
    using V = double;
    static constexpr int W = 1;
    static constexpr bool kEnergy = Energy;
    static constexpr int kSlots = Base::kSlots;
    using Bonds = typename Base::Bonds;
    using Front = typename Base::Front;
    static constexpr bool kSlotValues = true;
    Base base;
    double two_c, hard_c, hard_n, inv_horizon;
    explicit Lanes(const MembraneHardeningLaw& L)
        : base(L.base), two_c(2.0 * L.base.c), hard_c(L.hard_c), hard_n(L.hard_n), inv_horizon(1.0 / L.base.horizon) {}
    double row_factor() const { return 1.0; }
    std::array<double, 4> slot_key() const { return base.slot_key(); }
    template <class Q>
    void slot_values(double xi2, double inv_xi, double measure, double mpx2, double* out) const {
      base.template slot_values<Q>(xi2, inv_xi, measure, mpx2, out);
    }
    Front front(const Bonds& b, V y2) const { return base.front(b, y2); }
    double g(const Bonds& b) const { return Conical ? std::max(0.0, 1.0 - b.xi2 * b.inv_xi * inv_horizon) : 1.0; }
    double coefficient(const Bonds& b, const Front& p, double& w, unsigned& fresh) const {
      double w_base = 0;
      const double k = base.coefficient(b, p, w_base, fresh);
      if (fresh || b.dead) return 0.0;
      const double lam = std::sqrt(p.y2 / b.xi2), xi = b.xi2 * b.inv_xi;
      if constexpr (Energy)
        w += w_base + hard_c * (std::pow(lam, hard_n) - hard_n * lam + hard_n - 1.0) * g(b) * b.measure;
      return two_c * k + hard_c * hard_n * (std::pow(lam, hard_n - 1.0) - 1.0) * g(b) * b.measure / (xi * std::sqrt(p.y2));
    }
    /// d k_h / d(y^2) = (d k_h / dy) / (2y), k_h = a (lambda^(n-1) - 1) / y, a = c' n g w V / |xi|.
    double slope(const Bonds& b, const Front& p) const {
      const double y = std::sqrt(p.y2), xi = b.xi2 * b.inv_xi, lam = y / xi, n = hard_n;
      const double a = hard_c * n * g(b) * b.measure / xi;
      const double dk_dy = a * ((n - 1.0) * std::pow(lam, n - 2.0) / (xi * y) - (std::pow(lam, n - 1.0) - 1.0) / p.y2);
      return two_c * base.slope(b, p) + dk_dy / (2.0 * y);
    }
  };

  template <class F>
  decltype(auto) visit_shape(F&& f) const { return base.visit_shape(f); }
  void make_intact() { base.make_intact(); }
};

}  // namespace peri
