// Model: pure bond laws (value types of constants with noexcept functions of one bond's
// geometry) and their calibration from a material's physical inputs. No loops, no MPI, no PETSc.
//
// Conventions. xi2 = |xi|^2 (reference bond length squared), y2 = |xi + eta|^2 (current).
// A law gives `coefficient(xi2, y2)` such that the force density on node i from bond (i, j) is
//   coefficient * weight_ij * V_j * (x_j - x_i)          [N/m^3, i.e. rho * acceleration]
// (eq. 7: the force is parallel to the current bond, f = f_hat * (xi+eta)/y, so
// coefficient = f_hat / y), `energy(xi2, y2)` the micropotential w [J/m^6], and
// `broken_at(xi2, y2)` the irreversible failure test of eqs. (11), (22).
//
// Calibration (derived in README "Calibration"): for a membrane of thickness h and horizon
// delta the homogeneous small-strain energy of both laws is that of an isotropic in-plane
// material with Lame constants lambda = mu:
//   membrane law (eq. 19):  mu = pi h c R,      R  = int_0^delta xi g dxi   (g=1: delta^2/2)
//   PMB law, membrane:      mu = pi h c R3 / 8, R3 = int_0^delta xi^2 g dxi (g=1: delta^3/3)
//   PMB law, 3D solid:      K  = 2 pi c R4 / 9, R4 = int_0^delta xi^3 g dxi (g=1: delta^4/4,
//                           c = 18 K / (pi delta^4)); nu = 1/4, lambda = mu = 3K/5
// Membranes: c_l^2 = 3 mu / rho, c_s^2 = mu / rho, in-plane bulk K = lambda + mu = 2 mu,
// in-plane Young's E = 8 mu / 3. Solids: c_l^2 = 3 mu / rho, E = 5 mu / 2.
// Fibers of cross-section A (eq. 31, uniaxial; E from youngs_modulus, bulk_modulus or rho c_l^2):
//   membrane law (eq. 33):  E = 8 A c R0,   R0 = int_0^delta g dxi      (g=1: delta)
//   PMB law:                E = A c R1,     R1 = int_0^delta xi g dxi   (g=1: delta^2/2)
// and c_l^2 = E / rho (the bar wave speed).
#pragma once
#include <cmath>
#include <string>
#include <vector>

#include "peri/geometry/discretization.hpp"

namespace peri {

/// Constants of one bond law (one material in one body).
struct BondLaw {
  ModelKind kind = ModelKind::Membrane;
  double c = 0;                 ///< micromodulus c (eq. 13) or PMB constant
  double horizon = 0;           ///< delta [m]
  bool conical = false;         ///< g = 1 - |xi|/delta instead of 1
  bool breaks = false;          ///< bonds may fail
  bool linear_critical = false; ///< eq. (29): critical stretch linear in |xi|
  double critical0 = INFINITY;  ///< stretch at failure (membrane: lambda_0; PMB: 1 + s_0) at |xi|=0
  double critical_delta = INFINITY;  ///< same at |xi| = delta (equals critical0 unless linear)
  bool hardening = false;       ///< eq. (16) term
  double hard_c = 0, hard_n = 2;

