#include "peri/models/fracture_energy.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "peri/bonds/crossing.hpp"
#include "peri/core/error.hpp"

namespace peri {

namespace {

// The bonds of `body` that cross `advance`, each once: from its end i on the negative side
// (side(x_i) < 0, and near(x_i): within reach of the advance) to an end j on the other side;
// the energy w_0 w_ij V_i V_j they hold at breaking (eq. 26), divided by `measure` for G_h.
template <class Side, class Near>
CrackAdvanceEnergy crossing_bonds(const Nodes& nodes, const CellList& cells, const BondLaw& law, int body,
                                  const Crack& advance, Side side, Near near, double measure) {
  const BodyGeometry& g = nodes.bodies.at(body);
  CrackAdvanceEnergy out;
  std::vector<std::int64_t> ids;
  std::vector<double> weights;
  for (std::int64_t i = g.first; i < g.first + g.count; ++i) {
    const double* xi = &nodes.X[3 * i];
    if (!(side(xi) < 0) || !near(xi)) continue;
    neighbours_of(nodes, cells, i, ids, weights);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const std::int64_t j = ids[k];
      const double* xj = &nodes.X[3 * j];
      if (side(xj) < 0) continue;
      if (!(i < j ? crosses(xi, xj, advance) : crosses(xj, xi, advance))) continue;
      double s2 = 0;
      for (int c = 0; c < 3; ++c) s2 += (xj[c] - xi[c]) * (xj[c] - xi[c]);
      out.energy += law.critical_energy(s2) * weights[k] * nodes.volume[i] * nodes.volume[j];  // eq. (26)
      ++out.bonds;
    }
  }
  out.release_rate = out.energy / measure;
  return out;
}

// Composite Simpson on [0, delta] of w_0(xi) xi^power (smooth: g and lambda_0 are linear in xi).
double critical_energy_moment(const BondLaw& law, int power) {
  const int n = 2000;
  const double d = law.horizon(), step = d / n;
  double sum = 0;
  for (int k = 1; k <= n; ++k) {
    const double xi = k * step;
    double f = law.critical_energy(xi * xi);
    for (int q = 0; q < power; ++q) f *= xi;
    sum += f * (k == n ? 1 : (k % 2 ? 4 : 2));
  }
  return sum * step / 3.0;
}

}  // namespace

CrackAdvanceEnergy crack_advance_energy(const Nodes& nodes, const CellList& cells, const BondLaw& law, int body,
                                        const Crack& advance) {
  const BodyGeometry& g = nodes.bodies.at(body);
  if (!g.traits.flat || !g.traits.grid) throw InputError("crack_advance_energy: flat grid sheets (membranes) only");
  if (!law.breaks()) throw InputError("crack_advance_energy: the material has no critical stretch");
  const double* a = advance.from.data();
  const double* b = advance.to.data();
  const double len = std::hypot(b[0] - a[0], b[1] - a[1]);
  // Each crossing bond from its end on the right of a -> b (negative orientation).
  auto side = [&](const double* p) { return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]); };
  const double reach_i = reach(g);
  auto near = [&](const double* p) {
    const double ux = b[0] - a[0], uy = b[1] - a[1];
    const double t = std::clamp(((p[0] - a[0]) * ux + (p[1] - a[1]) * uy) / (len * len), 0.0, 1.0);
    return std::hypot(p[0] - a[0] - t * ux, p[1] - a[1] - t * uy) <= reach_i;
  };
  return crossing_bonds(nodes, cells, law, body, advance, side, near, g.thickness * len);
}

CrackAdvanceEnergy crack_advance_energy_3d(const Nodes& nodes, const CellList& cells, const BondLaw& law, int body,
                                           const Crack& advance) {
  const BodyGeometry& g = nodes.bodies.at(body);
  if (g.traits.dimension != 3) throw InputError("crack_advance_energy_3d: solid bodies only");
  if (!law.breaks()) throw InputError("crack_advance_energy_3d: the material has no critical stretch");
  if (!advance.is_polygon()) throw InputError("crack_advance_energy_3d: the advance is a polygon");
  const std::vector<Vec3>& c = advance.polygon;
  // Newell's vector area, and the polygon's box grown by the reach.
  double area[3] = {0, 0, 0};
  Vec3 lo = c[0], hi = c[0];
  const double reach_i = reach(g);
  for (std::size_t k = 0; k < c.size(); ++k) {
    const Vec3& p = c[k];
    const Vec3& q = c[(k + 1) % c.size()];
    area[0] += 0.5 * (p[1] * q[2] - p[2] * q[1]);
    area[1] += 0.5 * (p[2] * q[0] - p[0] * q[2]);
    area[2] += 0.5 * (p[0] * q[1] - p[1] * q[0]);
    for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], p[d]), hi[d] = std::max(hi[d], p[d]);
  }
  // A side of the plane through the first three corners (exact).
  auto side = [&](const double* x) { return orient3d(c[0].data(), c[1].data(), c[2].data(), x); };
  auto near = [&](const double* x) {
    for (int d = 0; d < 3; ++d)
      if (x[d] < lo[d] - reach_i || x[d] > hi[d] + reach_i) return false;
    return true;
  };
  return crossing_bonds(nodes, cells, law, body, advance, side, near,
                        std::sqrt(area[0] * area[0] + area[1] * area[1] + area[2] * area[2]));
}

double release_rate_3d(const BondLaw& law) { return M_PI * critical_energy_moment(law, 3); }

double eq30_release_rate(const BondLaw& law, double thickness) {
  return 2.0 * thickness * critical_energy_moment(law, 2);  // eq. (30)
}

}  // namespace peri
