#include "peri/bonds/bonds.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <unordered_map>

#include "peri/bonds/crossing.hpp"
#include "peri/core/error.hpp"

namespace peri {

double reach(const BodyGeometry& g) {
  if (g.quadrature == Quadrature::Full || g.quadrature == Quadrature::Taper) return g.horizon;
  return g.horizon + g.spacing * (g.traits.dimension == 3 ? 0.8660254037844387 : 0.7071067811865476);
}

namespace {

// The grid's unit along each axis: the spacing on square and cubic grids; dx/2 and dx sqrt(3)/2
// along x and y on hexagonal ones (the units discretize() places nodes on, the same expressions).
// Bodies without a grid (fibers, spheres): 0, no snapping.
std::array<double, 3> lattice_units(const BodyGeometry& g) {
  if (!g.traits.grid) return {0.0, 0.0, 0.0};
  const double dx = g.spacing;
  const bool hex = g.grid == Grid::Hexagonal;
  return {hex ? 0.5 * dx : dx, hex ? dx * std::sqrt(3.0) / 2.0 : dx, dx};
}

// Offset of grid node (i, j, k) from the body's first node in lattice units (hexagonal grids: x
// in half spacings, odd rows one further).
std::array<std::int64_t, 3> units_from_first(const BodyGeometry& g, std::int64_t i, std::int64_t j, std::int64_t k) {
  return {g.grid == Grid::Hexagonal ? 2 * i + (j % 2) : i, j, k};
}

// The stencil of body g, or an empty one when its nodes do not fill its grid in raster order.
LatticeStencil lattice_stencil(const Nodes& nodes, int body) {
  const BodyGeometry& g = nodes.bodies[body];
  LatticeStencil st;
  const std::int64_t nx = g.cells[0], ny = g.cells[1], nz = g.cells[2];
  if (!g.traits.grid || g.count <= 0 || nx * ny * nz != g.count ||
      g.first + g.count > nodes.size() || !(g.spacing > 0))
    return st;
  const std::array<double, 3> unit = lattice_units(g);
  const double* x0 = &nodes.X[3 * g.first];
  for (std::int64_t l = 0; l < g.count; ++l) {  // every node where the raster order puts it
    const std::int64_t n = g.first + l;
    if (nodes.body[n] != body) return st;
    const auto u = units_from_first(g, l % nx, (l / nx) % ny, l / (nx * ny));
    for (int c = 0; c < 3; ++c)
      if (std::fabs((nodes.X[3 * n + c] - x0[c]) / unit[c] - static_cast<double>(u[c])) > 1e-3) return st;
  }
  st.cells = g.cells;
  st.uniform_volume = std::all_of(nodes.volume.begin() + g.first, nodes.volume.begin() + g.first + g.count,
                                  [&](double v) { return v == nodes.volume[g.first]; });
  const double far = reach(g) + 1e-6 * g.spacing, far2 = far * far;
  // Offsets reach the horizon, but never beyond the grid: one that leaves it from every node
  // would only be tested and skipped for each node (a horizon wider than the body).
  const std::int64_t mx = std::min(static_cast<std::int64_t>(std::ceil(far / g.spacing)) + 1, nx - 1);
  const std::int64_t my = std::min(static_cast<std::int64_t>(std::ceil(far / unit[1])) + 1, ny - 1);
  const std::int64_t mz = g.traits.dimension == 3 ? std::min(static_cast<std::int64_t>(std::ceil(far / unit[2])) + 1, nz - 1) : 0;
  const int parities = g.grid == Grid::Hexagonal ? 2 : 1;
  for (int p = 0; p < parities; ++p)
    for (std::int64_t dk = -mz; dk <= mz; ++dk)  // (dk, dj, di) ascending: natural ids ascending
      for (std::int64_t dj = -my; dj <= my; ++dj)
        for (std::int64_t di = -mx; di <= mx; ++di) {
          if (di == 0 && dj == 0 && dk == 0) continue;
          const std::int64_t ux = parities == 2 ? 2 * di + (((p + dj) % 2 + 2) % 2) - p : di;
          // What reference_offset gives for this pair: nearbyint(difference / unit) * unit.
          const double xi[3] = {static_cast<double>(ux) * unit[0], static_cast<double>(dj) * unit[1],
                                static_cast<double>(dk) * unit[2]};
          if (xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2] > far2) continue;
          const double w = quadrature_weight(g, xi);
          if (!(w > 0)) continue;
          st.by_parity[p].push_back({static_cast<std::int32_t>(di), static_cast<std::int32_t>(dj),
                                     static_cast<std::int32_t>(dk), (dk * ny + dj) * nx + di, w,
                                     xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2]});
          st.extent = {std::max(st.extent[0], std::abs(di)), std::max(st.extent[1], std::abs(dj)),
                       std::max(st.extent[2], std::abs(dk))};
        }
  return st;
}

}  // namespace

