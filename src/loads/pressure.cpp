#include "peri/loads/pressure.hpp"

#include <algorithm>
#include <sstream>
#include <unordered_map>
#include <utility>

namespace peri {

Pressure::Pressure(const Scene& scene, const std::vector<BodyGeometry>& bodies, const Domain& domain)
    : domain_(domain) {
  std::unordered_map<std::int64_t, std::int32_t> local;  // natural -> local, nodes of loaded spheres
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    const Body& body = scene.bodies[b];
    if (!(body.pressure > 0)) continue;  // (spheres and mesh membranes take a pressure)
    if (local.empty())
      for (std::int32_t l = 0; l < domain.local(); ++l) local.emplace(domain.natural[l], l);
    const BodyGeometry& g = bodies[b];
    Sphere load;
    // Per owned corner, its triangles' other corners and the triangle (in the file's order of the
    // triangles, the same on any number of ranks).
    std::vector<std::vector<std::array<std::int32_t, 3>>> shares(domain.owned);
    for (const auto& t : g.triangles) {
      std::int32_t at[3] = {-1, -1, -1};
      for (int k = 0; k < 3; ++k)
        if (const auto i = local.find(t[k]); i != local.end()) at[k] = i->second;
      if (at[0] < 0 || at[1] < 0 || at[2] < 0) continue;  // a corner beyond the halo: no share
      bool met = false;
      for (int k = 0; k < 3; ++k) {
        if (at[k] >= domain.owned) continue;
        shares[at[k]].push_back({at[(k + 1) % 3], at[(k + 2) % 3], static_cast<std::int32_t>(load.corners.size())});
        met = true;
      }
      if (met) load.corners.push_back({at[0], at[1], at[2]});
    }
    load.body = body.name;
    load.pressure = body.pressure;
    load.ramp = body.pressure_ramp_time;
    auto bond_to = [&](std::int32_t i, std::int32_t j) -> std::int64_t {
      for (std::int64_t q = domain.bonds.offsets[i]; q < domain.bonds.offsets[i + 1]; ++q)
        if (domain.bonds.neighbor[q] == j) return q;
      return -1;
    };
    for (std::int32_t i = 0; i < domain.owned; ++i) {
      if (shares[i].empty()) continue;
      load.node.push_back(i);
      load.inv_volume.push_back(1.0 / domain.volume[i]);
      for (const auto& [a, c, t] : shares[i]) {
        load.triangle.push_back(t);
        load.bonds.push_back({bond_to(i, a), bond_to(i, c)});
      }
      load.begin.push_back(static_cast<std::int64_t>(load.triangle.size()));
    }
    load.area.assign(3 * load.corners.size(), 0.0);
    load.force_prev.assign(3 * load.node.size(), 0.0);
    load.x_prev.assign(3 * load.node.size(), 0.0);
    loads_.push_back(std::move(load));
  }
}

double Pressure::current(const Sphere& load, double t) const {
  if (load.held >= 0) return load.held;
  return load.pressure * (load.ramp > 0 ? std::min(t / load.ramp, 1.0) : 1.0);
}

void Pressure::begin_quasistatic(double t) {
  // At the run's start no pressure has acted yet (even without a ramp): level 0 is p = 0.
  for (Sphere& load : loads_) load.held = load.held_from = load.held >= 0 || t > 0 ? current(load, t) : 0.0;
}

void Pressure::set_quasistatic_level(double level) {
  for (Sphere& load : loads_) load.held = load.held_from + level * (load.pressure - load.held_from);
}

std::string Pressure::quasistatic_text(double level) const {
  // (every rank holds every loaded body's entry, with or without owned corners)
  std::ostringstream s;
  s.precision(7);
  for (const Sphere& load : loads_)
    s << (s.tellp() > 0 ? ", " : "") << "the pressure in body '" << load.body << "' "
      << load.held_from + level * (load.pressure - load.held_from) << " Pa";
  return s.str();
}

