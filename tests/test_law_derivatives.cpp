// The scalar laws of models/laws/ (Marder's lattice functions, the fibers' 6-12 pair, the tools'
// penalty contact) are written once for any scalar type. Instantiated with a dual number
// (value + derivative, forward mode), each law's energy gives its force and each force its
// stiffness exactly, so every derivative the laws state in closed form is checked against the
// function it derives from, to round-off, at many points; and each against a closed form of its
// own where the papers give one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "peri/models/laws/contact.hpp"
#include "peri/models/laws/marder.hpp"
#include "peri/models/laws/pair.hpp"
#include "peri/models/marder.hpp"

namespace {

// A dual number v + d eps (eps^2 = 0): arithmetic carries d/dx of every result.
struct Dual {
  double v = 0, d = 0;
  Dual() = default;
  Dual(double value, double derivative = 0) : v(value), d(derivative) {}  // NOLINT: constants
};
Dual operator+(Dual a, Dual b) { return {a.v + b.v, a.d + b.d}; }
Dual operator-(Dual a, Dual b) { return {a.v - b.v, a.d - b.d}; }
Dual operator-(Dual a) { return {-a.v, -a.d}; }
Dual operator*(Dual a, Dual b) { return {a.v * b.v, a.d * b.v + a.v * b.d}; }
Dual operator/(Dual a, Dual b) { return {a.v / b.v, (a.d * b.v - a.v * b.d) / (b.v * b.v)}; }
Dual operator+(double a, Dual b) { return Dual(a) + b; }
Dual operator-(double a, Dual b) { return Dual(a) - b; }
Dual operator*(double a, Dual b) { return Dual(a) * b; }
Dual operator/(double a, Dual b) { return Dual(a) / b; }
Dual operator+(Dual a, double b) { return a + Dual(b); }
Dual operator-(Dual a, double b) { return a - Dual(b); }
Dual operator*(Dual a, double b) { return a * Dual(b); }
Dual operator/(Dual a, double b) { return a / Dual(b); }
bool operator<(Dual a, double b) { return a.v < b; }
bool operator>=(Dual a, double b) { return a.v >= b; }
bool operator<(Dual a, Dual b) { return a.v < b.v; }
Dual exp(Dual a) {
  const double e = std::exp(a.v);
  return {e, e * a.d};
}
Dual min(Dual a, Dual b) { return a.v <= b.v ? a : b; }

Dual variable(double x) { return {x, 1.0}; }

// |a - b| within rel of the larger magnitude (and of `scale`, for values that pass through zero).
void expect_close(double a, double b, double rel, double scale, const char* what, double at) {
  EXPECT_LE(std::fabs(a - b), rel * std::max({std::fabs(a), std::fabs(b), scale})) << what << " at " << at;
}

// Marder's lattice (the supersonic scene's material at its spacing): Delta = 0.5 mm, u_s = Delta/4,
// u_c = 3 Delta, a = 1000 J/kg, b = 0.4.
const peri::MarderLaw kLattice = peri::marder_law(1000, 0.4, 5e-4, 1.25e-4, 1.5e-3, 1e-6, false);

// With the stiffening pair term beyond u_g = 2 Delta (w = 0.25 Delta).
const peri::MarderLaw kStiffLattice = peri::marder_law(
    1000, 0.4, 5e-4, 1.25e-4, 1.5e-3, 1e-6, false, {.stiffening_onset = 1e-3, .stiffening_width = 1.25e-4});

TEST(LawDerivatives, MarderFunctionsAreTheirDerivatives) {
  for (const peri::MarderLaw& L : {kLattice, kStiffLattice}) {
    const double f_scale = L.A * L.delta * L.delta, df_scale = L.A * L.delta;
    int points = 0;
    for (double u = 0.5 * L.delta; u < 1.3 * L.uc; u += 0.0137 * L.delta, ++points) {
      const Dual f = L.f(variable(u)), h = L.h(variable(u));
      expect_close(f.v, L.f(u), 1e-14, f_scale, "f(dual) value", u);  // the same arithmetic
      expect_close(f.d, L.df(u), 1e-12, df_scale, "df", u);
      expect_close(h.d, L.dh(u), 1e-12, 1.0 / L.us, "dh", u);
      const double X = (u - L.delta) * L.delta;  // u_ij . u_ik over the range a pair of bonds sees
      expect_close(L.g(variable(X)).d, L.dg(X), 1e-12, L.B * L.delta * L.delta, "dg", X);
    }
    EXPECT_GT(points, 100);
    // f is continuous where its cutoff branch meets the Mooney-Rivlin one (u = Delta + u_s), constant
    // beyond u_c, and zero (with its reference constant) for the unstretched bond's share: f(Delta)
    // is the f_constant that makes the reference lattice's energy zero.
    const double join = L.delta + L.us;
    expect_close(L.f(std::nextafter(join, 0.0)), L.f(join), 1e-9, f_scale, "f continuous at Delta + u_s",
                 join);
    EXPECT_EQ(L.f(1.1 * L.uc), L.f(L.uc));
    EXPECT_EQ(L.df(1.1 * L.uc), 0.0);
    expect_close(L.f(L.delta), L.f_constant(), 1e-13, f_scale, "f(Delta)", L.delta);
    // The switch: h(u_c) = 1/2, and -h (1 - h) / u_s at u_c: -1 / (4 u_s).
    EXPECT_DOUBLE_EQ(L.h(L.uc), 0.5);
    expect_close(L.dh(L.uc), -0.25 / L.us, 1e-14, 0, "dh(u_c)", L.uc);
  }
  // The stiffening adds nothing up to u_g and (A/36) (u - u_g)^4 / w^2 beyond.
  const peri::MarderLaw &L = kStiffLattice, &M = kLattice;
  for (double u : {1.2 * L.delta, 1.9 * L.delta, L.stiffening_onset}) EXPECT_EQ(L.f(u), M.f(u)) << u;
  const double u = 2.5 * L.delta, x = u - L.stiffening_onset;
  expect_close(L.f(u) - M.f(u), L.A / 36 * std::pow(x, 4) / std::pow(L.stiffening_width, 2), 1e-12,
               L.A * L.delta * L.delta, "stiffening energy", u);
}

// The fibers' pairs of example 7.5: a = 1 nm, alpha and beta of the scene's adjacent segments.
TEST(LawDerivatives, PairForceAndStiffnessAreTheDerivatives) {
  for (const peri::LennardJonesPair p : {peri::LennardJonesPair{1e-3, 2e-3, 1e-9}, peri::LennardJonesPair{5e-4, -1e-4, 1e-9}}) {
    const double scale = std::fabs(p.alpha) + std::fabs(p.beta);
    for (double y = 0.8e-9; y < 3e-9; y += 0.0173e-9) {
      const Dual w = p.energy(variable(y)), f = p.force(variable(y));
      expect_close(w.v, p.energy(y), 1e-14, scale, "energy(dual) value", y);
      expect_close(w.d, p.force(y), 1e-12, scale / p.length, "force = dw2/dy", y);
      expect_close(f.d, p.stiffness(y), 1e-12, scale / (p.length * p.length), "stiffness = df/dy", y);
    }
  }
  // Attracting pair: no force at the potential's minimum y* = a (2 alpha / beta)^(1/6), where
  // w2 = -beta^2 / (4 alpha), and a positive stiffness (a stable separation).
  const peri::LennardJonesPair p{1e-3, 2e-3, 1e-9};
  const double y_min = p.length * std::pow(2 * p.alpha / p.beta, 1.0 / 6.0);
  EXPECT_LE(std::fabs(p.force(y_min)), 1e-13 * p.beta / p.length);
  EXPECT_NEAR(p.energy(y_min), -p.beta * p.beta / (4 * p.alpha), 1e-14 * p.beta);
  EXPECT_GT(p.stiffness(y_min), 0.0);
}

TEST(LawDerivatives, ContactNormalForceIsTheEnergysDerivative) {
  const peri::PenaltyContact c{4.0e9, 0.3};  // k [1/s^2], mu
  const double rho = 1200, dt = 1e-7;
  for (double p = 1e-7; p < 1e-4; p *= 1.37) {
    const Dual e = c.energy(Dual(rho), variable(p));
    expect_close(e.d, c.normal(rho, p), 1e-14, 0, "normal = de/dp", p);
    expect_close(c.normal(rho, p), rho * 4.0e9 * p, 1e-15, 0, "rho k p", p);
    // Friction: mu f_n while that is below the step's cap rho |t| / (2 dt), the cap beyond.
    const double fn = c.normal(rho, p);
    for (double speed : {1e-3, 1.0, 1e3}) {
      const double ft = c.friction_force(fn, rho, speed, dt), cap = 0.5 * rho * speed / dt;
      EXPECT_EQ(ft, std::min(0.3 * fn, cap)) << p << " " << speed;
      // A step under ft changes the sliding speed by at most half of it: the sliding never reverses.
      EXPECT_LE(ft / rho * dt, 0.5 * speed * (1 + 1e-15));
    }
  }
}

}  // namespace