CellList::CellList(const Nodes& nodes, double reach_, bool stencils) {
  if (stencils)
    for (std::size_t b = 0; b < nodes.bodies.size(); ++b) stencils_.push_back(lattice_stencil(nodes, static_cast<int>(b)));
  build(nodes.X.data(), nodes.size(), reach_);
}

CellList::CellList(const double* x, std::int64_t n, double reach_) { build(x, n, reach_); }

void CellList::build(const double* X, std::int64_t n, double reach_) {
  std::array<double, 3> hi{};
  lo_ = {0, 0, 0};
  if (n > 0) {
    for (int d = 0; d < 3; ++d) lo_[d] = hi[d] = X[d];
    for (std::int64_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d) {
        lo_[d] = std::min(lo_[d], X[3 * i + d]);
        hi[d] = std::max(hi[d], X[3 * i + d]);
      }
  }
  for (int d = 0; d < 3; ++d)  // (the setup refuses nodes this far apart before: check_node_positions)
    if (!std::isfinite(hi[d] - lo_[d]))
      throw InputError("the nodes span more than the largest double along axis " + std::to_string(d) +
                       "; expected nodes within 1e9 spacings of the origin");
  size_ = reach_ * (1.0 + 1e-9);
  // Keep the number of cells O(N) even for sparse scenes (grow the cell if needed).
  // (Counted in doubles: nodes flung far apart in a failing run would overflow 64-bit counts.)
  std::array<double, 3> dims{};
  for (;;) {
    double total = 1;
    for (int d = 0; d < 3; ++d) {
      dims[d] = std::floor((hi[d] - lo_[d]) / size_) + 1;
      total *= dims[d];
    }
    if (total <= 4.0 * static_cast<double>(n) + 64) break;
    size_ *= 1.5;
  }
  for (int d = 0; d < 3; ++d) dims_[d] = static_cast<std::int64_t>(dims[d]);
  const std::int64_t ncells = dims_[0] * dims_[1] * dims_[2];
  start_.assign(ncells + 1, 0);
  std::vector<std::int64_t> cell(n);
  for (std::int64_t i = 0; i < n; ++i) {
    const auto c = cell_of(&X[3 * i]);
    cell[i] = (c[2] * dims_[1] + c[1]) * dims_[0] + c[0];
    ++start_[cell[i] + 1];
  }
  std::partial_sum(start_.begin(), start_.end(), start_.begin());
  sorted_.resize(n);
  std::vector<std::int64_t> fill(start_.begin(), start_.end() - 1);
  for (std::int64_t i = 0; i < n; ++i) sorted_[fill[cell[i]]++] = i;
}

std::array<std::int64_t, 3> CellList::cell_of(const double* x) const {
  std::array<std::int64_t, 3> c{};
  for (int d = 0; d < 3; ++d)
    c[d] = std::clamp<std::int64_t>(static_cast<std::int64_t>((x[d] - lo_[d]) / size_), 0, dims_[d] - 1);
  return c;
}

