// Body kind `sphere` (example 7.2): a spherical membrane on a geodesic grid (the icosahedron's
// faces split into n^2 triangles, projected onto the sphere), measure area x thickness, full
// weights within the horizon; its triangles carry an internal follower pressure.
#include <algorithm>
#include <cmath>
#include <map>

#include "common.hpp"
#include "kinds.hpp"

namespace peri::kinds {
namespace {

using scene_detail::format_number;

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

void read(const Map& m, Body& b, const Material&) {
  b.origin = m.at("center").vec3("m");
  b.radius = m.at("radius").positive("m");
  b.thickness = m.at("thickness").positive("m");
  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  if (b.spacing > b.radius)
    spacing.fail("spacing must not exceed the radius (" + format_number(b.radius) + " m), got " + spacing.got());
  read_horizon(m, b);
  if (auto x = m.get("pressure")) b.pressure = x->non_negative("Pa");
  if (auto x = m.get("pressure_ramp_time")) b.pressure_ramp_time = x->non_negative("s");
  b.quadrature = Quadrature::Full;
}

void emit(Writer& w, const Body& b) {
  w.key(4, "center", scene_detail::flow(b.origin));
  w.key(4, "radius", b.radius);
  w.key(4, "thickness", b.thickness);
  w.key(4, "spacing", b.spacing);
  emit_horizon(w, b);
  w.key(4, "pressure", b.pressure);
  w.key(4, "pressure_ramp_time", b.pressure_ramp_time);
}

// Geodesic nodes on the sphere; a node's area is a third of its triangles' (flat) areas, scaled
// so that they sum to 4 pi R^2; no grid (reference offsets are not snapped).
void discretize(const Body& b, BodyGeometry& g, NodeSink& sink) {
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
    sink.add(b.origin[0] + R * unit[k][0], b.origin[1] + R * unit[k][1], b.origin[2] + R * unit[k][2],
             area[k] * scale * b.thickness);
  for (const auto& t : tris) g.triangles.push_back({g.first + t[0], g.first + t[1], g.first + t[2]});
  g.cells = {static_cast<std::int64_t>(unit.size()), 1, 1};
}

}  // namespace

BodyKind sphere_kind() {
  BodyKind k;
  k.name = "sphere";
  k.summary = "geodesic nodes on a sphere, full weights within the horizon";
  k.traits = {.dimension = 2, .grid = false, .irregular = true};  // (families differ node to node)
  k.keys = {
      {.name = "center", .required = true, .what = "center of the sphere [x, y, z], m", .unit = "m",
       .doc = "the centre [x, y, z]"},
      {.name = "radius", .required = true, .what = "radius of the sphere, m", .unit = "m",
       .doc = "R > 0; n = round(1.107 R / spacing) splits each icosahedron face into n^2 triangles, 10 n^2 + 2 "
              "nodes; a node's area is a third of its triangles', scaled to 4 pi R^2 in all"},
      {.name = "thickness", .required = true, .what = "membrane thickness, m", .unit = "m",
       .doc = "h > 0; a node's measure is its area times h"},
      {.name = "spacing", .required = true, .what = "node spacing on the sphere, m", .unit = "m",
       .doc = "> 0, at most the radius: the geodesic grid's edges are about this long"},
      kHorizonFactorKey,
      kHorizonKey,
      {.name = "pressure", .unit = "Pa", .fallback = "0",
       .doc = "internal pressure p >= 0, a follower load (each geodesic triangle carries p times its current area "
              "vector, a third to each corner whose bonds to the other two are intact); its work is external work; "
              "wall stress p R / (2 h) at most 100 in-plane bulk moduli; in quasistatic stages p steps with the load factor, its stiffness in the tangent"},
      {.name = "pressure_ramp_time", .unit = "s", .fallback = "0",
       .doc = "the pressure rises linearly from 0 over this time, >= 0"},
  };
  k.read = read;
  k.emit = emit;
  k.measure_keys = [](const Body& b) {
    return key_text(b, "spacing", b.spacing) + ", " + key_text(b, "thickness", b.thickness);
  };
  k.node_estimate = [](const Body& b) {
    return 10.0 * std::pow(static_cast<double>(sphere_frequency(b.radius, b.spacing)), 2) + 2;
  };
  k.family_estimate = [](const Body& b) { return grid_family(b, 2); };
  k.discretize = discretize;
  return k;
}

}  // namespace peri::kinds

namespace peri {

std::int64_t sphere_frequency(double radius, double spacing) {
  // The icosahedron's edge subtends 1.1071 rad; its n-fold subdivision, about 1.1071 R / n.
  const double n = 1.1071487177940904 * radius / spacing;  // beyond 1e9: refused by the size check
  return std::max<std::int64_t>(1, std::llround(std::min(n, 1e9)));
}

}  // namespace peri
