// Marder's lattice law (Marder, "Dynamic fracture of nonlinear solids with multi-particle
// modeling", eqs. (27), (31)-(33)): the two-body energy f(u) of a bond of length u, the three-body
// switch h(u) and angular energy g(X) of a pair of bonds of one node, X = u_ij . u_ik, with their
// derivatives. Pure functions of the constants, written once for any scalar type T with the
// arithmetic of double (double in the lattice's loop, models/marder.hpp; a dual number in the
// tests, which checks each derivative against its function exactly).
#pragma once
#include <cmath>

namespace peri {

/// The lattice's options beyond the paper's constants, as a scene gives them (docs/theory/marder.md).
struct MarderOptions {
  double kelvin_viscosity = 0;  ///< nu of the bond dashpots [m^2/s] (0: none)
  double stiffening_onset = 0;  ///< u_g of the pair stiffening [m] (MarderLaw::stiffening)
  double stiffening_width = 0;  ///< w of the pair stiffening [m] (0: none)
  double break_separation = 0;  ///< u_b [m]: bonds break at u_b <= u_c, the switch stays at u_c (0: at u_c)
};

/// Constants of one lattice body (SI units: A in N/m, B in N/m^3).
struct MarderLaw {
  double A = 0;          ///< eq. (27): A = m a / Delta^2
  double B = 0;          ///< eq. (27): B = 9 m a b / (8 Delta^4)
  double delta = 0;      ///< lattice spacing Delta [m]
  double us = 0;         ///< short-distance cutoff u_s [m]
  double uc = 0;         ///< fracture separation u_c [m]
  double mass = 0;       ///< m, mass per node [kg]
  double a = 0, b = 0;   ///< Mooney-Rivlin constants of eq. (6) (a in J/kg, b dimensionless)
  bool reversible = false;  ///< bonds heal when u < u_c again (the paper's pure functional)
  /// Kelvin (Kelvin-Voigt) dashpot of every intact bond [kg/s]: force on i from bond ij
  /// eta (e_ij . (v_j - v_i)) e_ij, e_ij the current bond direction. eta = 8 m nu / (3 Delta^2)
  /// for the material's kinematic viscosity nu (docs/theory/marder.md); 0: no dashpots.
  double dashpot = 0;
  /// Strain stiffening beyond the Mooney-Rivlin branch (not in the paper; docs/theory/marder.md):
  /// for u_g < u the pair energy gains (A/36) (u - u_g)^4 / w^2, so the bond's stiffness grows by
  /// (A/3) ((u - u_g)/w)^2 -- the Mooney-Rivlin pair stiffness A/3 once more at u = u_g + w.
  /// Zero below u_g, with its first three derivatives, so a far field below u_g stays exactly
  /// Mooney-Rivlin. stiffening_width = 0: none.
  double stiffening_onset = 0;  ///< u_g [m]
  double stiffening_width = 0;  ///< w [m]
  /// Length u_b <= u_c at which a bond breaks (not in the paper): 0 breaks at u_c; f and h keep
  /// u_c, so a break below it leaves the far field's law untouched (docs/theory/marder.md).
  double break_separation = 0;

  /// Length at which a bond breaks: u_b if given, else u_c.
  double break_length() const noexcept { return break_separation > 0 ? break_separation : uc; }

  /// Constant of f that makes the reference lattice energy zero: the "+4" of eqs. (23), (24),
  /// (31) is 4 Delta^4 B per node for Delta = 1, shared by the six pair terms of a node.
  double f_constant() const noexcept { return 2.0 / 3.0 * B * delta * delta * delta * delta; }

  /// Two-body energy f(u), eq. (31).
  template <class T>
  T f(T u) const noexcept {
    const double d2 = delta * delta;
    if (u >= uc) u = uc;
    const T s = u * u - d2;
    const T quartic = B / 9.0 * s * s + f_constant();
    if (u < delta + us) return A / 6.0 * s * (u - delta) / us + quartic;
    return A / 6.0 * s + quartic + stiffening(u);
  }
  /// df/du.
  template <class T>
  T df(T u) const noexcept {
    const double d2 = delta * delta;
    if (u >= uc) return T(0.0);
    const T s = u * u - d2;
    const T quartic = 4.0 * B / 9.0 * u * s;
    if (u < delta + us) return A / 6.0 * (2.0 * u * (u - delta) + s) / us + quartic;
    return A / 3.0 * u + quartic + dstiffening(u);
  }
  /// The stiffening pair energy (A/36) (u - u_g)^4 / w^2 for u > u_g, else 0.
  template <class T>
  T stiffening(T u) const noexcept {
    if (!(stiffening_width > 0) || u < stiffening_onset) return T(0.0);
    const T x = u - stiffening_onset;
    return A / 36.0 * (x * x) * (x * x) / (stiffening_width * stiffening_width);
  }
  /// Its derivative (A/9) (u - u_g)^3 / w^2.
  template <class T>
  T dstiffening(T u) const noexcept {
    if (!(stiffening_width > 0) || u < stiffening_onset) return T(0.0);
    const T x = u - stiffening_onset;
    return A / 9.0 * x * x * x / (stiffening_width * stiffening_width);
  }
  /// Three-body switch h(u), eq. (32).
  template <class T>
  T h(T u) const noexcept {
    using std::exp;
    return 1.0 / (1.0 + exp((u - uc) / us));
  }
  /// dh/du = -h (1 - h) / u_s.
  template <class T>
  T dh(T u) const noexcept {
    const T v = h(u);
    return -v * (1.0 - v) / us;
  }
  /// Three-body angular energy g(X), eq. (33).
  template <class T>
  T g(T X) const noexcept {
    const T t = X + 2.0 * delta * delta;
    return -B / 27.0 * t * t;
  }
  /// dg/dX.
  template <class T>
  T dg(T X) const noexcept {
    return -2.0 * B / 27.0 * (X + 2.0 * delta * delta);
  }
};

}  // namespace peri