namespace {

// Area of {p : |p| <= r, 0 <= p_x <= x, 0 <= p_y <= y} for x, y >= 0.
double quadrant_area(double r, double x, double y) {
  x = std::min(x, r);
  y = std::min(y, r);
  if (x * x + y * y <= r * r) return x * y;
  auto primitive = [r](double t) {  // integral of sqrt(r^2 - t^2) dt
    const double s = std::sqrt(std::max(r * r - t * t, 0.0));
    return 0.5 * (t * s + r * r * std::asin(std::clamp(t / r, -1.0, 1.0)));
  };
  const double xs = std::sqrt(std::max(r * r - y * y, 0.0));  // where the chord height equals y
  return y * xs + primitive(x) - primitive(xs);
}

// Signed extension of quadrant_area to all four quadrants (odd in x and in y).
double signed_area(double r, double x, double y) {
  const double a = quadrant_area(r, std::fabs(x), std::fabs(y));
  return ((x < 0) != (y < 0)) ? -a : a;
}

}  // namespace

double disc_rectangle_area(double r, double x0, double x1, double y0, double y1) {
  return signed_area(r, x1, y1) - signed_area(r, x0, y1) - signed_area(r, x1, y0) +
         signed_area(r, x0, y0);
}

double quadrature_weight(const BodyGeometry& g, const double xi[3]) {
  const double d = g.horizon;
  // Work with |xi| components so that xi and -xi give identical results.
  const double ax = std::fabs(xi[0]), ay = std::fabs(xi[1]), az = std::fabs(xi[2]);
  const double r2 = ax * ax + ay * ay + az * az;
  if (g.quadrature == Quadrature::Full) return r2 <= d * d * (1.0 + 1e-10) ? 1.0 : 0.0;
  if (g.quadrature == Quadrature::Taper) {
    // Volume fraction of a neighbour near the horizon as in LAMMPS' PERI package (Parks et al.
    // 2008): 1/2 + (delta - |xi|)/dx within dx/2 of delta, 1 inside, 0 beyond delta.
    if (r2 > d * d * (1.0 + 1e-10)) return 0.0;
    const double r = std::sqrt(r2);
    return std::fabs(r - d) <= 0.5 * g.spacing ? 0.5 + (d - r) / g.spacing : 1.0;
  }
  const double hx = 0.5 * g.spacing;
  if (g.traits.dimension == 2) {  // a sheet (grid sheets: membranes)
    // Cell of the neighbour: dx by (cell_area/dx) rectangle (square grid: dx by dx).
    const double hy = 0.5 * g.cell_area / g.spacing;
    // Cells wholly inside the disc (far corner within the horizon) or wholly outside (nearest
    // point beyond it) need no area: most candidates of a cell-list search are one or the other.
    if ((ax + hx) * (ax + hx) + (ay + hy) * (ay + hy) <= d * d) return 1.0;
    const double nx = std::max(ax - hx, 0.0), ny = std::max(ay - hy, 0.0);
    if (nx * nx + ny * ny >= d * d) return 0.0;
    const double area = disc_rectangle_area(d, ax - hx, ax + hx, ay - hy, ay + hy);
    const double w = area / g.cell_area;
    return w < 1e-12 ? 0.0 : std::min(w, 1.0);
  }
  // Solid: fraction of the cube inside the ball; columns in (x, y) at Gauss-like midpoints, the
  // z-extent of each column inside the ball exactly.
  const double far = std::sqrt(std::pow(ax + hx, 2) + std::pow(ay + hx, 2) + std::pow(az + hx, 2));
  if (far <= d) return 1.0;
  const double nx = std::max(ax - hx, 0.0), ny = std::max(ay - hx, 0.0), nz = std::max(az - hx, 0.0);
  if (nx * nx + ny * ny + nz * nz >= d * d) return 0.0;
  constexpr int n = 8;
  double sum = 0;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      const double x = ax - hx + (a + 0.5) * g.spacing / n, y = ay - hx + (b + 0.5) * g.spacing / n;
      const double h2 = d * d - x * x - y * y;
      if (h2 <= 0) continue;
      const double h = std::sqrt(h2);
      sum += std::max(0.0, std::min(az + hx, h) - std::max(az - hx, -h));
    }
  const double w = sum / (n * n * g.spacing);
  return w < 1e-12 ? 0.0 : std::min(w, 1.0);
}

