// Calibration: a material's physical inputs (scene) -> the constants of its bond law in a body, and
// back (small-strain moduli and wave speeds). The derivations are in docs/theory; in short, for a
// membrane of thickness h and horizon delta the homogeneous small-strain energy of both laws is
// that of an isotropic in-plane material with Lame constants lambda = mu:
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
#include <string>

#include "peri/geometry/discretization.hpp"
#include "peri/models/law.hpp"

namespace peri {

/// The law of a material in a body, its constant calibrated from the material's stiffness input
/// (through the registry entry of the material's model). Throws InputError for combinations the
/// law does not support (e.g. the membrane law in a solid), and when c is not a finite double of
/// at least 2.2e-308 (naming what made it so).
BondLaw calibrate(const Material& m, const BodyGeometry& g, const std::string& where);

/// A derived constant every later product (forces, energies, the stable step) can use without
/// overflow to inf or underflow to 0: finite, and at least the smallest normal double.
bool usable(double x);

/// The material's stiffness input for messages: "materials.<name>.<key>: <value> <unit>" (a wave
/// speed with its density, which gives a modulus only with it).
std::string stiffness_input(const Material& m);

/// Refuses (InputError) a micromodulus c = modulus / per_c that is not usable, naming what made it
/// so: the material's stiffness (the modulus over- or underflows), the body's geometry (per_c:
/// stiffness per unit micromodulus, from thickness, horizon, cross-section), or the two together.
void check_micromodulus(const Material& m, const BodyGeometry& g, const std::string& where, double modulus,
                        double per_c, double c);

/// Small-strain constants implied by a calibrated law in a body (inverse of calibrate).
ElasticConstants elastic_constants(const BondLaw& law, const BodyGeometry& g, double density);

/// Rayleigh wave speed for given c_s / c_l (root of the Rayleigh equation).
double rayleigh_ratio(double cs_over_cl);

/// Moments R_k = int_0^delta xi^k g(xi) dxi of the influence function (g = 1 or conical).
double influence_moment(int k, double delta, bool conical);

/// Elastic constants of an isotropic body from its shear modulus (membranes: in-plane, lambda =
/// mu; solids: nu = 1/4), or of a bar (fibers) from its Young's modulus `mu_or_e`.
ElasticConstants isotropic_constants(double mu_or_e, const BodyGeometry& g, double density);

}  // namespace peri