  /// Influence function g(|xi|).
  double influence(double xi) const noexcept { return conical ? std::max(0.0, 1.0 - xi / horizon) : 1.0; }
  /// Critical stretch lambda_0(|xi|) (eq. 29; constant when not linear).
  double critical_stretch(double xi) const noexcept {
    return linear_critical ? critical0 + (critical_delta - critical0) * xi / horizon : critical0;
  }
  /// Failure test: lambda >= lambda_0(|xi|) (eq. 11 with y_0 = lambda_0 |xi|).
  bool broken_at(double xi2, double y2) const noexcept {
    const double lc = linear_critical ? critical_stretch(std::sqrt(xi2)) : critical0;
    return y2 >= lc * lc * xi2;  // never true when the material does not break (lc = inf)
  }
  /// Force coefficient f_hat / y (see file comment).
  double coefficient(double xi2, double y2) const noexcept {
    if (kind == ModelKind::Membrane) {
      // eq. (15): f_hat = 2c/|xi| (lambda - lambda^-3) g  =>  f_hat/y = 2c g/xi^2 (1 - lambda^-4)
      const double r = xi2 / y2;
      const double g = conical ? influence(std::sqrt(xi2)) : 1.0;
      double k = 2.0 * c * g / xi2 * (1.0 - r * r);
      if (hardening) {
        // d/dlambda of c'(lambda^n - n lambda + n - 1) g = c' n (lambda^(n-1) - 1) g
        const double lam = std::sqrt(y2 / xi2);
        k += hard_c * hard_n * (std::pow(lam, hard_n - 1.0) - 1.0) * g / (std::sqrt(xi2) * std::sqrt(y2));
      }
      return k;
    }
    // PMB: f_hat = c s g, s = y/|xi| - 1  =>  f_hat/y = c g (1/|xi| - 1/y)
    const double xi = std::sqrt(xi2);
    const double g = conical ? influence(xi) : 1.0;
    return c * g * (1.0 / xi - 1.0 / std::sqrt(y2));
  }
  /// Micropotential w (energy per volume squared) of an intact bond.
  double energy(double xi2, double y2) const noexcept {
    const double xi = std::sqrt(xi2);
    const double g = influence(xi);
    if (kind == ModelKind::Membrane) {
      const double l2 = y2 / xi2;  // eq. (13): c (lambda^2 + lambda^-2 - 2) g
      double w = c * (l2 + 1.0 / l2 - 2.0) * g;
      if (hardening) {
        const double lam = std::sqrt(l2);
        w += hard_c * (std::pow(lam, hard_n) - hard_n * lam + hard_n - 1.0) * g;
      }
      return w;
    }
    const double s = std::sqrt(y2) / xi - 1.0;  // PMB: w = c s^2 |xi| g / 2
    return 0.5 * c * s * s * xi * g;
  }
  /// The micropotential at the critical stretch, w(lambda_0(|xi|)): the energy a bond holds when
  /// it breaks (eqs. 26-27), energy(xi2, (lambda_0 |xi|)^2) in closed form (one square root).
  double critical_energy(double xi2) const noexcept {
    const double xi = std::sqrt(xi2);
    const double lc = critical_stretch(xi);
    const double g = influence(xi);
    if (kind == ModelKind::Membrane) {
      const double l2 = lc * lc;  // eq. (13) at lambda = lambda_0
      double w = c * (l2 + 1.0 / l2 - 2.0) * g;
      if (hardening) w += hard_c * (std::pow(lc, hard_n) - hard_n * lc + hard_n - 1.0) * g;
      return w;
    }
    const double s = lc - 1.0;  // PMB: stretch s_0
    return 0.5 * c * s * s * xi * g;
  }
  /// Bond stiffness d f_hat / dy at the reference state [N/m^7], for the stable time step
  /// (Silling & Askari 2005): membrane 8 c g / xi^2, PMB c g / xi.
  double reference_stiffness(double xi2) const noexcept {
    const double xi = std::sqrt(xi2);
    const double g = influence(xi);
    double k = kind == ModelKind::Membrane ? 8.0 * c * g / xi2 : c * g / xi;
    if (hardening) k += hard_c * hard_n * (hard_n - 1.0) * g / xi2;
    return k;
  }
};

/// Small-strain constants of a calibrated law in a body (isotropic, lambda = mu).
struct ElasticConstants {
  double mu = 0;           ///< shear modulus [Pa]
  double bulk = 0;         ///< K: in-plane lambda+mu (membranes), 3D bulk (solids) [Pa]
  double youngs = 0;       ///< E [Pa]
  double c_longitudinal = 0, c_shear = 0, c_rayleigh = 0;  ///< wave speeds [m/s]
};

/// Build the law of a material in a body, calibrating c from the material's stiffness input.
/// Throws InputError for combinations the code does not support (e.g. membrane law in a solid),
/// and when c is not a finite double of at least 2.2e-308 (naming what made it so).
BondLaw calibrate(const Material& m, const BodyGeometry& g, const std::string& where);

/// A derived constant every later product (forces, energies, the stable step) can use without
/// overflow to inf or underflow to 0: finite, and at least the smallest normal double.
bool usable(double x);

/// The material's stiffness input for messages: "materials.<name>.<key>: <value> <unit>" (a wave
/// speed with its density, which gives a modulus only with it).
std::string stiffness_input(const Material& m);

/// Small-strain constants implied by a calibrated law (inverse of calibrate).
ElasticConstants elastic_constants(const BondLaw& law, const BodyGeometry& g, double density);

/// Rayleigh wave speed for given c_s / c_l (root of the Rayleigh equation).
double rayleigh_ratio(double cs_over_cl);

}  // namespace peri