void reference_offset(const BodyGeometry& g, const double* Xi, const double* Xj, double xi[3]) {
  const std::array<double, 3> unit = lattice_units(g);
  for (int c = 0; c < 3; ++c) {
    xi[c] = Xj[c] - Xi[c];
    if (unit[c] > 0) xi[c] = std::nearbyint(xi[c] / unit[c]) * unit[c];
  }
}

void neighbours_of(const Nodes& nodes, const CellList& cells, std::int64_t i,
                   std::vector<std::int64_t>& ids, std::vector<double>& weights, std::vector<double>* xi2) {
  ids.clear();
  weights.clear();
  if (xi2) xi2->clear();
  const int body = nodes.body[i];
  const BodyGeometry& g = nodes.bodies[body];
  if (const LatticeStencil* st = cells.stencil(body)) {
    const std::int64_t nx = st->cells[0], ny = st->cells[1], nz = st->cells[2];
    const std::int64_t l = i - g.first, ix = l % nx, iy = (l / nx) % ny, iz = l / (nx * ny);
    const std::vector<LatticeStencil::Offset>& list = st->by_parity[g.grid == Grid::Hexagonal ? iy % 2 : 0];
    const auto& e = st->extent;
    const bool inside = ix >= e[0] && ix + e[0] < nx && iy >= e[1] && iy + e[1] < ny && iz >= e[2] && iz + e[2] < nz;
    ids.reserve(list.size());
    weights.reserve(list.size());
    if (xi2) xi2->reserve(list.size());
    for (const LatticeStencil::Offset& o : list) {
      if (!inside) {
        const std::int64_t jx = ix + o.di, jy = iy + o.dj, jz = iz + o.dk;
        if (jx < 0 || jx >= nx || jy < 0 || jy >= ny || jz < 0 || jz >= nz) continue;
      }
      ids.push_back(i + o.step);
      weights.push_back(o.weight);
      if (xi2) xi2->push_back(o.xi2);
    }
    return;
  }
  const double* xi = &nodes.X[3 * i];
  // A candidate beyond reach() (the horizon; plus a cell's half-diagonal for partial areas) has
  // no weight: rejected on its raw distance before the snapped offset and the weight (most of a
  // cell-list search's candidates; the margin covers the snapping's round-off).
  const double far = reach(g) + 1e-6 * g.spacing, far2 = far * far;
  struct Found {
    std::int64_t j;
    double w, xi2;
  };
  thread_local std::vector<Found> found;
  found.clear();
  cells.for_each_candidate(xi, [&](std::int64_t j) {
    if (j == i || nodes.body[j] != body) return;
    const double* xj = &nodes.X[3 * j];
    const double e0 = xj[0] - xi[0], e1 = xj[1] - xi[1], e2 = xj[2] - xi[2];
    if (e0 * e0 + e1 * e1 + e2 * e2 > far2) return;
    double d[3];
    reference_offset(g, xi, &nodes.X[3 * j], d);
    const double w = quadrature_weight(g, d);
    if (w > 0) found.push_back({j, w, d[0] * d[0] + d[1] * d[1] + d[2] * d[2]});
  });
  std::sort(found.begin(), found.end(), [](const Found& a, const Found& b) { return a.j < b.j; });
  for (const Found& f : found) {
    ids.push_back(f.j);
    weights.push_back(f.w);
    if (xi2) xi2->push_back(f.xi2);
  }
}

