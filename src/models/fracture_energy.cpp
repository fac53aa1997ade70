#include "peri/models/fracture_energy.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "peri/bonds/crossing.hpp"
#include "peri/core/error.hpp"

namespace peri {

CrackAdvanceEnergy crack_advance_energy(const Nodes& nodes, const CellList& cells, const BondLaw& law, int body,
                                        const Crack& advance) {
  const BodyGeometry& g = nodes.bodies.at(body);
  if (!g.traits.flat || !g.traits.grid) throw InputError("crack_advance_energy: flat grid sheets (membranes) only");
  if (!law.breaks()) throw InputError("crack_advance_energy: the material has no critical stretch");
  const double* a = advance.from.data();
  const double* b = advance.to.data();
  const double len = std::hypot(b[0] - a[0], b[1] - a[1]);
  // Count each crossing bond once: from its end on the right of a -> b (negative orientation).
  auto side = [&](const double* p) { return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]); };
  auto seg_distance = [&](const double* p) {
    const double ux = b[0] - a[0], uy = b[1] - a[1];
    const double t = std::clamp(((p[0] - a[0]) * ux + (p[1] - a[1]) * uy) / (len * len), 0.0, 1.0);
    return std::hypot(p[0] - a[0] - t * ux, p[1] - a[1] - t * uy);
  };
  const double reach_i = reach(g);
  CrackAdvanceEnergy out;
  std::vector<std::int64_t> ids;
  std::vector<double> weights;
  for (std::int64_t i = g.first; i < g.first + g.count; ++i) {
    const double* xi = &nodes.X[3 * i];
    if (side(xi) >= 0 || seg_distance(xi) > reach_i) continue;
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
  out.release_rate = out.energy / (g.thickness * len);
  return out;
}

CrackAdvanceEnergy crack_advance_energy_3d(const Nodes& nodes, const CellList& cells, const BondLaw& law, int body,
                                           const Crack& advance) {
  const BodyGeometry& g = nodes.bodies.at(body);
  if (g.traits.dimension != 3) throw InputError("crack_advance_energy_3d: solid bodies only");
  if (!law.breaks()) throw InputError("crack_advance_energy_3d: the material has no critical stretch");
  if (!advance.is_polygon()) throw InputError("crack_advance_energy_3d: the advance is a polygon");
  const std::vector<Vec3>& c = advance.polygon;
  // Newell's vector area; a side of the plane through the first three corners (exact).
  double area[3] = {0, 0, 0};
  for (std::size_t k = 0; k < c.size(); ++k) {
    const Vec3& p = c[k];
    const Vec3& q = c[(k + 1) % c.size()];
    area[0] += 0.5 * (p[1] * q[2] - p[2] * q[1]);
    area[1] += 0.5 * (p[2] * q[0] - p[0] * q[2]);
    area[2] += 0.5 * (p[0] * q[1] - p[1] * q[0]);
  }
  auto side = [&](const double* x) { return orient3d(c[0].data(), c[1].data(), c[2].data(), x); };
  const double reach_i = reach(g);
  CrackAdvanceEnergy out;
  std::vector<std::int64_t> ids;
  std::vector<double> weights;
  for (std::int64_t i = g.first; i < g.first + g.count; ++i) {
    const double* xi = &nodes.X[3 * i];
    if (side(xi) >= 0) continue;  // each crossing bond once: from its end on the negative side
    bool near = true;             // within the reach of the polygon's box
    for (int d = 0; d < 3; ++d) {
      double lo = c[0][d], hi = c[0][d];
      for (const Vec3& p : c) lo = std::min(lo, p[d]), hi = std::max(hi, p[d]);
      near = near && xi[d] >= lo - reach_i && xi[d] <= hi + reach_i;
    }
    if (!near) continue;
    neighbours_of(nodes, cells, i, ids, weights);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const std::int64_t j = ids[k];
      const double* xj = &nodes.X[3 * j];
      if (side(xj) < 0) continue;
      if (!(i < j ? crosses(xi, xj, advance) : crosses(xj, xi, advance))) continue;
      double s2 = 0;
      for (int d = 0; d < 3; ++d) s2 += (xj[d] - xi[d]) * (xj[d] - xi[d]);
      out.energy += law.critical_energy(s2) * weights[k] * nodes.volume[i] * nodes.volume[j];
      ++out.bonds;
    }
  }
  out.release_rate = out.energy / std::sqrt(area[0] * area[0] + area[1] * area[1] + area[2] * area[2]);
  return out;
}

double release_rate_3d(const BondLaw& law) {
  // Composite Simpson on [0, delta] of w_0(xi) xi^3.
  const int n = 2000;
  const double d = law.horizon(), step = d / n;
  double sum = 0;
  for (int k = 1; k <= n; ++k) {
    const double xi = k * step;
    sum += law.critical_energy(xi * xi) * xi * xi * xi * (k == n ? 1 : (k % 2 ? 4 : 2));
  }
  return M_PI * sum * step / 3.0;
}

double eq30_release_rate(const BondLaw& law, double thickness) {
  // Composite Simpson on [0, delta] of w_0(xi) xi^2 (smooth: g and lambda_0 are linear in xi).
  const int n = 2000;
  const double d = law.horizon(), step = d / n;
  double sum = 0;
  for (int k = 0; k <= n; ++k) {
    const double xi = k * step;
    if (xi == 0) continue;
    const double f = law.critical_energy(xi * xi) * xi * xi;
    sum += f * (k == 0 || k == n ? 1 : (k % 2 ? 4 : 2));
  }
  return 2.0 * thickness * sum * step / 3.0;  // eq. (30)
}

}  // namespace peri
