// The contact law of rigid tools (Silling & Bobaru 7.4): a penalty on a node's depth p inside the
// tool, per unit volume of the node of density rho,
//   normal force  f_n = rho k p,   energy  e = f_n p / 2 = rho k p^2 / 2   (f_n = de/dp),
// and Coulomb friction opposite to the sliding velocity t relative to the tool's surface, capped
// for an explicit step of length dt so that one step never reverses the sliding:
//   f_t = min(mu f_n, rho |t| / (2 dt)).
// Pure functions of the constants, written once for any scalar type T with the arithmetic of
// double (double in the contact loop, loads/contact.hpp; a dual number in the tests).
#pragma once
#include <algorithm>

namespace peri {

struct PenaltyContact {
  double stiffness = 0;  ///< k, penalty stiffness per unit mass [1/s^2]
  double friction = 0;   ///< Coulomb coefficient mu

  /// f_n [N/m^3] at depth p [m] for density rho [kg/m^3].
  template <class T>
  T normal(T rho, T p) const noexcept {
    return rho * stiffness * p;
  }
  /// e [J/m^3]: the penalty's energy, whose derivative in p is normal().
  template <class T>
  T energy(T rho, T p) const noexcept {
    return 0.5 * normal(rho, p) * p;
  }
  /// f_t [N/m^3] for the normal force f_n, the sliding speed |t| [m/s] and the step dt [s].
  template <class T>
  T friction_force(T normal_force, T rho, T speed, double dt) const noexcept {
    using std::min;
    return min(T(friction * normal_force), T(0.5 * rho * speed / dt));
  }
};

}  // namespace peri
