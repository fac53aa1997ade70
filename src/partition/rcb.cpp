// Recursive coordinate bisection (partition.hpp): the partitioner `auto` takes for one square-grid
// body that fills its box, with each node weighed by its bond count from the grid alone.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

#include "peri/bonds/bonds.hpp"
#include "peri/partition/partition.hpp"

namespace peri {

bool fills_its_box(const Nodes& nodes) {
  if (nodes.bodies.size() != 1) return false;
  const BodyGeometry& g = nodes.bodies[0];
  return g.traits.grid && g.grid == Grid::Square && g.count == nodes.size() && g.count == g.cells[0] * g.cells[1] * g.cells[2];
}

// Every grid offset o with a quadrature weight counts at the nodes n with n + o in the box, a box
// of nodes, added by a 3D difference array and prefix sums (O(N + offsets), no neighbour search).
std::vector<std::int32_t> grid_bond_counts(const Nodes& nodes) {
  const BodyGeometry& g = nodes.bodies[0];
  const std::int64_t nx = g.cells[0], ny = g.cells[1], nz = g.cells[2];
  std::int64_t m[3];
  for (int d = 0; d < 3; ++d)
    m[d] = std::min<std::int64_t>(g.cells[d] - 1, static_cast<std::int64_t>(std::ceil(reach(g) / g.spacing)));
  const std::int64_t sx = nx + 1, sy = ny + 1;
  std::vector<std::int32_t> diff(static_cast<std::size_t>(sx * sy * (nz + 1)), 0);
  for (std::int64_t k = -m[2]; k <= m[2]; ++k)
    for (std::int64_t j = -m[1]; j <= m[1]; ++j)
      for (std::int64_t i = -m[0]; i <= m[0]; ++i) {
        const double d[3] = {static_cast<double>(i) * g.spacing, static_cast<double>(j) * g.spacing,
                             static_cast<double>(k) * g.spacing};
        if ((i == 0 && j == 0 && k == 0) || !(quadrature_weight(g, d) > 0)) continue;
        // Nodes [a, b) along each axis keep n + o inside.
        const std::int64_t a[3] = {std::max<std::int64_t>(0, -i), std::max<std::int64_t>(0, -j), std::max<std::int64_t>(0, -k)};
        const std::int64_t b[3] = {std::min(nx, nx - i), std::min(ny, ny - j), std::min(nz, nz - k)};
        for (int c = 0; c < 8; ++c) {
          const std::int64_t x = c & 1 ? b[0] : a[0], y = c & 2 ? b[1] : a[1], z = c & 4 ? b[2] : a[2];
          diff[static_cast<std::size_t>(x + sx * (y + sy * z))] += __builtin_popcount(c) % 2 ? -1 : 1;
        }
      }
  for (std::int64_t z = 0; z <= nz; ++z)  // prefix sums along x, then y, then z
    for (std::int64_t y = 0; y <= ny; ++y)
      for (std::int64_t x = 1; x <= nx; ++x) diff[x + sx * (y + sy * z)] += diff[x - 1 + sx * (y + sy * z)];
  for (std::int64_t z = 0; z <= nz; ++z)
    for (std::int64_t y = 1; y <= ny; ++y)
      for (std::int64_t x = 0; x <= nx; ++x) diff[x + sx * (y + sy * z)] += diff[x + sx * (y - 1 + sy * z)];
  for (std::int64_t z = 1; z <= nz; ++z)
    for (std::int64_t y = 0; y <= ny; ++y)
      for (std::int64_t x = 0; x <= nx; ++x) diff[x + sx * (y + sy * z)] += diff[x + sx * (y + sy * (z - 1))];
  std::vector<std::int32_t> count(static_cast<std::size_t>(nodes.size()));
  for (std::int64_t z = 0; z < nz; ++z)
    for (std::int64_t y = 0; y < ny; ++y)
      for (std::int64_t x = 0; x < nx; ++x) count[x + nx * (y + ny * z)] = diff[x + sx * (y + sy * z)];
  return count;
}

PartitionMethod resolve_partition_method(PartitionMethod method, const Nodes& nodes) {
  if (method != PartitionMethod::Auto) return method;
  return fills_its_box(nodes) ? PartitionMethod::Rcb : PartitionMethod::Cells;
}

std::vector<int> rcb_parts(const Nodes& nodes, int parts, int line_weight) {
  const std::int64_t n = nodes.size();
  std::vector<int> part(static_cast<std::size_t>(n), 0);
  if (parts <= 1 || n == 0) return part;
  const double* X = nodes.X.data();
  // The work of a node: its bond count where the grid gives it for free, else 1.
  const std::vector<std::int32_t> bonds = fills_its_box(nodes) ? grid_bond_counts(nodes) : std::vector<std::int32_t>{};
  auto weight = [&](std::int32_t i) { return bonds.empty() ? 1.0 : 1.0 + bonds[i]; };
  std::vector<std::int32_t> order(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), 0);
  struct Range {
    std::int64_t begin, end;
    int first_part, parts;
  };
  std::vector<Range> todo{{0, n, 0, parts}};
  while (!todo.empty()) {
    const Range r = todo.back();
    todo.pop_back();
    if (r.parts == 1 || r.end - r.begin <= 1) {
      for (std::int64_t k = r.begin; k < r.end; ++k) part[order[k]] = r.first_part;
      continue;
    }
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (std::int64_t k = r.begin; k < r.end; ++k)
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::min(lo[d], X[3 * order[k] + d]);
        hi[d] = std::max(hi[d], X[3 * order[k] + d]);
      }
    // The axis to cut: the longest extent, x's divided by the line weight (a cut across x splits
    // the grid lines); ties go to z, then y (a part then stays a range of the natural order).
    const double extent[3] = {(hi[0] - lo[0]) / line_weight, hi[1] - lo[1], hi[2] - lo[2]};
    const int axis = extent[2] >= extent[1] && extent[2] >= extent[0] ? 2 : extent[1] >= extent[0] ? 1 : 0;
    // Sorted by (axis, the other cross axis, the line's axis, natural id): a grid line along x
    // (along y if x is cut) is a consecutive range.
    const int other = axis == 2 ? 1 : 2, along = axis == 0 ? 1 : 0;
    auto key = [&](std::int32_t i) { return std::make_tuple(X[3 * i + axis], X[3 * i + other], X[3 * i + along], i); };
    std::sort(order.begin() + r.begin, order.begin() + r.end,
              [&](std::int32_t a, std::int32_t b) { return key(a) < key(b); });
    const int left_parts = r.parts / 2;
    double total = 0;
    for (std::int64_t k = r.begin; k < r.end; ++k) total += weight(order[k]);
    // The first node past the left parts' share of the weight.
    const double share = total * left_parts / r.parts;
    std::int64_t split = r.begin;
    for (double sum = 0; split < r.end - 1 && sum + 0.5 * weight(order[split]) < share; ++split) sum += weight(order[split]);
    auto same_line = [&](std::int64_t a, std::int64_t b) {
      return X[3 * order[a] + axis] == X[3 * order[b] + axis] && X[3 * order[a] + other] == X[3 * order[b] + other];
    };
    if (split > r.begin && same_line(split - 1, split)) {
      // The nearer end (by weight) of the line it falls in, if that moves at most 0.5% of the
      // left parts' weight (a small part splits its lines rather than its balance).
      std::int64_t a = split, b = split;
      double back = 0, ahead = 0;
      while (a > r.begin && same_line(a - 1, split)) back += weight(order[--a]);
      while (b < r.end && same_line(b, split)) ahead += weight(order[b++]);
      const bool to_a = a > r.begin && (back <= ahead || b == r.end);
      const bool to_b = !to_a && b < r.end;
      if (to_a && back <= 0.005 * share) split = a;
      else if (to_b && ahead <= 0.005 * share) split = b;
    }
    // At least a node per part on either side (a part without nodes would leave a rank idle).
    split = std::clamp(split, r.begin + left_parts, r.end - (r.parts - left_parts));
    todo.push_back({r.begin, split, r.first_part, left_parts});
    todo.push_back({split, r.end, r.first_part + left_parts, r.parts - left_parts});
  }
  return part;
}

}  // namespace peri
