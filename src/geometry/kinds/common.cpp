#include "common.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace peri::kinds {

using scene_detail::format_number;
using scene_detail::join;

void read_horizon(const Map& m, Body& b) {
  if (auto x = m.get("horizon_factor")) {
    b.horizon_factor = x->number("a number >= 1");
    if (!(b.horizon_factor >= 1))
      x->fail("horizon must be at least one spacing (expected >= 1), got " + x->got());
  }
  if (auto x = m.get("horizon")) {
    if (m.given("horizon_factor")) x->fail("give either horizon [m] or horizon_factor, not both");
    const double h = x->number("a number [m]");
    if (!(h >= b.spacing))
      x->fail("horizon must be at least one spacing (expected >= " + format_number(b.spacing) + " m), got " +
              x->got());
    b.horizon = h;
  }
}

void emit_horizon(Writer& w, const Body& b) {
  if (b.horizon)
    w.key(4, "horizon", *b.horizon);
  else
    w.key(4, "horizon_factor", b.horizon_factor);
}

double grid_family(const Body& b, int dimension) {
  const double m = b.horizon_value() / b.spacing + 0.71;
  return dimension == 3 ? 4.18879 * m * m * m : 3.14159 * m * m;
}

void read_sheet_extent(const Map& m, Body& b) {
  b.origin = m.at("origin").vec3("m");
  const Value size = m.at("size");
  const std::string expected = "a membrane size [Lx, Ly] (or [Lx, Ly, 0]) with Lx, Ly > 0 [m]";
  const auto xs = size.numbers(2, 3, expected, "m");
  if (!(xs[0] > 0 && xs[1] > 0) || (xs.size() == 3 && xs[2] != 0))
    size.fail("expected " + expected + ", got [" + join({format_number(xs[0]), format_number(xs[1])}) +
              (xs.size() == 3 ? ", " + format_number(xs[2]) : "") + "]");
  b.size = {xs[0], xs[1], 0.0};
  b.thickness = m.at("thickness").positive("m");
  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  const double smallest = std::min(b.size[0], b.size[1]);
  if (b.spacing > smallest)
    spacing.fail("spacing must not exceed the smallest extent of size (" + format_number(smallest) +
                 " m), got " + spacing.got());
}

std::int64_t count_along(double length, double dx) { return std::max<std::int64_t>(1, std::llround(length / dx)); }

namespace {

// The grid sheet's cell centres, rows along x, through the cutouts' filter.
void grid_sheet_raster(const Body& b, BodyGeometry& g, CutSink& sink) {
  const double dx = b.spacing;
  g.thickness = b.thickness;
  if (g.grid == Grid::Square) {
    // Cell-centred square grid: node (i, j) sits at the centre of its dx-by-dx cell.
    const std::int64_t nx = count_along(b.size[0], dx), ny = count_along(b.size[1], dx);
    g.cells = {nx, ny, 1};
    g.cell_area = dx * dx;
    for (std::int64_t j = 0; j < ny; ++j)
      for (std::int64_t i = 0; i < nx; ++i)
        sink.add(b.origin[0] + (i + 0.5) * dx, b.origin[1] + (j + 0.5) * dx, b.origin[2], g.cell_area * b.thickness);
    return;
  }
  // Hexagonal (triangular-lattice) grid: rows dy = dx*sqrt(3)/2 apart, odd rows shifted by dx/2;
  // each node owns a hexagonal cell of area dx*dy.
  const double dy = dx * std::sqrt(3.0) / 2.0;
  const std::int64_t nx = count_along(b.size[0], dx), ny = count_along(b.size[1], dy);
  g.cells = {nx, ny, 1};
  g.cell_area = dx * dy;
  for (std::int64_t j = 0; j < ny; ++j) {
    const double shift = (j % 2) ? 0.75 : 0.25;
    for (std::int64_t i = 0; i < nx; ++i)
      sink.add(b.origin[0] + (i + shift) * dx, b.origin[1] + (j + 0.5) * dy, b.origin[2], g.cell_area * b.thickness);
  }
}

}  // namespace

void grid_sheet_nodes(const Body& b, BodyGeometry& g, NodeSink& all) {
  CutSink sink(b, all);
  grid_sheet_raster(b, g, sink);
  sink.finish();
}

double grid_sheet_count(const Body& b) {
  double n = 1;
  for (int d = 0; d < 2; ++d) n *= std::max(1.0, std::round(b.size[d] / b.spacing));
  return b.grid == Grid::Hexagonal ? n * (2.0 / std::sqrt(3.0)) : n;
}

std::pair<std::size_t, std::size_t> first_close_pair(const std::vector<Vec3>& x, double cell, double tol) {
  const std::size_t n = x.size();
  for (const Vec3& p : x)
    for (double c : p)
      if (!(std::fabs(c / cell) < 1e15)) return {n, n};  // cells beyond an integer's reach
  struct CellHash {
    std::size_t operator()(const std::array<std::int64_t, 3>& c) const {
      return static_cast<std::size_t>(c[0] * 73856093 ^ c[1] * 19349663 ^ c[2] * 83492791);
    }
  };
  std::unordered_map<std::array<std::int64_t, 3>, std::vector<std::size_t>, CellHash> grid;
  grid.reserve(n);
  auto cell_of = [&](const Vec3& p) {
    return std::array<std::int64_t, 3>{static_cast<std::int64_t>(std::floor(p[0] / cell)),
                                       static_cast<std::int64_t>(std::floor(p[1] / cell)),
                                       static_cast<std::int64_t>(std::floor(p[2] / cell))};
  };
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& p = x[i];
    const auto c = cell_of(p);
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = grid.find({c[0] + dx, c[1] + dy, c[2] + dz});
          if (it == grid.end()) continue;
          for (std::size_t j : it->second) {
            const double d[3] = {p[0] - x[j][0], p[1] - x[j][1], p[2] - x[j][2]};
            if (std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) <= tol) return {i, j};
          }
        }
    grid[c].push_back(i);
  }
  return {n, n};
}

std::string key_text(const Body& b, const char* key, double value) {
  return "bodies." + b.name + "." + key + " " + number_text(value) + " m";
}

}  // namespace peri::kinds
