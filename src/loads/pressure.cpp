#include "peri/loads/pressure.hpp"

#include <algorithm>
#include <unordered_map>
#include <utility>

namespace peri {

Pressure::Pressure(const Scene& scene, const std::vector<BodyGeometry>& bodies, const Domain& domain)
    : domain_(domain) {
  std::unordered_map<std::int64_t, std::int32_t> local;  // natural -> local, nodes of loaded spheres
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    const Body& body = scene.bodies[b];
    if (!(body.pressure > 0)) continue;  // (only spheres take a pressure)
    if (local.empty())
      for (std::int32_t l = 0; l < domain.local(); ++l) local.emplace(domain.natural[l], l);
    const BodyGeometry& g = bodies[b];
    std::vector<std::vector<std::pair<std::int32_t, std::int32_t>>> corners(domain.owned);
    for (const auto& t : g.triangles)
      for (int k = 0; k < 3; ++k) {
        const auto i = local.find(t[k]);
        if (i == local.end() || i->second >= domain.owned) continue;
        const auto a = local.find(t[(k + 1) % 3]), c = local.find(t[(k + 2) % 3]);
        if (a == local.end() || c == local.end()) continue;  // a corner beyond the halo: no share
        corners[i->second].push_back({a->second, c->second});
      }
    Sphere load;
    load.pressure = body.pressure;
    load.ramp = body.pressure_ramp_time;
    auto bond_to = [&](std::int32_t i, std::int32_t j) -> std::int64_t {
      for (std::int64_t q = domain.bonds.offsets[i]; q < domain.bonds.offsets[i + 1]; ++q)
        if (domain.bonds.neighbor[q] == j) return q;
      return -1;
    };
    for (std::int32_t i = 0; i < domain.owned; ++i) {
      if (corners[i].empty()) continue;
      load.node.push_back(i);
      for (const auto& [a, c] : corners[i]) {
        load.others.push_back({a, c});
        load.bonds.push_back({bond_to(i, a), bond_to(i, c)});
      }
      load.begin.push_back(static_cast<std::int64_t>(load.others.size()));
    }
    load.force_prev.assign(3 * load.node.size(), 0.0);
    load.x_prev.assign(3 * load.node.size(), 0.0);
    loads_.push_back(std::move(load));
  }
}

void Pressure::add_forces(double t, const LoadTarget& target, bool book, EnergyLedger& ledger) {
  const double* x = target.x;
  const std::int64_t s = target.x_stride;
  double* force = target.force;
  auto pos = [&](std::int32_t i, int c) { return x[c * s + i]; };
  auto intact = [&](std::int64_t q) { return q < 0 || !(domain_.bonds.broken[q] & 1); };
  for (Sphere& load : loads_) {
    const double p = load.pressure * (load.ramp > 0 ? std::min(t / load.ramp, 1.0) : 1.0);
    double work = 0;
    for (std::size_t m = 0; m < load.node.size(); ++m) {
      const std::int32_t i = load.node[m];
      double f[3] = {0, 0, 0};
      for (std::int64_t e = load.begin[m]; e < load.begin[m + 1]; ++e) {
        if (!intact(load.bonds[e][0]) || !intact(load.bonds[e][1])) continue;
        const std::int32_t a = load.others[e][0], c = load.others[e][1];
        const double e1[3] = {pos(a, 0) - pos(i, 0), pos(a, 1) - pos(i, 1), pos(a, 2) - pos(i, 2)};
        const double e2[3] = {pos(c, 0) - pos(i, 0), pos(c, 1) - pos(i, 1), pos(c, 2) - pos(i, 2)};
        // p times the triangle's area vector (1/2 e1 x e2), a third to this corner.
        const double k = p / 6.0;
        f[0] += k * (e1[1] * e2[2] - e1[2] * e2[1]);
        f[1] += k * (e1[2] * e2[0] - e1[0] * e2[2]);
        f[2] += k * (e1[0] * e2[1] - e1[1] * e2[0]);
      }
      const double inv_volume = 1.0 / domain_.volume[i];
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