std::int64_t family_class(const Nodes& nodes, const CellList& cells, std::int64_t i) {
  const int body = nodes.body[i];
  const LatticeStencil* st = cells.stencil(body);
  if (!st || !st->uniform_volume || body >= (1 << 14)) return -1;
  const BodyGeometry& g = nodes.bodies[body];
  const std::int64_t nx = st->cells[0], ny = st->cells[1];
  const std::int64_t l = i - g.first, at[3] = {l % nx, (l / nx) % ny, l / (nx * ny)};
  std::int64_t key = 2 * body + (g.grid == Grid::Hexagonal ? at[1] % 2 : 0);  // 15 bits
  for (int d = 0; d < 3; ++d) {  // distance to the low and the high face, up to the extent: 7 bits each
    const std::int64_t e = st->extent[d];
    if (e >= 127) return -1;
    key = (key << 7) | std::min(at[d], e);
    key = (key << 7) | std::min(st->cells[d] - 1 - at[d], e);
  }
  return key;
}

namespace {

// The fan triangles [first, last] of a many-cornered polygon that segment a-b may meet (first >
// last: none), a superset found by angle: the part of the segment within the slab |n . x -
// offset| <= 2 tolerance (where every point of the fan lies), projected on the plane, seen from
// the first corner, spans an arc of angles; a triangle whose wedge misses the arc, widened by the
// round-off of the projection, cannot meet the segment. Where the projection passes near the
// first corner (angles undefined) or the slab's ends are not resolved, every triangle stays.
void fan_candidates(const double* a, const double* b, double da, double db, double tolerance, double scale,
                    const Crack& crack, std::size_t& first, std::size_t& last) {
  const double slab = 2 * tolerance, dd = db - da;
  double t0 = 0, t1 = 1;
  if (dd != 0) {
    double ta = (-slab - da) / dd, tb = (slab - da) / dd;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (!(t0 <= t1)) return;
  }
  const double* c0 = crack.polygon[0].data();
  const double* u = crack.fan_u.data();
  const double* v = crack.fan_v.data();
  double q[2][2];
  for (int e = 0; e < 2; ++e) {
    const double t = e == 0 ? t0 : t1;
    double r[3];
    for (int d = 0; d < 3; ++d) r[d] = a[d] + t * (b[d] - a[d]) - c0[d];
    q[e][0] = r[0] * u[0] + r[1] * u[1] + r[2] * u[2];
    q[e][1] = r[0] * v[0] + r[1] * v[1] + r[2] * v[2];
  }
  // The in-plane segment's distance from the first corner, and how far round-off and the fan's
  // departure from the plane may move a point of it.
  const double ex = q[1][0] - q[0][0], ey = q[1][1] - q[0][1], e2 = ex * ex + ey * ey;
  double s = e2 > 0 ? -(q[0][0] * ex + q[0][1] * ey) / e2 : 0.0;
  s = std::clamp(s, 0.0, 1.0);
  const double dist = std::hypot(q[0][0] + s * ex, q[0][1] + s * ey);
  const double reach = std::fabs(c0[0]) + std::fabs(c0[1]) + std::fabs(c0[2]);
  const double slack = slab + 1e-12 * (scale + reach);
  if (!(dist > 1e3 * slack)) return;
  const double margin = slack / dist + 1e-12;
  auto angle = [](const double* p) {
    const double phi = std::atan2(p[1], p[0]);
    return phi < -M_PI / 2 ? phi + 2 * M_PI : phi;
  };
  const double p0 = angle(q[0]), p1 = angle(q[1]);
  // The arc the segment spans (the shorter way round: it passes the corner at a distance), as
  // one interval [lo, hi] of angles, or as (-inf, lo] and [hi, inf) where it passes the angle
  // 3 pi / 2 at which the angles wrap (behind the fan, which lies within [0, pi]).
  const bool wraps = std::fabs(p0 - p1) > M_PI;
  const double lo = std::min(p0, p1), hi = std::max(p0, p1);
  const std::vector<double>& low = crack.fan_low;
  const std::vector<double>& high = crack.fan_high;
  // Triangles with fan_high >= x: from the first such on; with fan_low <= y: up to the last.
  auto from = [&](double x) { return static_cast<std::size_t>(std::lower_bound(high.begin(), high.end(), x) - high.begin()); };
  auto upto = [&](double y) {
    return static_cast<std::ptrdiff_t>(std::upper_bound(low.begin(), low.end(), y) - low.begin()) - 1;
  };
  if (!wraps) {
    first = from(lo - margin);
    const std::ptrdiff_t end = upto(hi + margin);
    if (end < static_cast<std::ptrdiff_t>(first)) first = 1, last = 0;
    else last = static_cast<std::size_t>(end);
    return;
  }
  // Two ends of the fan: triangles up to angle lo, and from angle hi on; the range between them
  // when they meet, else both ends (the range from the first to the last is tested: a superset).
  const std::ptrdiff_t low_end = upto(lo + margin);
  const std::size_t high_start = from(hi - margin);
  if (low_end < 0 && high_start >= high.size()) {
    first = 1, last = 0;
    return;
  }
  first = low_end < 0 ? high_start : 0;
  last = high_start >= high.size() ? static_cast<std::size_t>(low_end) : high.size() - 1;
}

}  // namespace

