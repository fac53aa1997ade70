#include "peri/models/marder.hpp"

#include <algorithm>
#include <sstream>

namespace peri {
namespace {

constexpr std::uint8_t kBrokenBit = 1;  // the same bit the peridynamic loop and node_damage use

std::string num(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

}  // namespace

std::string marder_parameter_problem(double a, double b, double delta, double us, double uc,
                                    const MarderOptions& options) {
  const double onset = options.stiffening_onset, width = options.stiffening_width, ub = options.break_separation;
  if (!(a > 0))
    return "the Mooney-Rivlin constant a must be > 0 (a <= 0 gives no tension and no wave speed), got a = " +
           num(a);
  if (!(delta > 0)) return "the lattice spacing must be > 0, got " + num(delta);
  if (!(us > 0)) return "the cutoff u_s must be > 0, got " + num(us);
  if (!(uc > delta + us))
    return "the fracture separation u_c = " + num(uc) + " m must exceed Delta + u_s = " + num(delta + us) +
           " m: bonds would break before the lattice reaches the Mooney-Rivlin range (eq. 31)";
  if (!(b < 2))
    return "b = " + num(b) +
           " >= 2 makes the stretched sheet lose its shear stiffness (c_s^2 = a (1 - b/2) <= 0); expected b < 2";
  if (!(b < delta / us) || !(b > -2 * delta / us))
    return "b = " + num(b) + " makes the unstretched lattice unstable: its cutoff branch (eq. 31) is stable to "
           "homogeneous shear and dilatation only for -2 Delta/u_s < b < Delta/u_s, here (" +
           num(-2 * delta / us) + ", " + num(delta / us) + "); expected a larger Delta/u_s or a smaller |b|";
  if (!(width >= 0)) return "the stiffening width w must be >= 0, got " + num(width);
  if (width > 0 && !(onset >= delta + us && onset < uc))
    return "the stiffening onset u_g = " + num(onset) + " m must lie on the Mooney-Rivlin branch, Delta + u_s = " +
           num(delta + us) + " m <= u_g < u_c = " + num(uc) + " m";
  if (!(ub >= 0)) return "the break separation u_b must be > 0, got " + num(ub);
  if (ub > 0 && !(ub > delta + us && ub <= uc))
    return "the break separation u_b = " + num(ub) + " m must lie in (Delta + u_s, u_c] = (" + num(delta + us) +
           ", " + num(uc) + "] m: a bond breaks on the Mooney-Rivlin branch, at u_c at the latest";
  return {};
}

double marder_dashpot(double kelvin_viscosity, double delta, double mass) noexcept {
  // Homogeneous strain rate D of the reference lattice: v_j - v_i = D d_j (spin adds nothing
  // along the bond), so bond j pulls with eta Delta (e.D e) e. Stress (force per length) of a
  // node's cell, area (sqrt(3)/2) Delta^2: sum_j d_j (x) f_j / (2 cell) = eta Delta^2 /(2 cell)
  // sum_j (e.D e) e (x) e, and over the six directions sum e_a e_b e_c e_d = (3/4)(d_ab d_cd +
  // d_ac d_bd + d_ad d_bc): sigma = (sqrt(3)/4) eta (2 D + tr D I). Per unit mass
  // (m / cell per area): nu = (sqrt(3)/4) eta cell / m = (3/8) eta Delta^2 / m.
  return 8.0 * mass * kelvin_viscosity / (3.0 * delta * delta);
}

MarderLaw marder_law(double a, double b, double delta, double us, double uc, double mass, bool reversible,
                     const MarderOptions& options) {
  MarderLaw law;
  law.a = a;
  law.b = b;
  law.delta = delta;
  law.us = us;
  law.uc = uc;
  law.mass = mass;
  law.reversible = reversible;
  law.dashpot = marder_dashpot(options.kelvin_viscosity, delta, mass);
  law.stiffening_onset = options.stiffening_onset;
  law.stiffening_width = options.stiffening_width;
  law.break_separation = options.break_separation;
  const double d2 = delta * delta;
  law.A = mass * a / d2;                    // eq. (27), rho = mass per node (eq. 25)
  law.B = 9.0 * mass * a * b / (8.0 * d2 * d2);
  return law;
}

double marder_node(const MarderLaw& law, int n, const double* d, const std::uint8_t* active,
                   double* grad) noexcept {
  double r[kMarderMaxNeighbours], hv[kMarderMaxNeighbours], hr[kMarderMaxNeighbours];
  double energy = 0;
  const double rmin = 1e-12 * law.delta;  // coincident nodes: no direction, no force
  // In passes over the bonds (lengths, the switches, then the terms), so that the bonds' chains
  // of root, exponential and divisions overlap; each value is computed as law.h and law.dh do.
  for (int j = 0; j < n; ++j) {
    const double* dj = d + 3 * j;
    r[j] = std::max(std::sqrt(dj[0] * dj[0] + dj[1] * dj[1] + dj[2] * dj[2]), rmin);
  }
  for (int j = 0; j < n; ++j) hv[j] = active[j] ? law.h(r[j]) : 0.0;  // eq. (32)
  for (int j = 0; j < n; ++j) {
    const double* dj = d + 3 * j;
    double c = 0;
    hr[j] = 0;
    if (active[j]) {
      energy += law.f(r[j]);  // eq. (28)
      c = law.df(r[j]) / r[j];
      hr[j] = -hv[j] * (1.0 - hv[j]) / law.us / r[j];  // law.dh(r) / r
    }
    if (grad)
      for (int k = 0; k < 3; ++k) grad[3 * j + k] = c * dj[k];
  }
  // eq. (29): sum over ordered pairs j != k = twice the sum over j < k.
  for (int j = 0; j < n; ++j) {
    if (hv[j] == 0) continue;
    const double* dj = d + 3 * j;
    for (int k = j + 1; k < n; ++k) {
      if (hv[k] == 0) continue;
      const double* dk = d + 3 * k;
      const double X = dj[0] * dk[0] + dj[1] * dk[1] + dj[2] * dk[2];
      const double gv = law.g(X), hh = hv[j] * hv[k];
      energy += 2.0 * hh * gv;
      if (!grad) continue;
      const double cross = 2.0 * hh * law.dg(X);
      const double cj = 2.0 * hr[j] * hv[k] * gv, ck = 2.0 * hv[j] * hr[k] * gv;
      for (int c = 0; c < 3; ++c) {
        grad[3 * j + c] += cj * dj[c] + cross * dk[c];
        grad[3 * k + c] += ck * dk[c] + cross * dj[c];
      }
    }
  }
  return energy;
}

std::vector<std::uint8_t> marder_directions(const BondView& v, std::int64_t rows) {
  const double sector = 3.14159265358979323846 / 3.0;
  std::vector<std::uint8_t> dir(static_cast<std::size_t>(v.offsets[rows]));
  for (std::int64_t i = 0; i < rows; ++i)
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
      const std::int32_t j = v.neighbor[b];
      const double a = std::atan2(v.X[3 * j + 1] - v.X[3 * i + 1], v.X[3 * j] - v.X[3 * i]);
      dir[b] = static_cast<std::uint8_t>(((std::lround(a / sector) % 6) + 6) % 6);
    }
  return dir;
}

void marder_sum_slots(const double* slots, const std::int32_t* nodes, std::size_t n, double* force) {
  for (std::size_t r = 0; r < n; ++r) {
    const std::int32_t i = nodes[r];
    const double* s = slots + 3 * kMarderSlots * static_cast<std::size_t>(i);
    for (int c = 0; c < 3; ++c) {
      double f = s[c];
      for (int k = 1; k < kMarderSlots; ++k) f += s[3 * k + c];
      force[3 * i + c] = f;
    }
  }
}

void marder_forces(const MarderLaw& law, const BondView& v, const std::int32_t* rows, std::size_t nrows,
                   const std::uint8_t* direction, double* slots, bool with_energy, BondTally& tally,
                   const double* velocity, double* viscous) {
  const bool dashpots = velocity && viscous && law.dashpot > 0;
  double d[3 * kMarderMaxNeighbours], grad[3 * kMarderMaxNeighbours];
  std::uint8_t active[kMarderMaxNeighbours], before[kMarderMaxNeighbours];
  const double ub2 = law.break_length() * law.break_length();
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    const std::int64_t b0 = v.offsets[i];
    const int n = static_cast<int>(std::min<std::int64_t>(v.offsets[i + 1] - b0, kMarderMaxNeighbours));
    const double xi[3] = {v.X[3 * i] + v.u[3 * i], v.X[3 * i + 1] + v.u[3 * i + 1], v.X[3 * i + 2] + v.u[3 * i + 2]};
    int newly = 0;
    for (int k = 0; k < n; ++k) {
      const std::int32_t j = v.neighbor[b0 + k];
      double r2 = 0;
      for (int c = 0; c < 3; ++c) {
        // Both rows of a bond compute the same |d| bit for bit (d_ji = -d_ij exactly), so their
        // break decisions agree on any number of ranks.
        const double xj = v.X[3 * j + c] + v.u[3 * j + c];
        d[3 * k + c] = xj - xi[c];
        r2 += d[3 * k + c] * d[3 * k + c];
      }
      std::uint8_t& flag = v.broken[b0 + k];
      const bool beyond = r2 >= ub2 && !(flag & kMarderUnbreakable);
      if (law.reversible) {
        before[k] = active[k] = !(flag & kMarderCut);
        const std::uint8_t keep = flag & kMarderUnbreakable;
        const std::uint8_t now =
            (flag & kMarderCut) ? flag : static_cast<std::uint8_t>(keep | (beyond ? kBrokenBit : 0));
        newly += (now & kBrokenBit) && !(flag & kBrokenBit);
        flag = now;
      } else {
        before[k] = !(flag & kBrokenBit);
        if (beyond && before[k]) {
          flag |= kBrokenBit;
          ++newly;
        }
        active[k] = !(flag & kBrokenBit);
      }
    }
    double energy_before = 0;
    if (newly && !law.reversible) energy_before = marder_node(law, n, d, before, nullptr);
    const double energy = marder_node(law, n, d, active, grad);
    if (newly) {
      if (!law.reversible) tally.dissipated += energy_before - energy;
      tally.newly_broken += newly;
      if (v.row_broken) v.row_broken[i] = 1;
    }
    if (with_energy) tally.strain_energy += energy;
    double fi[3] = {0, 0, 0};
    for (int k = 0; k < n; ++k) {
      const std::int32_t j = v.neighbor[b0 + k];
      // This row is the neighbour of j in the direction opposite to j's from i.
      const int slot = 1 + (direction[b0 + k] + 3) % 6;
      double* sj = slots + 3 * (kMarderSlots * static_cast<std::size_t>(j) + slot);
      for (int c = 0; c < 3; ++c) {
        fi[c] += grad[3 * k + c];
        sj[c] = -grad[3 * k + c];
      }
    }
    double* si = slots + 3 * kMarderSlots * static_cast<std::size_t>(i);
    for (int c = 0; c < 3; ++c) si[c] = fi[c];
    if (!dashpots) continue;
    // Kelvin dashpots of the intact bonds, from this row's end: d_ji = -d_ij and
    // v_i - v_j = -(v_j - v_i) exactly, so row j's force is bit for bit the negative.
    double fv[3] = {0, 0, 0}, power = 0;
    const double* vi = velocity + 3 * static_cast<std::size_t>(i);
    for (int k = 0; k < n; ++k) {
      if (v.broken[b0 + k] & kBrokenBit) continue;
      const double* vj = velocity + 3 * static_cast<std::size_t>(v.neighbor[b0 + k]);
      const double* dk = d + 3 * k;
      const double r = std::sqrt(dk[0] * dk[0] + dk[1] * dk[1] + dk[2] * dk[2]);
      if (!(r > 1e-12 * law.delta)) continue;
      const double rate = (dk[0] * (vj[0] - vi[0]) + dk[1] * (vj[1] - vi[1]) + dk[2] * (vj[2] - vi[2])) / r;
      const double s = law.dashpot * rate / r;
      for (int c = 0; c < 3; ++c) fv[c] += s * dk[c];
      power += law.dashpot * rate * rate;
    }
    double* out = viscous + 3 * static_cast<std::size_t>(i);
    for (int c = 0; c < 3; ++c) out[c] = fv[c];
    tally.viscous_power += 0.5 * power;
  }
}

