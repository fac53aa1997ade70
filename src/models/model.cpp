#include "peri/models/model.hpp"

#include <limits>
#include <sstream>

namespace peri {
namespace {

// Moments R_k = int_0^delta xi^k g(xi) dxi of the influence function.
double moment(int k, double delta, bool conical) {
  const double full = std::pow(delta, k + 1) / (k + 1);
  return conical ? full - std::pow(delta, k + 1) / (k + 2) : full;
}

// mu per unit micromodulus for the law in the body (see model.hpp).
double mu_per_c(ModelKind kind, const BodyGeometry& g, bool conical) {
  const double pi = 3.14159265358979323846;
  if (g.kind == BodyKind::Membrane || g.kind == BodyKind::Shell) {
    if (kind == ModelKind::Membrane) return pi * g.thickness * moment(1, g.horizon, conical);
    return pi * g.thickness * moment(2, g.horizon, conical) / 8.0;
  }
  // Solid PMB: K = 2 pi c R4 / 9 and mu = 3K/5.
  return 0.6 * 2.0 * pi * moment(3, g.horizon, conical) / 9.0;
}

// Fibers (eq. 31, cross-section A, uniaxial): W = A int_0^delta w dxi per unit volume, so
//   membrane law (eq. 33's w1): W = A c R0 (lambda^2 + lambda^-2 - 2) = 4 A c R0 eps^2 + ...,
//                               E = 8 A c R0, R0 = int_0^delta g dxi (g = 1: delta)
//   PMB law:                    W = A c R1 s^2 / 2, E = A c R1, R1 = int_0^delta xi g dxi.
double youngs_per_c_fiber(ModelKind kind, const BodyGeometry& g, bool conical) {
  return kind == ModelKind::Membrane ? 8.0 * g.area * moment(0, g.horizon, conical)
                                     : g.area * moment(1, g.horizon, conical);
}

std::string number(double x) {
  std::ostringstream s;
  s.precision(6);
  s << x;
  return s.str();
}

// Refuses a micromodulus that is not usable, naming what made it so: the material's stiffness
// (its modulus overflows or underflows), the body's geometry (thickness, horizon, cross-section),
// or the two together (their quotient does).
void check_micromodulus(const Material& m, const BodyGeometry& g, const std::string& where, double modulus,
                        double per_c, double c) {
  if (usable(c)) return;
  std::ostringstream msg;
  const std::string geometry = (g.kind == BodyKind::Fiber ? "cross-section " + number(g.area) + " m^2"
                                                          : "thickness " + number(g.thickness) + " m") +
                               ", horizon " + number(g.horizon) + " m";
  if (!usable(modulus)) {
    msg << m.where.str() << ": " << stiffness_input(m) << " gives " << (g.kind == BodyKind::Fiber ? "E" : "mu")
        << " = " << number(modulus) << " Pa, " << (modulus > 1 ? "beyond the largest double" : "below the smallest normal double");
  } else if (!usable(per_c)) {
    msg << where << ": the body's geometry (" << geometry << ") gives a stiffness per unit micromodulus of "
        << number(per_c) << ", " << (per_c > 1 ? "beyond the largest double" : "below the smallest normal double");
  } else {
    msg << m.where.str() << ": " << stiffness_input(m) << " in " << where.substr(where.rfind(": ") == std::string::npos ? 0 : where.rfind(": ") + 2) << " ("
        << geometry << ") gives a micromodulus c = " << number(c) << ", "
        << (c > 1 ? "beyond the largest double" : "below the smallest normal double");
  }
  msg << "; expected a stiffness and geometry whose micromodulus is a finite double of at least 2.2e-308";
  throw InputError(msg.str());
}

}  // namespace

bool usable(double x) { return std::isfinite(x) && x >= std::numeric_limits<double>::min(); }

std::string stiffness_input(const Material& m) {
  const std::string p = "materials." + m.name + ".";
  if (m.marder) return p + "mooney_rivlin_a: " + number(m.marder->a) + " J/kg";
  if (m.wave_speed)
    return p + "wave_speed: " + number(*m.wave_speed) + " m/s (density " + number(m.density) + " kg/m^3)";
  if (m.bulk_modulus) return p + "bulk_modulus: " + number(*m.bulk_modulus) + " Pa";
  if (m.youngs_modulus) return p + "youngs_modulus: " + number(*m.youngs_modulus) + " Pa";
  return p + "micromodulus: " + number(m.micromodulus.value_or(0));
}

BondLaw calibrate(const Material& m, const BodyGeometry& g, const std::string& where) {
  if (m.model == ModelKind::Membrane && g.kind == BodyKind::Solid)
    throw InputError(where + ": material '" + m.name +
                     "' uses the membrane micropotential (eq. 13), which is defined for membrane "
                     "and fiber bodies only; expected model: pmb for a solid body");
  BondLaw law;
  law.kind = m.model;
  law.horizon = g.horizon;
  law.conical = m.influence == Influence::Conical;
  const double k = mu_per_c(m.model, g, law.conical);
  // In-plane (membrane) and 3D (solid, nu = 1/4) relations between mu and the inputs.
  const bool membrane = g.kind == BodyKind::Membrane || g.kind == BodyKind::Shell;
  double mu = 0;
  if (m.micromodulus) {
    law.c = *m.micromodulus;
  } else if (g.kind == BodyKind::Fiber) {
    // One modulus in 1D: the bar's E (a "bulk modulus" of a fiber is read as E too).
    double e = 0;
    if (m.wave_speed) e = m.density * *m.wave_speed * *m.wave_speed;
    if (m.bulk_modulus) e = *m.bulk_modulus;
    if (m.youngs_modulus) e = *m.youngs_modulus;
    law.c = e / youngs_per_c_fiber(m.model, g, law.conical);
    check_micromodulus(m, g, where, e, youngs_per_c_fiber(m.model, g, law.conical), law.c);
  } else {
    if (m.wave_speed) mu = m.density * *m.wave_speed * *m.wave_speed / 3.0;
    if (m.bulk_modulus) mu = membrane ? *m.bulk_modulus / 2.0 : 0.6 * *m.bulk_modulus;
    if (m.youngs_modulus) mu = membrane ? 3.0 * *m.youngs_modulus / 8.0 : 0.4 * *m.youngs_modulus;
    law.c = mu / k;
    check_micromodulus(m, g, where, mu, k, law.c);
  }
  if (m.critical_stretch) {
    law.breaks = true;
    const double to_stretch = m.model == ModelKind::PMB ? 1.0 : 0.0;  // PMB gives a strain s_0
    law.critical0 = *m.critical_stretch + to_stretch;
    law.critical_delta = m.critical_stretch_at_horizon ? *m.critical_stretch_at_horizon + to_stretch
                                                       : law.critical0;
    law.linear_critical = law.critical_delta != law.critical0;
  }
  if (m.hardening) {
    law.hardening = true;
    law.hard_c = m.hardening->coefficient;
    law.hard_n = m.hardening->exponent;
  }
  return law;
}

double rayleigh_ratio(double a) {
  // Solve (2 - x^2)^2 = 4 sqrt(1 - x^2) sqrt(1 - a^2 x^2) for x = c_R / c_s in (0, 1).
  auto f = [a](double x) {
    return std::pow(2.0 - x * x, 2) - 4.0 * std::sqrt(1.0 - x * x) * std::sqrt(1.0 - a * a * x * x);
  };
  double lo = 0.5, hi = 0.999999;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (f(lo) * f(mid) <= 0 ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

ElasticConstants elastic_constants(const BondLaw& law, const BodyGeometry& g, double density) {
  ElasticConstants e;
  if (g.kind == BodyKind::Fiber) {  // a bar: E, its wave speed sqrt(E / rho); no shear
    e.youngs = e.bulk = law.c * youngs_per_c_fiber(law.kind, g, law.conical);
    e.c_longitudinal = std::sqrt(e.youngs / density);
    return e;
  }
  e.mu = law.c * mu_per_c(law.kind, g, law.conical);
  const bool membrane = g.kind == BodyKind::Membrane || g.kind == BodyKind::Shell;
  e.bulk = membrane ? 2.0 * e.mu : e.mu / 0.6;
  e.youngs = membrane ? 8.0 * e.mu / 3.0 : 2.5 * e.mu;
  e.c_longitudinal = std::sqrt(3.0 * e.mu / density);
  e.c_shear = std::sqrt(e.mu / density);
  e.c_rayleigh = e.c_shear * rayleigh_ratio(e.c_shear / e.c_longitudinal);
  return e;
}

}  // namespace peri