bool crosses(const double* a, const double* b, const Crack& crack) {
  if (!crack.is_polygon()) return segments_cross(a, b, crack.from.data(), crack.to.data());
  // A convex polygon as the fan of triangles from its first corner (degenerate ones meet nothing);
  // neighbouring triangles share their closed edge, so a bond through it meets one of them.
  const std::vector<Vec3>& c = crack.polygon;
  // Both ends beyond the polygon's reach from its plane, on one side: nothing to meet. (The
  // distances' round-off is below 8e-16 of the magnitudes in them.)
  const double* n = crack.plane_normal.data();
  const double da = n[0] * a[0] + n[1] * a[1] + n[2] * a[2] - crack.plane_offset;
  const double db = n[0] * b[0] + n[1] * b[1] + n[2] * b[2] - crack.plane_offset;
  double scale = std::fabs(crack.plane_offset);
  for (int d = 0; d < 3; ++d) scale += std::fabs(a[d]) + std::fabs(b[d]);
  const double tolerance = crack.plane_tolerance + 8e-16 * scale;
  if ((da > tolerance && db > tolerance) || (da < -tolerance && db < -tolerance)) return false;
  std::size_t first = 0, last = c.size() - 3;  // the fan triangles to test (k: corners 0, k+1, k+2)
  if (!crack.fan_low.empty()) fan_candidates(a, b, da, db, tolerance, scale, crack, first, last);
  for (std::size_t k = first + 1; k <= last + 1; ++k)
    if (segment_meets_triangle(a, b, c[0].data(), c[k].data(), c[k + 1].data())) return true;
  return false;
}

double rounded_xi2(double xi2, double horizon) {
  const double scale = std::max(horizon * horizon, xi2);  // lattices have no horizon
  if (!(scale > 0)) return xi2;
  const double quantum = std::ldexp(1.0, std::ilogb(scale) - 46);
  return std::nearbyint(xi2 / quantum) * quantum;
}

// Patterns are found by a hash of their slots; equal hashes are confirmed slot by slot.
struct PatternBuilder::Index {
  std::unordered_multimap<std::uint64_t, std::int32_t> by_hash;
};

PatternBuilder::PatternBuilder() : index_(std::make_unique<Index>()) {}
PatternBuilder::~PatternBuilder() = default;