double marder_energy(const MarderLaw& law, const BondView& v, const std::int32_t* rows, std::size_t nrows) {
  double d[3 * kMarderMaxNeighbours];
  std::uint8_t active[kMarderMaxNeighbours];
  double total = 0;
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    const std::int64_t b0 = v.offsets[i];
    const int n = static_cast<int>(std::min<std::int64_t>(v.offsets[i + 1] - b0, kMarderMaxNeighbours));
    for (int k = 0; k < n; ++k) {
      const std::int32_t j = v.neighbor[b0 + k];
      for (int c = 0; c < 3; ++c)
        d[3 * k + c] = (v.X[3 * j + c] + v.u[3 * j + c]) - (v.X[3 * i + c] + v.u[3 * i + c]);
      const std::uint8_t flag = v.broken[b0 + k];
      active[k] = law.reversible ? !(flag & kMarderCut) : !(flag & kBrokenBit);
    }
    total += marder_node(law, n, d, active, nullptr);
  }
  return total;
}

double marder_stable_time_step(const MarderLaw& law) {
  const double D = law.delta, us = law.us, uc = law.uc, A = law.A, B = std::fabs(law.B);
  const double u1 = D + us;
  const double cutoff = A / 6.0 * (6.0 * u1 - 2.0 * D) / us + 4.0 * B / 9.0 * (3.0 * u1 * u1 - D * D);
  // The stiffening term adds (A/3) ((u - u_g)/w)^2, largest at u_c.
  const double w = law.stiffening_width, x = w > 0 ? std::max(uc - law.stiffening_onset, 0.0) / w : 0.0;
  const double quartic = A / 3.0 * (1.0 + x * x) + 4.0 * B / 9.0 * (3.0 * uc * uc - D * D);
  const double pair = 2.0 * std::max(cutoff, quartic);
  // Three-body terms a bond takes part in (10 ordered pairs of each of its two rows), with
  // X = d_j . d_k <= u_c^2: |g''| u_c^2 and |g'| from the angular law; the switch h adds
  // |g| |h''| (|h''| <= 0.1/u_s^2) and 2 |g'| |h'| u_c (|h'| <= 1/(4 u_s)), the stiffest part
  // when u_s is small: h turns the three-body terms off within a few u_s of u_c.
  const double t = uc * uc + 2.0 * D * D;
  const double g_max = B / 27.0 * t * t, dg_max = 2.0 * B / 27.0 * t, ddg = 2.0 * B / 27.0;
  const double three = 2.0 * 10.0 * (ddg * uc * uc + dg_max + 0.1 * g_max / (us * us) + 0.5 * dg_max * uc / us);
  const double dt0 = std::sqrt(2.0 * law.mass / (6.0 * (pair + three)));
  if (!(law.dashpot > 0)) return dt0;
  // Dashpots on the half-step velocity: leapfrog x_{n+1} - 2 x_n + x_{n-1} = -(omega dt)^2 x_n
  // - gamma dt (x_n - x_{n-1}) is stable iff (omega dt)^2 / 4 + gamma dt / 2 < 1 (Jury). The
  // damping matrix of a node is sum_j eta (2 - 2 cos k.d_j) e_j e_j^T <= 4 eta sum_j e_j e_j^T,
  // whose largest eigenvalue is at most its trace, 6: gamma <= 24 eta / m for any deformation.
  const double omega = 2.0 / dt0, gamma = 24.0 * law.dashpot / law.mass;
  return 4.0 / (gamma + std::sqrt(gamma * gamma + 4.0 * omega * omega));
}

