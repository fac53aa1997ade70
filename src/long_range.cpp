#include "peri/long_range.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace peri {

std::int64_t LongRangeTable::index_of(std::int64_t natural_id) const {
  const auto it = std::lower_bound(natural.begin(), natural.end(), natural_id);
  return it != natural.end() && *it == natural_id ? it - natural.begin() : -1;
}

LongRangeTable long_range_table(const Nodes& nodes) {
  LongRangeTable t;
  for (std::size_t b = 0; b < nodes.bodies.size(); ++b) {
    const BodyGeometry& g = nodes.bodies[b];
    if (g.kind != BodyKind::Fiber) continue;
    for (std::int64_t k = 0; k < g.count; ++k) {
      const std::int64_t n = g.first + k;
      t.natural.push_back(n);
      t.body.push_back(static_cast<int>(b));
      // Node k sits at arc length (k + 1/2) ds (discretize).
      const double s = (static_cast<double>(k) + 0.5) * g.spacing;
      t.segment.push_back(g.segment_length > 0 ? static_cast<std::int32_t>(std::floor(s / g.segment_length)) : 0);
      t.X.insert(t.X.end(), {nodes.X[3 * n], nodes.X[3 * n + 1], nodes.X[3 * n + 2]});
      t.volume.push_back(nodes.volume[n]);
    }
  }
  return t;
}

PairLaw::PairLaw(const LongRange& spec)
    : length(spec.length), cutoff(spec.cutoff), exclusion(spec.exclusion) {
  for (const PairRule& r : spec.pairs) {
    const int k = static_cast<int>(r.between);
    if (acts[k]) continue;  // the first rule for a kind wins
    acts[k] = true;
    alpha[k] = r.alpha;
    beta[k] = r.beta;
  }
}

double PairLaw::energy(PairKind k, double y) const noexcept {  // eq. (33)
  const int i = static_cast<int>(k);
  const double r2 = (length / y) * (length / y), r6 = r2 * r2 * r2;
  return alpha[i] * r6 * r6 - beta[i] * r6;
}

double PairLaw::force(PairKind k, double y) const noexcept {  // eq. (35), second term
  const int i = static_cast<int>(k);
  const double r = length / y, r2 = r * r, r6 = r2 * r2 * r2;
  return (-12.0 * alpha[i] * r6 * r6 + 6.0 * beta[i] * r6) * r / length;
}

namespace {

// Pair kind of table nodes p and q, or -1 when they do not interact (one segment).
int pair_kind(const LongRangeTable& t, std::int64_t p, std::int64_t q) {
  if (t.body[p] != t.body[q]) return static_cast<int>(PairKind::OtherFibers);
  const std::int32_t d = std::abs(t.segment[p] - t.segment[q]);
  if (d == 0) return -1;
  return static_cast<int>(d == 1 ? PairKind::AdjacentSegments : PairKind::DistantSegments);
}

}  // namespace

double long_range_forces(const PairLaw& law, const LongRangeTable& table, const double* x,
                         const std::vector<std::int64_t>& mine, double* force, bool with_energy) {
  const std::int64_t n = table.size();
  if (n == 0 || mine.empty()) return 0.0;
  // Cell list on the current positions, cells at least the cutoff wide (at most ~4n of them).
  std::array<double, 3> lo{}, hi{};
  for (int c = 0; c < 3; ++c) lo[c] = hi[c] = x[c];
  for (std::int64_t p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min(lo[c], x[3 * p + c]);
      hi[c] = std::max(hi[c], x[3 * p + c]);
    }
  double size = law.cutoff;
  std::array<std::int64_t, 3> dims{};
  for (;;) {
    double total = 1;
    for (int c = 0; c < 3; ++c) {
      dims[c] = static_cast<std::int64_t>(std::floor((hi[c] - lo[c]) / size)) + 1;
      total *= static_cast<double>(dims[c]);
    }
    if (total <= 4.0 * static_cast<double>(n) + 64) break;
    size *= 1.5;
  }
  auto cell_of = [&](const double* xp, int c) {
    return std::clamp<std::int64_t>(static_cast<std::int64_t>((xp[c] - lo[c]) / size), 0, dims[c] - 1);
  };
  thread_local std::vector<std::int64_t> start, sorted, cell, fill;
  start.assign(static_cast<std::size_t>(dims[0] * dims[1] * dims[2] + 1), 0);
  cell.resize(n);
  for (std::int64_t p = 0; p < n; ++p) {
    const double* xp = &x[3 * p];
    cell[p] = (cell_of(xp, 2) * dims[1] + cell_of(xp, 1)) * dims[0] + cell_of(xp, 0);
    ++start[cell[p] + 1];
  }
  for (std::size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
  sorted.resize(n);
  fill.assign(start.begin(), start.end() - 1);
  for (std::int64_t p = 0; p < n; ++p) sorted[fill[cell[p]]++] = p;

  const double cut2 = law.cutoff * law.cutoff, excl2 = law.exclusion * law.exclusion;
  double shift[3];
  for (int k = 0; k < 3; ++k) shift[k] = law.energy(static_cast<PairKind>(k), law.cutoff);
  double energy = 0;
  for (std::size_t m = 0; m < mine.size(); ++m) {
    const std::int64_t p = mine[m];
    const double* xp = &x[3 * p];
    const double* Xp = &table.X[3 * p];
    const std::int64_t ci[3] = {cell_of(xp, 0), cell_of(xp, 1), cell_of(xp, 2)};
    double f[3] = {0, 0, 0};
    for (std::int64_t k = std::max<std::int64_t>(ci[2] - 1, 0); k <= std::min(ci[2] + 1, dims[2] - 1); ++k)
      for (std::int64_t j = std::max<std::int64_t>(ci[1] - 1, 0); j <= std::min(ci[1] + 1, dims[1] - 1); ++j)
        for (std::int64_t i = std::max<std::int64_t>(ci[0] - 1, 0); i <= std::min(ci[0] + 1, dims[0] - 1); ++i) {
          const std::int64_t c = (k * dims[1] + j) * dims[0] + i;
          for (std::int64_t s = start[c]; s < start[c + 1]; ++s) {
            const std::int64_t q = sorted[s];
            const double* xq = &x[3 * q];
            const double d[3] = {xq[0] - xp[0], xq[1] - xp[1], xq[2] - xp[2]};
            const double y2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if (y2 > cut2 || q == p) continue;
            const int kind = pair_kind(table, p, q);
            if (kind < 0 || !law.acts[kind]) continue;
            if (!(y2 > 0)) continue;  // coincident nodes: no direction (the repulsion keeps them apart)
            const double* Xq = &table.X[3 * q];
            const double e[3] = {Xq[0] - Xp[0], Xq[1] - Xp[1], Xq[2] - Xp[2]};
            if (e[0] * e[0] + e[1] * e[1] + e[2] * e[2] < excl2) continue;
            const double y = std::sqrt(y2);
            const PairKind pk = static_cast<PairKind>(kind);
            const double scale = law.force(pk, y) / y * table.volume[q];
            for (int a = 0; a < 3; ++a) f[a] += scale * d[a];
            if (with_energy) energy += 0.5 * (law.energy(pk, y) - shift[kind]) * table.volume[p] * table.volume[q];
          }
        }
    for (int a = 0; a < 3; ++a) force[3 * m + a] += f[a];
  }
  return energy;
}

}  // namespace peri