void PatternBuilder::add_row(const std::vector<double>& xi2, const std::vector<double>& measure, double horizon) {
  const std::size_t n = xi2.size();
  bonds_ += static_cast<std::int64_t>(n);
  thread_local std::vector<double> rounded;
  rounded.resize(n);
  std::uint64_t h = 1469598103934665603ull ^ n;  // FNV-1a over the slots' bits
  auto mix = [&h](double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    h = (h ^ bits) * 1099511628211ull;
  };
  // rounded_xi2 with the horizon's quantum (a power of two: scaling by it and its inverse is
  // exact) worked out once per row; |xi|^2 beyond the horizon squared has a quantum of its own.
  const double h2 = horizon * horizon;
  const bool by_horizon = h2 > 0 && std::isnormal(h2);
  const double quantum = by_horizon ? std::ldexp(1.0, std::ilogb(h2) - 46) : 0.0;
  const double inv_quantum = by_horizon ? std::ldexp(1.0, 46 - std::ilogb(h2)) : 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    rounded[k] = by_horizon && xi2[k] <= h2 ? std::nearbyint(xi2[k] * inv_quantum) * quantum
                                             : rounded_xi2(xi2[k], horizon);
    mix(rounded[k]);
    mix(measure[k]);
  }
  auto [lo, hi] = index_->by_hash.equal_range(h);
  for (auto it = lo; it != hi; ++it) {
    const std::int32_t p = it->second;
    const std::int64_t b = p_.begin[p];
    if (p_.begin[p + 1] - b != static_cast<std::int64_t>(n)) continue;
    bool same = true;
    for (std::size_t k = 0; k < n && same; ++k)
      same = p_.xi2[b + k] == rounded[k] && p_.measure[b + k] == measure[k];
    if (same) {
      p_.of_row.push_back(p);
      return;
    }
  }
  const auto p = static_cast<std::int32_t>(p_.patterns());
  p_.xi2.insert(p_.xi2.end(), rounded.begin(), rounded.end());
  for (std::size_t k = 0; k < n; ++k) p_.inv_xi.push_back(1.0 / std::sqrt(rounded[k]));
  p_.measure.insert(p_.measure.end(), measure.begin(), measure.end());
  for (std::size_t k = 0; k < n; ++k) p_.measure_per_xi2.push_back(measure[k] / rounded[k]);
  p_.begin.push_back(static_cast<std::int64_t>(p_.xi2.size()));
  p_.of_row.push_back(p);
  index_->by_hash.emplace(h, p);
}

void PatternBuilder::add_free_row(const std::vector<double>& weights) {
  bool whole = true;
  for (double w : weights) whole = whole && static_cast<float>(w) == 1.0f;
  if (!whole && !weighted_) {  // the bonds so far weigh 1
    p_.free_weight.assign(static_cast<std::size_t>(bonds_), 1.0f);
    weighted_ = true;
  }
  if (weighted_)
    for (double w : weights) p_.free_weight.push_back(static_cast<float>(w));
  bonds_ += static_cast<std::int64_t>(weights.size());
  p_.of_row.push_back(FamilyPatterns::kFree);
  p_.has_free = true;
}

FamilyPatterns PatternBuilder::finish() {
  if (weighted_) p_.free_weight.resize(static_cast<std::size_t>(bonds_), 1.0f);
  p_.xi2.shrink_to_fit();
  p_.inv_xi.shrink_to_fit();
  p_.measure.shrink_to_fit();
  p_.measure_per_xi2.shrink_to_fit();
  index_->by_hash.clear();
  return std::move(p_);
}

void BondFamilies::summarize_rows() {
  row_broken.assign(static_cast<std::size_t>(rows()), 0);
  for (std::int64_t i = 0; i < rows(); ++i)
    for (std::int64_t b = offsets[i]; b < offsets[i + 1]; ++b) row_broken[i] |= broken[b] ? 1 : 0;
}

double BondFamilies::bytes_per_bond() const {
  if (neighbor.empty()) return 0;
  const double bytes = offsets.size() * sizeof(std::int64_t) + neighbor.size() * sizeof(std::int32_t) +
                       broken.size() + row_broken.size() + patterns.of_row.size() * sizeof(std::int32_t) +
                       patterns.begin.size() * sizeof(std::int64_t) +
                       (patterns.xi2.size() + patterns.inv_xi.size() + patterns.measure.size() +
                        patterns.measure_per_xi2.size() + history.size()) * sizeof(double) +
                       patterns.free_weight.size() * sizeof(float);
  return bytes / static_cast<double>(neighbor.size());
}

}  // namespace peri