void Pressure::add_stiffness(const LoadTarget& target, const StiffnessSink& sink) const {
  const double* x = target.x;
  const std::int64_t s = target.x_stride;
  auto pos = [&](std::int32_t i, int c) { return x[c * s + i]; };
  // [v]x: the matrix of v x (.), row-major, times k.
  auto cross = [](const double* v, double k, double* m) {
    const double r[9] = {0, -v[2], v[1], v[2], 0, -v[0], -v[1], v[0], 0};
    for (int q = 0; q < 9; ++q) m[q] = k * r[q];
  };
  for (const Sphere& load : loads_) {
    const double k = (load.held >= 0 ? load.held : load.pressure) / 6.0;
    for (std::size_t m = 0; m < load.node.size(); ++m) {
      const std::int32_t i = load.node[m];
      for (std::int64_t e = load.begin[m]; e < load.begin[m + 1]; ++e) {
        if (!intact(load.bonds[e][0]) || !intact(load.bonds[e][1])) continue;
        const auto [a, c] = others(load, e, i);
        const double e1[3] = {pos(a, 0) - pos(i, 0), pos(a, 1) - pos(i, 1), pos(a, 2) - pos(i, 2)};
        const double e2[3] = {pos(c, 0) - pos(i, 0), pos(c, 1) - pos(i, 1), pos(c, 2) - pos(i, 2)};
        // F_i = k e1 x e2: dF_i = k ([e2]x - [e1]x) dx_i - k [e2]x dx_a + k [e1]x dx_c; K = -dF.
        double kia[9], kic[9], kii[9];
        cross(e2, k, kia);
        cross(e1, -k, kic);
        for (int q = 0; q < 9; ++q) kii[q] = -(kia[q] + kic[q]);
        sink(i, i, kii);
        sink(i, a, kia);
        sink(i, c, kic);
      }
    }
  }
}

void Pressure::add_forces(double t, const LoadTarget& target, bool book, EnergyLedger& ledger) {
  const double* x = target.x;
  const std::int64_t s = target.x_stride;
  double* force = target.force;
  auto pos = [&](std::int32_t i, int c) { return x[c * s + i]; };
  for (Sphere& load : loads_) {
    const double p = current(load, t);
    // p times a triangle's area vector (1/2 (b - a) x (c - a), formed once per triangle from its
    // corners in the file's order, so its three corners take the same bits on any number of
    // ranks), a third to each corner. (The division outside the loop: the compiler keeps it
    // inside, past the intact tests' branch.)
    const double k = p / 6.0;
    const std::size_t n_triangles = load.corners.size();
    for (std::size_t q = 0; q < n_triangles; ++q) {
      const auto [a, b, c] = load.corners[q];
      const double e1[3] = {pos(b, 0) - pos(a, 0), pos(b, 1) - pos(a, 1), pos(b, 2) - pos(a, 2)};
      const double e2[3] = {pos(c, 0) - pos(a, 0), pos(c, 1) - pos(a, 1), pos(c, 2) - pos(a, 2)};
      load.area[3 * q] = e1[1] * e2[2] - e1[2] * e2[1];
      load.area[3 * q + 1] = e1[2] * e2[0] - e1[0] * e2[2];
      load.area[3 * q + 2] = e1[0] * e2[1] - e1[1] * e2[0];
    }
    double work = 0;
    for (std::size_t m = 0; m < load.node.size(); ++m) {
      const std::int32_t i = load.node[m];
      // A row without a broken bond (BondFamilies::row_broken) has every triangle whole.
      const bool whole = domain_.bonds.row_broken[i] == 0;
      double f[3] = {0, 0, 0};
      for (std::int64_t e = load.begin[m]; e < load.begin[m + 1]; ++e) {
        if (!whole && (!intact(load.bonds[e][0]) || !intact(load.bonds[e][1]))) continue;
        const double* area = load.area.data() + 3 * static_cast<std::size_t>(load.triangle[e]);
        f[0] += k * area[0];
        f[1] += k * area[1];
        f[2] += k * area[2];
      }
      const double inv_volume = load.inv_volume[m];
      for (int c = 0; c < 3; ++c) {
        force[3 * static_cast<std::size_t>(i) + c] += f[c] * inv_volume;
        const double xc = pos(i, c);
        if (book && load.started) work += 0.5 * (load.force_prev[3 * m + c] + f[c]) * (xc - load.x_prev[3 * m + c]);
        load.force_prev[3 * m + c] = f[c];
        load.x_prev[3 * m + c] = xc;
      }
    }
    load.started = true;
    ledger.external_work += work;
  }
}

}  // namespace peri