WaveSpeeds mooney_rivlin_wave_speeds(double a, double b, double /*lambda_along*/, double lambda_across) {
  WaveSpeeds w;
  w.longitudinal = std::sqrt(a * (1.0 + 0.5 * b * (lambda_across * lambda_across - 1.0)));
  w.shear = std::sqrt(a * (1.0 - 0.5 * b));
  return w;
}

WaveSpeeds marder_lattice_wave_speeds(const MarderLaw& law, double lambda_along, double lambda_across,
                                      bool along_y) {
  // F in the frame (wave axis, other axis); bond directions of the lattice in that frame.
  const double pi = 3.14159265358979323846;
  const double step = 1e-4;
  auto energy = [&](double f11, double f21) {
    double d[3 * 6];
    std::uint8_t active[6];
    for (int k = 0; k < 6; ++k) {
      const double ang = k * pi / 3 + (along_y ? pi / 2 : 0);
      const double n1 = std::cos(ang) * law.delta, n2 = std::sin(ang) * law.delta;
      d[3 * k] = f11 * n1;
      d[3 * k + 1] = f21 * n1 + lambda_across * n2;
      d[3 * k + 2] = 0;
      active[k] = 1;
    }
    return marder_node(law, 6, d, active, nullptr);
  };
  const double e0 = energy(lambda_along, 0);
  const double q11 = (energy(lambda_along + step, 0) - 2 * e0 + energy(lambda_along - step, 0)) / (step * step);
  const double q22 = (energy(lambda_along, step) - 2 * e0 + energy(lambda_along, -step)) / (step * step);
  WaveSpeeds w;
  w.longitudinal = std::sqrt(std::max(q11, 0.0) / law.mass);
  w.shear = std::sqrt(std::max(q22, 0.0) / law.mass);
  return w;
}

}  // namespace peri
