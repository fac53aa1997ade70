// The long-range pair law of fibers (Silling & Bobaru eqs. 32-36): a 6-12 potential on the current
// distance y of two nodes, per unit volume squared,
//   w2(y) = alpha (a/y)^12 - beta (a/y)^6                                  (eq. 33)
//   f(y)  = dw2/dy = -12 alpha/a (a/y)^13 + 6 beta/a (a/y)^7               (eq. 35, second term)
//   k(y)  = df/dy  = (156 alpha (a/y)^12 - 42 beta (a/y)^6) / y^2
// (f > 0: the pair attracts). Pure functions of the constants, written once for any scalar type T
// with the arithmetic of double (double in the pair loop, models/long_range.hpp; a dual number in
// the tests, which checks f and k against the derivatives of w2 and f exactly).
#pragma once

namespace peri {

struct LennardJonesPair {
  double alpha = 0;   ///< repulsive coefficient of (a/y)^12 [J/m^6]
  double beta = 0;    ///< attractive coefficient of (a/y)^6 [J/m^6] (< 0: a repulsive tail)
  double length = 0;  ///< a [m]

  /// w2(y) [J/m^6], eq. (33).
  template <class T>
  T energy(T y) const noexcept {
    const T r2 = (length / y) * (length / y), r6 = r2 * r2 * r2;
    return alpha * r6 * r6 - beta * r6;
  }
  /// dw2/dy [N/m^6], eq. (35): the scalar force, positive when the pair attracts.
  template <class T>
  T force(T y) const noexcept {
    const T r = length / y, r2 = r * r, r6 = r2 * r2 * r2;
    return (-12.0 * alpha * r6 * r6 + 6.0 * beta * r6) * r / length;
  }
  /// d force / dy [N/m^7] (a tangent's radial stiffness).
  template <class T>
  T stiffness(T y) const noexcept {
    const T r2 = (length / y) * (length / y), r6 = r2 * r2 * r2;
    return (156.0 * alpha * r6 * r6 - 42.0 * beta * r6) / (y * y);
  }
};

}  // namespace peri
