#include "peri/models/long_range.hpp"

#include "peri/bonds/bonds.hpp"

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
  int fiber = 0;
  for (std::size_t b = 0; b < nodes.bodies.size(); ++b) {
    const BodyGeometry& g = nodes.bodies[b];
    if (!g.traits.long_range) continue;
    for (std::size_t path = 0; path + 1 < g.path_first.size(); ++path, ++fiber)
      for (std::int64_t k = g.path_first[path]; k < g.path_first[path + 1]; ++k) {
        const std::int64_t n = g.first + k;
        t.natural.push_back(n);
        t.fiber.push_back(fiber);
        // The node's arc length along its path: (k' + 1/2) ds (discretize).
        const double s = (static_cast<double>(k - g.path_first[path]) + 0.5) * g.path_spacing[path];
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

double PairLaw::energy(PairKind k, double y) const noexcept { return potential(k).energy(y); }

double PairLaw::force(PairKind k, double y) const noexcept { return potential(k).force(y); }

namespace {

// Pair kind of table nodes p and q, or -1 when they do not interact (one segment).
int pair_kind(const LongRangeTable& t, std::int64_t p, std::int64_t q) {
  if (t.fiber[p] != t.fiber[q]) return static_cast<int>(PairKind::OtherFibers);
  const std::int32_t d = std::abs(t.segment[p] - t.segment[q]);
  if (d == 0) return -1;
  return static_cast<int>(d == 1 ? PairKind::AdjacentSegments : PairKind::DistantSegments);
}

// Rebuilds the list: a cell list on the current positions (cells at least cutoff + skin wide),
// every partner of each node of `mine` within that reach.
void build_list(const PairLaw& law, const LongRangeTable& table, const double* x,
                const std::vector<std::int64_t>& mine, LongRangeList& list) {
  const std::int64_t n = table.size();
  const double reach = law.cutoff + list.skin, reach2 = reach * reach;
  const CellList cells(x, n, reach);
  const double excl2 = law.exclusion * law.exclusion;
  list.begin.assign(1, 0);
  list.partner.clear();
  list.kind.clear();
  for (const std::int64_t p : mine) {
    const double* xp = &x[3 * p];
    const double* Xp = &table.X[3 * p];
    cells.for_each_candidate(xp, [&](std::int64_t q) {
      if (q == p) return;
      const double* xq = &x[3 * q];
      const double y2 = std::pow(xq[0] - xp[0], 2) + std::pow(xq[1] - xp[1], 2) + std::pow(xq[2] - xp[2], 2);
      if (y2 > reach2) return;
      const int kind = pair_kind(table, p, q);
      if (kind < 0 || !law.acts[kind]) return;
      const double* Xq = &table.X[3 * q];
      if (std::pow(Xq[0] - Xp[0], 2) + std::pow(Xq[1] - Xp[1], 2) + std::pow(Xq[2] - Xp[2], 2) < excl2) return;
      list.partner.push_back(q);
      list.kind.push_back(static_cast<std::int8_t>(kind));
    });
    // Partners in ascending table order: the summation order then does not depend on where
    // the nodes stood when the list was built (a run resumed from a checkpoint, whose first
    // list is built later, sums the same pairs in the same order).
    const std::int64_t b = list.begin.back(), e = static_cast<std::int64_t>(list.partner.size());
    std::vector<std::pair<std::int64_t, std::int8_t>> sorted_pairs;
    for (std::int64_t k = b; k < e; ++k) sorted_pairs.push_back({list.partner[k], list.kind[k]});
    std::sort(sorted_pairs.begin(), sorted_pairs.end());
    for (std::int64_t k = b; k < e; ++k) {
      list.partner[k] = sorted_pairs[k - b].first;
      list.kind[k] = sorted_pairs[k - b].second;
    }
    list.begin.push_back(e);
  }
  list.x_built.assign(x, x + 3 * n);
  ++list.builds;
}

}  // namespace

double long_range_forces(const PairLaw& law, const LongRangeTable& table, const double* x,
                         const std::vector<std::int64_t>& mine, double* force, LongRangeList& list,
                         bool with_energy, double* energy_density) {
  const std::int64_t n = table.size();
  if (n == 0 || mine.empty()) return 0.0;
  if (!(list.skin > 0)) list.skin = 0.25 * law.cutoff;
  // Rebuild once some node has moved more than skin/2 (every rank decides alike: same x).
  bool rebuild = list.x_built.size() != static_cast<std::size_t>(3 * n) || list.begin.size() != mine.size() + 1;
  const double half2 = 0.25 * list.skin * list.skin;
  for (std::int64_t p = 0; p < n && !rebuild; ++p)
    rebuild = std::pow(x[3 * p] - list.x_built[3 * p], 2) + std::pow(x[3 * p + 1] - list.x_built[3 * p + 1], 2) +
                  std::pow(x[3 * p + 2] - list.x_built[3 * p + 2], 2) > half2;
  if (rebuild) build_list(law, table, x, mine, list);

  // Per pair one division and no square root: with r2 = a^2 / y^2, w2'(y) / y =
  // (-12 alpha r2^6 + 6 beta r2^3) / y^2 (eq. 35) and w2 = alpha r2^6 - beta r2^3 (eq. 33).
  const double cut2 = law.cutoff * law.cutoff, a2 = law.length * law.length;
  double shift[3], alpha12[3], beta6[3];
  for (int k = 0; k < 3; ++k) {
    shift[k] = law.energy(static_cast<PairKind>(k), law.cutoff);
    alpha12[k] = 12.0 * law.alpha[k];
    beta6[k] = 6.0 * law.beta[k];
  }
  double energy = 0;
  for (std::size_t m = 0; m < mine.size(); ++m) {
    const std::int64_t p = mine[m];
    const double* xp = &x[3 * p];
    double f[3] = {0, 0, 0}, e_p = 0;
    for (std::int64_t e = list.begin[m]; e < list.begin[m + 1]; ++e) {
      const std::int64_t q = list.partner[e];
      const double* xq = &x[3 * q];
      const double d[3] = {xq[0] - xp[0], xq[1] - xp[1], xq[2] - xp[2]};
      const double y2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
      if (y2 > cut2 || !(y2 > 0)) continue;  // coincident nodes: no direction
      const int k = list.kind[e];
      const double inv_y2 = 1.0 / y2, r2 = a2 * inv_y2, r6 = r2 * r2 * r2;
      const double scale = (beta6[k] - alpha12[k] * r6) * r6 * inv_y2 * table.volume[q];
      for (int a = 0; a < 3; ++a) f[a] += scale * d[a];
      if (with_energy) e_p += ((law.alpha[k] * r6 - law.beta[k]) * r6 - shift[k]) * table.volume[q];
    }
    for (int a = 0; a < 3; ++a) force[3 * m + a] += f[a];
    energy += 0.5 * e_p * table.volume[p];
    if (energy_density) energy_density[m] += 0.5 * e_p;
  }
  return energy;
}

}  // namespace peri
