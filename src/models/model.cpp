#include "peri/models/model.hpp"

#include <cmath>
#include <limits>
#include <sstream>

#include "peri/core/error.hpp"

namespace peri {
namespace {

std::string number(double x) {
  std::ostringstream s;
  s.precision(6);
  s << x;
  return s.str();
}

}  // namespace

bool usable(double x) { return std::isfinite(x) && x >= std::numeric_limits<double>::min(); }

std::string stiffness_input(const Material& m) {
  const std::string p = "materials." + m.name + ".";
  if (m.marder) {  // the lattice's stiffness and so its step depend on all of these (eqs. 27, 31-32)
    const MarderParams& q = *m.marder;
    std::string s = p + "mooney_rivlin_a: " + number(q.a) + " J/kg (with mooney_rivlin_b " + number(q.b) + ", cutoff " +
                    number(q.cutoff) + " m, fracture_separation " + number(q.fracture_separation) + " m";
    if (q.options.stiffening_width > 0)
      s += ", stiffening_onset " + number(q.options.stiffening_onset) + " m, stiffening_width " +
           number(q.options.stiffening_width) + " m";
    return s + ")";
  }
  if (m.wave_speed)
    return p + "wave_speed: " + number(*m.wave_speed) + " m/s (density " + number(m.density) + " kg/m^3)";
  if (m.bulk_modulus) return p + "bulk_modulus: " + number(*m.bulk_modulus) + " Pa";
  if (m.youngs_modulus) return p + "youngs_modulus: " + number(*m.youngs_modulus) + " Pa";
  return p + "micromodulus: " + number(m.micromodulus.value_or(0));
}

void check_micromodulus(const Material& m, const BodyGeometry& g, const std::string& where, double modulus,
                        double per_c, double c) {
  if (usable(c)) return;
  std::ostringstream msg;
  const std::string geometry = (g.traits.dimension == 1 ? "cross-section " + number(g.area) + " m^2"
                                                          : "thickness " + number(g.thickness) + " m") +
                               ", horizon " + number(g.horizon) + " m";
  if (!usable(modulus)) {
    msg << m.where.str() << ": " << stiffness_input(m) << " gives " << (g.traits.dimension == 1 ? "E" : "mu")
        << " = " << number(modulus) << " Pa, " << (modulus > 1 ? "beyond the largest double" : "below the smallest normal double");
  } else if (!usable(per_c)) {
    msg << where << ": the body's geometry (" << geometry << ") gives a stiffness per unit micromodulus of "
        << number(per_c) << ", " << (per_c > 1 ? "beyond the largest double" : "below the smallest normal double");
  } else {
    msg << m.where.str() << ": " << stiffness_input(m) << " in "
        << where.substr(where.rfind(": ") == std::string::npos ? 0 : where.rfind(": ") + 2) << " (" << geometry
        << ") gives a micromodulus c = " << number(c) << ", "
        << (c > 1 ? "beyond the largest double" : "below the smallest normal double");
  }
  msg << "; expected a stiffness and geometry whose micromodulus is a finite double of at least 2.2e-308";
  throw InputError(msg.str());
}

double influence_moment(int k, double delta, bool conical) {
  const double full = std::pow(delta, k + 1) / (k + 1);
  return conical ? full - std::pow(delta, k + 1) / (k + 2) : full;
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

ElasticConstants isotropic_constants(double mu_or_e, const BodyGeometry& g, double density) {
  ElasticConstants e;
  if (g.traits.dimension == 1) {  // a bar: E, its wave speed sqrt(E / rho); no shear
    e.youngs = e.bulk = mu_or_e;
    e.c_longitudinal = std::sqrt(e.youngs / density);
    return e;
  }
  e.mu = mu_or_e;
  const bool membrane = g.traits.dimension == 2;
  e.bulk = membrane ? 2.0 * e.mu : e.mu / 0.6;
  e.youngs = membrane ? 8.0 * e.mu / 3.0 : 2.5 * e.mu;
  e.c_longitudinal = std::sqrt(3.0 * e.mu / density);
  e.c_shear = std::sqrt(e.mu / density);
  e.c_rayleigh = e.c_shear * rayleigh_ratio(e.c_shear / e.c_longitudinal);
  return e;
}

BondLaw calibrate(const Material& m, const BodyGeometry& g, const std::string& where) {
  const LawEntry* entry = find_law(m.model);
  if (!entry || !entry->calibrate)
    throw InputError(where + ": material '" + m.name + "': model '" + m.model + "' has no bond law");
  BondLaw law;
  entry->calibrate(m, g, where, law);
  return law;
}

ElasticConstants elastic_constants(const BondLaw& law, const BodyGeometry& g, double density) {
  return law.entry().elastic(law.constants(), g, density);
}

}  // namespace peri
