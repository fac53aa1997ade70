#include "peri/geometry/discretization.hpp"

#include <algorithm>
#include <map>
#include <cmath>
#include <limits>
#include <sstream>

namespace peri {
namespace {

std::int64_t count_along(double length, double dx) {
  return std::max<std::int64_t>(1, std::llround(length / dx));
}

double distance(const Vec3& p, const Vec3& q) {
  return std::sqrt(std::pow(q[0] - p[0], 2) + std::pow(q[1] - p[1], 2) + std::pow(q[2] - p[2], 2));
}

double path_length(const std::vector<Vec3>& path) {
  double length = 0;
  for (std::size_t k = 1; k < path.size(); ++k) length += distance(path[k - 1], path[k]);
  return length;
}

// Number of neighbours inside a horizon of m spacings (continuum estimate + boundary cells).
double neighbours_estimate(const Body& b) {
  if (b.kind == BodyKind::Lattice) return 6.0;  // nearest neighbours of a triangular lattice
  if (b.kind == BodyKind::Fiber) return 2.0 * std::floor(b.horizon_value() / b.spacing + 1e-9);
  const double m = b.horizon_value() / b.spacing + 0.71;
  return b.kind == BodyKind::Solid ? 4.18879 * m * m * m : 3.14159 * m * m;
}

// Splitmix64: a fully specified generator (the same integers everywhere; the normal deviates also
// go through libm's log and cos, the same on every rank of a run).
struct SplitMix {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  double uniform() { return (static_cast<double>(next() >> 11) + 0.5) * 0x1.0p-53; }  // (0, 1)
  double normal() {  // Box-Muller
    const double u = uniform(), v = uniform();
    return std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * 3.14159265358979323846 * v);
  }
};

// Mirror coordinate x back into [lo, hi].
double mirror_into(double x, double lo, double hi) {
  for (int k = 0; k < 8 && (x < lo || x > hi); ++k) x = x < lo ? 2 * lo - x : 2 * hi - x;
  return std::clamp(x, lo, hi);
}

std::vector<std::vector<Vec3>> network_paths(const FiberNetwork& n) {
  SplitMix rng{static_cast<std::uint64_t>(n.seed) * 0x2545f4914f6cdd1dull + 1};
  std::vector<std::vector<Vec3>> paths;
  for (const FiberFamily& f : n.families) {
    const int a = f.axis, t = 1 - a;  // along, across (in the plane); z out of the plane
    for (long k = 0; k < f.count; ++k) {
      Vec3 p;
      p[a] = n.min[a] + n.start_band * rng.uniform();
      p[t] = n.min[t] + (n.max[t] - n.min[t]) * rng.uniform();
      p[2] = n.min[2] + (n.max[2] - n.min[2]) * rng.uniform();
      std::vector<Vec3> path{p};
      while (path.back()[a] < n.max[a]) {
        const double theta = n.deviation * rng.normal(), phi = n.deviation * rng.normal();
        Vec3 q = path.back();
        q[a] += n.step * std::cos(phi) * std::cos(theta);
        q[t] += n.step * std::cos(phi) * std::sin(theta);
        q[2] += n.step * std::sin(phi);
        q[t] = mirror_into(q[t], n.min[t], n.max[t]);
        q[2] = mirror_into(q[2], n.min[2], n.max[2]);
        if (q[a] > n.max[a]) {  // end on the far face
          const Vec3& o = path.back();
          const double s = (n.max[a] - o[a]) / (q[a] - o[a]);
          for (int c = 0; c < 3; ++c) q[c] = o[c] + s * (q[c] - o[c]);
          q[a] = n.max[a];
        }
        if (q[a] <= path.back()[a]) {  // a step backwards (|theta| > pi/2): draw again
          if (path.size() > 100000) break;
          continue;
        }
        path.push_back(q);
      }
      if (path.size() >= 2) paths.push_back(std::move(path));
    }
  }
  return paths;
}

// Geodesic sphere of frequency n: every face of the icosahedron split into n^2 triangles, the
// points projected onto the unit sphere. A point shared by faces is made once, from its corner
// or edge (lower vertex index first), so that it has one id and one set of bits. Triangles are
// counter-clockwise seen from outside.
void geodesic_sphere(std::int64_t n, std::vector<Vec3>& points, std::vector<std::array<std::int64_t, 3>>& triangles) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  const double v[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                           {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  const int faces[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                            {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                            {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  std::map<std::array<std::int64_t, 4>, std::int64_t> ids;
  auto point = [&](int f, std::int64_t i, std::int64_t j) {
    // Barycentric weights (n - i - j, i, j) on the face's corners.
    const int c[3] = {faces[f][0], faces[f][1], faces[f][2]};
    const std::int64_t w[3] = {n - i - j, i, j};
    std::array<std::int64_t, 4> key;
    int nz = 0;
    for (int k = 0; k < 3; ++k) nz += w[k] > 0;
    if (nz == 1) {  // a corner
      int k = w[0] > 0 ? 0 : w[1] > 0 ? 1 : 2;
      key = {0, c[k], 0, 0};
    } else if (nz == 2) {  // an edge: (lower corner, higher corner, weight of the higher)
      int a = -1, b = -1;
      for (int k = 0; k < 3; ++k)
        if (w[k] > 0) (a < 0 ? a : b) = k;
      if (c[a] > c[b]) std::swap(a, b);
      key = {1, c[a], c[b], w[b]};
    } else {
      key = {2, f, i, j};
    }
    const auto it = ids.find(key);
    if (it != ids.end()) return it->second;
    double p[3];
    if (key[0] == 0) {
      for (int d = 0; d < 3; ++d) p[d] = v[key[1]][d];
    } else if (key[0] == 1) {
      const double s = static_cast<double>(key[3]) / static_cast<double>(n);
      for (int d = 0; d < 3; ++d) p[d] = v[key[1]][d] + s * (v[key[2]][d] - v[key[1]][d]);
    } else {
      for (int d = 0; d < 3; ++d)
        p[d] = (static_cast<double>(w[0]) * v[c[0]][d] + static_cast<double>(w[1]) * v[c[1]][d] +
                static_cast<double>(w[2]) * v[c[2]][d]) / static_cast<double>(n);
    }
    const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    points.push_back({p[0] / r, p[1] / r, p[2] / r});
    const std::int64_t id = static_cast<std::int64_t>(points.size()) - 1;
    ids.emplace(key, id);
    return id;
  };
  for (int f = 0; f < 20; ++f)
    for (std::int64_t i = 0; i < n; ++i)
      for (std::int64_t j = 0; i + j < n; ++j) {
        triangles.push_back({point(f, i, j), point(f, i + 1, j), point(f, i, j + 1)});
        if (i + j + 1 < n) triangles.push_back({point(f, i + 1, j), point(f, i + 1, j + 1), point(f, i, j + 1)});
      }
  for (auto& tri : triangles) {  // outward: (b - a) x (c - a) along the position
    const Vec3 &a = points[tri[0]], &b = points[tri[1]], &c = points[tri[2]];
    const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double nrm[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    if (nrm[0] * (a[0] + b[0] + c[0]) + nrm[1] * (a[1] + b[1] + c[1]) + nrm[2] * (a[2] + b[2] + c[2]) < 0)
      std::swap(tri[1], tri[2]);
  }
}

double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double nrm[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  return 0.5 * std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
}

}  // namespace

std::int64_t sphere_frequency(double radius, double spacing) {
  // The icosahedron's edge subtends 1.1071 rad; its n-fold subdivision, about 1.1071 R / n.
  const double n = 1.1071487177940904 * radius / spacing;  // beyond 1e9: refused by the size check
  return std::max<std::int64_t>(1, std::llround(std::min(n, 1e9)));
}

std::vector<std::vector<Vec3>> fiber_paths(const Body& b) {
  if (b.network) return network_paths(*b.network);
  return {b.path};
}

SizeEstimate estimate_size(const Scene& scene) {
  SizeEstimate e;
  for (std::size_t bi = 0; bi < scene.bodies.size(); ++bi) {
    const Body& b = scene.bodies[bi];
    double n = 1;
    const int dims = b.kind == BodyKind::Solid ? 3 : b.kind == BodyKind::Fiber ? 0 : 2;
    for (int d = 0; d < dims; ++d) n *= std::max(1.0, std::round(b.size[d] / b.spacing));
    if (b.kind == BodyKind::Shell) n = 10.0 * std::pow(static_cast<double>(sphere_frequency(b.radius, b.spacing)), 2) + 2;
    if (b.kind == BodyKind::Fiber) {
      n = 0;
      if (b.network)  // every fiber crosses the box once; its path is longer by its wiggles (bounded by 1.5)
        for (const FiberFamily& f : b.network->families)
          n += 1.5 * f.count * (b.network->max[f.axis] - b.network->min[f.axis]) / b.spacing;
      else
        n = std::max(1.0, std::round(path_length(b.path) / b.spacing));
    }
    if (b.grid == Grid::Hexagonal || b.kind == BodyKind::Lattice) n *= 2.0 / std::sqrt(3.0);
    // A horizon that takes in the whole body bonds every node to every other, no more.
    const double family = std::min(neighbours_estimate(b), std::max(n - 1, 0.0));
    e.nodes += n;
    e.bonds += n * family;
    if (family > e.largest_family) {
      e.largest_family = family;
      e.largest_family_body = static_cast<int>(bi);
    }
  }
  // 5 bytes per ordered bond (32-bit neighbour, flag; the reference geometry is shared by family
  // patterns) + ~350 bytes per node (state, PETSc, forces, output), as measured at 1M nodes.
  e.bytes = 5.0 * e.bonds + 350.0 * e.nodes;
  return e;
}

Nodes discretize(const Scene& scene) {
  Nodes nodes;
  const SizeEstimate est = estimate_size(scene);
  if (est.nodes > 2.0e9 || est.bonds > 2.0e11) {
    std::ostringstream msg;
    msg << scene.file << ": the scene asks for about " << est.nodes << " nodes and " << est.bonds
        << " bonds (" << est.bytes / 1e9 << " GB); peridrive indexes nodes with 32 bits per rank "
        << "and cannot run it: increase the spacing";
    throw InputError(msg.str());
  }
  nodes.X.reserve(static_cast<std::size_t>(3 * est.nodes));
  for (std::size_t bi = 0; bi < scene.bodies.size(); ++bi) {
    const Body& b = scene.bodies[bi];
    BodyGeometry g;
    g.material = scene.material_index(b.material);
    g.kind = b.kind;
    g.grid = b.grid;
    g.spacing = b.spacing;
    g.horizon = b.horizon_value();
    g.quadrature = b.quadrature;
    g.first = nodes.size();
    const double dx = b.spacing;
    auto push = [&](double x, double y, double z, double vol) {
      nodes.X.insert(nodes.X.end(), {x, y, z});
      nodes.volume.push_back(vol);
      nodes.body.push_back(static_cast<int>(bi));
    };
    if (b.kind == BodyKind::Lattice) {
      // Marder's triangular lattice: the hexagonal grid below, bonds to the six nearest
      // neighbours only (next-nearest ones are sqrt(3) Delta away).
      g.grid = Grid::Hexagonal;
      g.quadrature = Quadrature::Full;
      g.horizon = 1.1 * dx;
    }
    if (b.kind == BodyKind::Shell) {
      // Geodesic nodes on the sphere; a node's area is a third of its triangles' (flat) areas,
      // scaled so that they sum to 4 pi R^2; no lattice (reference offsets are not snapped).
      std::vector<Vec3> unit;
      std::vector<std::array<std::int64_t, 3>> tris;
      geodesic_sphere(sphere_frequency(b.radius, b.spacing), unit, tris);
      const double R = b.radius;
      std::vector<double> area(unit.size(), 0.0);
      double total = 0, edges = 0;
      for (const auto& t : tris) {
        const double a = triangle_area(unit[t[0]], unit[t[1]], unit[t[2]]) * R * R;
        for (int k = 0; k < 3; ++k) area[t[k]] += a / 3;
        total += a;
        for (int k = 0; k < 3; ++k) {
          const Vec3 &p = unit[t[k]], &q = unit[t[(k + 1) % 3]];
          edges += R * std::sqrt(std::pow(p[0] - q[0], 2) + std::pow(p[1] - q[1], 2) + std::pow(p[2] - q[2], 2));
        }
      }
      const double scale = 4.0 * 3.14159265358979323846 * R * R / total;
      g.thickness = b.thickness;
      g.quadrature = Quadrature::Full;
      g.center = b.origin;
      g.radius = R;
      g.spacing = edges / (3.0 * static_cast<double>(tris.size()));  // mean edge length
      g.cell_area = 4.0 * 3.14159265358979323846 * R * R / static_cast<double>(unit.size());
      for (std::size_t k = 0; k < unit.size(); ++k)
        push(b.origin[0] + R * unit[k][0], b.origin[1] + R * unit[k][1], b.origin[2] + R * unit[k][2],
             area[k] * scale * b.thickness);
      for (const auto& t : tris) g.triangles.push_back({g.first + t[0], g.first + t[1], g.first + t[2]});
      g.cells = {static_cast<std::int64_t>(unit.size()), 1, 1};
    } else if (b.kind == BodyKind::Fiber) {
      // Nodes at the centres of n equal arc-length steps ds = L/n along each path (eq. 31's
      // ds), each with the measure A ds; no lattice, so reference offsets are not snapped.
      g.area = 0.25 * 3.14159265358979323846 * b.diameter * b.diameter;
      g.segment_length = b.segment_length;
      g.quadrature = Quadrature::Full;
      for (const std::vector<Vec3>& path : fiber_paths(b)) {
        const double length = path_length(path);
        const std::int64_t n = count_along(length, dx);
        const double ds = length / static_cast<double>(n);
        g.path_spacing.push_back(ds);
        std::size_t leg = 1;
        double leg_start = 0;
        double leg_length = distance(path[0], path[1]);
        for (std::int64_t k = 0; k < n; ++k) {
          const double s = (static_cast<double>(k) + 0.5) * ds;
          while (s > leg_start + leg_length && leg + 1 < path.size()) {
            leg_start += leg_length;
            ++leg;
            leg_length = distance(path[leg - 1], path[leg]);
          }
          const double t = std::clamp((s - leg_start) / leg_length, 0.0, 1.0);
          const Vec3& p = path[leg - 1];
          const Vec3& q = path[leg];
          push(p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]), p[2] + t * (q[2] - p[2]), g.area * ds);
        }
        g.path_first.push_back(static_cast<std::int64_t>(nodes.size()) - g.first);
      }
      // One spacing for the body (stable-step and motion checks): the finest path's.
      g.spacing = *std::min_element(g.path_spacing.begin(), g.path_spacing.end());
      g.cells = {g.path_first.back(), 1, 1};
    } else if (b.kind != BodyKind::Solid) {
      g.thickness = b.thickness;
      if (g.grid == Grid::Square) {
        // Cell-centred square grid: node (i, j) sits at the centre of its dx-by-dx cell.
        const std::int64_t nx = count_along(b.size[0], dx), ny = count_along(b.size[1], dx);
        g.cells = {nx, ny, 1};
        g.cell_area = dx * dx;
        for (std::int64_t j = 0; j < ny; ++j)
          for (std::int64_t i = 0; i < nx; ++i)
            push(b.origin[0] + (i + 0.5) * dx, b.origin[1] + (j + 0.5) * dx, b.origin[2],
                 g.cell_area * b.thickness);
      } else {
        // Hexagonal (triangular-lattice) grid: rows dy = dx*sqrt(3)/2 apart, odd rows shifted by
        // dx/2; each node owns a hexagonal cell of area dx*dy.
        const double dy = dx * std::sqrt(3.0) / 2.0;
        const std::int64_t nx = count_along(b.size[0], dx), ny = count_along(b.size[1], dy);
        g.cells = {nx, ny, 1};
        g.cell_area = dx * dy;
        for (std::int64_t j = 0; j < ny; ++j) {
          const double shift = (j % 2) ? 0.75 : 0.25;
          for (std::int64_t i = 0; i < nx; ++i)
            push(b.origin[0] + (i + shift) * dx, b.origin[1] + (j + 0.5) * dy, b.origin[2],
                 g.cell_area * b.thickness);
        }
      }
    } else {
      const std::int64_t nx = count_along(b.size[0], dx), ny = count_along(b.size[1], dx),
                         nz = count_along(b.size[2], dx);
      g.cells = {nx, ny, nz};
      for (std::int64_t k = 0; k < nz; ++k)
        for (std::int64_t j = 0; j < ny; ++j)
          for (std::int64_t i = 0; i < nx; ++i)
            push(b.origin[0] + (i + 0.5) * dx, b.origin[1] + (j + 0.5) * dx,
                 b.origin[2] + (k + 0.5) * dx, dx * dx * dx);
    }
    g.count = nodes.size() - g.first;
    nodes.bodies.push_back(g);
  }
  return nodes;
}

std::vector<std::int64_t> select_nodes(const Nodes& nodes, const Scene& scene,
                                       const Region& region, const std::string& what) {
  int only_body = -1;
  if (!region.body.empty())
    for (std::size_t b = 0; b < scene.bodies.size(); ++b)
      if (scene.bodies[b].name == region.body) only_body = static_cast<int>(b);
  std::vector<std::int64_t> ids;
  for (std::int64_t i = 0; i < nodes.size(); ++i) {
    if (only_body >= 0 && nodes.body[i] != only_body) continue;
    if (region.contains({nodes.X[3 * i], nodes.X[3 * i + 1], nodes.X[3 * i + 2]})) ids.push_back(i);
  }
  if (ids.empty()) {
    std::ostringstream msg;
    msg.precision(6);
    msg << region.where.str() << ": " << what << ": the region [" << region.min[0] << ", "
        << region.min[1] << ", " << region.min[2] << "] .. [" << region.max[0] << ", "
        << region.max[1] << ", " << region.max[2] << "] selects no node"
        << (region.body.empty() ? "" : " of body '" + region.body + "'")
        << "; expected a box containing at least one node";
    throw InputError(msg.str());
  }
  return ids;
}

}  // namespace peri
