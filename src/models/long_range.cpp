#include "peri/models/long_range.hpp"

#include "peri/bonds/bonds.hpp"
#include "peri/core/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <type_traits>

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

std::vector<PairContactStep> pair_contact_steps(const Scene& scene) {
  std::vector<PairContactStep> steps;
  if (!scene.long_range) return steps;
  const LongRange& spec = *scene.long_range;
  for (std::size_t r = 0; r < spec.pairs.size(); ++r) {
    const PairRule& rule = spec.pairs[r];
    if (!(rule.alpha > 0 && rule.beta > 0)) continue;  // no well: repulsive only
    const LennardJonesPair pot{rule.alpha, rule.beta, spec.length};
    const double ratio = std::pow(rule.alpha / rule.beta, 1.0 / 6.0), cut = rule.cutoff_or(spec.cutoff);
    const double sigma = spec.length * ratio, bottom = sigma * std::pow(2.0, 1.0 / 6.0);
    if (!(bottom < cut)) continue;  // the well lies beyond the cutoff: pairs within it repel
    PairContactStep best{static_cast<int>(r), sigma, INFINITY, ""};
    for (const Body& b : scene.bodies) {
      if (!b.kind->traits.long_range || !(b.spacing > 0) || !(b.diameter > 0)) continue;
      const double ds = b.spacing, volume = 0.25 * M_PI * b.diameter * b.diameter * ds;
      double sum = 0;
      // Partners farther out than the potential's inflection soften the node (k < 0), and k only
      // falls with y: the sum stops there (and after 10^5 partners a side, a fiber far finer than
      // the potential's length, where the estimate is low).
      for (long k = 0; k <= 100000; ++k) {
        const double y = std::hypot(sigma, static_cast<double>(k) * ds), stiffness = pot.stiffness(y);
        if (y > cut || !(stiffness > 0)) break;
        sum += (k == 0 ? 1.0 : 2.0) * stiffness * volume;
      }
      if (!(sum > 0)) continue;
      const double dt = std::sqrt(2.0 * scene.material(b.material).density / sum);
      if (dt < best.dt) best = {static_cast<int>(r), sigma, dt, b.name};
    }
    if (std::isfinite(best.dt)) steps.push_back(best);
  }
  return steps;
}

PairLaw::PairLaw(const LongRange& spec)
    : length(spec.length), cutoff(spec.cutoff), exclusion(spec.exclusion) {
  potentials.assign(3, LennardJonesPair{0, 0, length});
  cutoffs.assign(3, cutoff);
  for (const PairRule& r : spec.pairs) {
    if (r.between == PairKind::Segments) {
      const std::int32_t lo = std::min(r.segments[0], r.segments[1]), hi = std::max(r.segments[0], r.segments[1]);
      const bool taken = std::any_of(segment_pairs.begin(), segment_pairs.end(),
                                     [&](const SegmentPair& s) { return s.lo == lo && s.hi == hi; });
      if (taken) continue;  // the first rule for a pair of segments wins
      segment_pairs.push_back({lo, hi, rules()});
      potentials.push_back({r.alpha, r.beta, length});
      cutoffs.push_back(r.cutoff_or(cutoff));
      continue;
    }
    const int k = static_cast<int>(r.between);
    if (acts[k]) continue;  // the first rule for a kind wins
    acts[k] = true;
    potentials[k] = {r.alpha, r.beta, length};
    cutoffs[k] = r.cutoff_or(cutoff);
  }
  std::sort(segment_pairs.begin(), segment_pairs.end(), [](const SegmentPair& a, const SegmentPair& b) {
    return a.lo != b.lo ? a.lo < b.lo : a.hi < b.hi;
  });
  for (int k = 0; k < rules(); ++k)
    if (k >= 3 || acts[k]) reach = std::max(reach, cutoffs[k]);
}

double PairLaw::energy(PairKind k, double y) const noexcept { return potential(k).energy(y); }

double PairLaw::force(PairKind k, double y) const noexcept { return potential(k).force(y); }

int PairLaw::rule_of(const LongRangeTable& t, std::int64_t p, std::int64_t q) const {
  constexpr int other = static_cast<int>(PairKind::OtherFibers);
  if (t.fiber[p] != t.fiber[q]) return acts[other] ? other : -1;
  const std::int32_t a = t.segment[p], b = t.segment[q];
  if (a == b) return -1;
  if (!segment_pairs.empty()) {  // a rule naming these two segments comes first
    const std::int32_t lo = std::min(a, b), hi = std::max(a, b);
    const auto it = std::lower_bound(segment_pairs.begin(), segment_pairs.end(), SegmentPair{lo, hi, 0},
                                     [](const SegmentPair& x, const SegmentPair& y) {
                                       return x.lo != y.lo ? x.lo < y.lo : x.hi < y.hi;
                                     });
    if (it != segment_pairs.end() && it->lo == lo && it->hi == hi) return it->rule;
  }
  const int k = static_cast<int>(std::abs(a - b) == 1 ? PairKind::AdjacentSegments : PairKind::DistantSegments);
  return acts[k] ? k : -1;
}

std::vector<PairLaw::Coefficients> PairLaw::coefficients() const {
  std::vector<Coefficients> c(potentials.size());
  for (int k = 0; k < rules(); ++k) {
    const LennardJonesPair& w = potentials[k];
    c[k] = {w.alpha, w.beta, 12.0 * w.alpha, 6.0 * w.beta, cutoffs[k] * cutoffs[k], w.energy(cutoffs[k])};
  }
  return c;
}

void check_segment_rules(const LongRange& spec, const LongRangeTable& table) {
  std::int32_t count = 0;  // segments of the scene's longest fiber (in segments)
  int fibers = 0;
  for (std::int64_t p = 0; p < table.size(); ++p) {
    count = std::max(count, table.segment[p] + 1);
    fibers = std::max(fibers, table.fiber[p] + 1);
  }
  for (const PairRule& r : spec.pairs) {
    if (r.between != PairKind::Segments || std::max(r.segments[0], r.segments[1]) < count) continue;
    std::string why = r.segments_where.str() + ": " + r.segments_key + ": expected segment indices 0 to " +
                      std::to_string(count - 1) + " (";
    if (count == 1)
      why += fibers == 1 ? "the fiber is one segment" : "each of the scene's fibers is one segment";
    else
      why += (fibers == 1 ? "the fiber has " : "the longest of the scene's " + std::to_string(fibers) + " fibers has ") +
             std::to_string(count) + " segments";
    why += std::string(count == 1 ? ": segment_length 0 or longer than the fiber" : "") + "), got [" +
           std::to_string(r.segments[0]) + ", " + std::to_string(r.segments[1]) + "]";
    throw InputError(why);
  }
}

bool LongRangeList::stale(const double* x, std::int64_t count) const {
  if (builds == 0 || x_built.size() != static_cast<std::size_t>(3 * count)) return true;
  const double half2 = 0.25 * skin * skin;
  for (std::int64_t p = 0; p < count; ++p)
    if (std::pow(x[3 * p] - x_built[3 * p], 2) + std::pow(x[3 * p + 1] - x_built[3 * p + 1], 2) +
            std::pow(x[3 * p + 2] - x_built[3 * p + 2], 2) >
        half2)
      return true;
  return false;
}

void build_long_range_list(const PairLaw& law, const LongRangeTable& table, const PairNodes& nodes,
                           const std::int64_t* rows, std::int64_t row_count, LongRangeList& list) {
  if (nodes.count > std::numeric_limits<std::int32_t>::max() / 3)  // (the pair sums index 3 q in 32 bits)
    throw RuntimeFailure("long-range pairs: more than 2^31 / 3 nodes seen by one rank");
  const double* x = nodes.x;
  const double reach = law.reach + list.skin, reach2 = reach * reach;
  std::vector<double> rule_reach2(law.rules());
  for (int r = 0; r < law.rules(); ++r) rule_reach2[r] = (law.cutoffs[r] + list.skin) * (law.cutoffs[r] + list.skin);
  const CellList cells(x, nodes.count, reach);  // cells at least the largest cutoff + skin wide
  const double excl2 = law.exclusion * law.exclusion;
  list.begin.assign(1, 0);
  list.partner.clear();
  list.rule.clear();
  std::vector<std::pair<std::int64_t, std::int32_t>> found;  // (table index, node) of one row
  std::vector<std::uint16_t> found_rule;
  for (std::int64_t r = 0; r < row_count; ++r) {
    const std::int64_t i = rows[r], p = nodes.table_index(i);
    const double* xp = &x[3 * i];
    const double* Xp = &table.X[3 * p];
    found.clear();
    cells.for_each_candidate(xp, [&](std::int64_t j) {
      const std::int64_t q = nodes.table_index(j);
      if (q == p) return;
      const double* xq = &x[3 * j];
      const double y2 = std::pow(xq[0] - xp[0], 2) + std::pow(xq[1] - xp[1], 2) + std::pow(xq[2] - xp[2], 2);
      if (y2 > reach2) return;
      const int rule = law.rule_of(table, p, q);
      if (rule < 0 || y2 > rule_reach2[rule]) return;
      const double* Xq = &table.X[3 * q];
      if (std::pow(Xq[0] - Xp[0], 2) + std::pow(Xq[1] - Xp[1], 2) + std::pow(Xq[2] - Xp[2], 2) < excl2) return;
      found.push_back({q, static_cast<std::int32_t>(j)});
      found_rule.push_back(static_cast<std::uint16_t>(rule));
    });
    // Partners in ascending table order: the summation order then depends neither on where the
    // nodes stood when the list was built (a run resumed from a checkpoint, whose first list is
    // built later, sums the same pairs in the same order) nor on which rank sees them, or where.
    std::vector<std::size_t> order(found.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return found[a].first < found[b].first; });
    for (const std::size_t k : order) {
      list.partner.push_back(found[k].second);
      list.rule.push_back(found_rule[k]);
    }
    found_rule.clear();
    list.begin.push_back(static_cast<std::int64_t>(list.partner.size()));
  }
  list.partner.insert(list.partner.end(), LongRangeList::kPad, 0);  // the pair sums' whole lanes
  list.rule.insert(list.rule.end(), LongRangeList::kPad, 0);
  list.shared_rule = list.begin.back() == 0 ? -1 : list.rule.front();
  for (std::int64_t e = 0; e < list.begin.back(); ++e)
    if (list.rule[e] != list.shared_rule) {
      list.shared_rule = -1;
      break;
    }
  list.x_built.assign(x, x + 3 * nodes.count);
  ++list.builds;
}

double long_range_forces(const PairLaw& law, const LongRangeTable& table, const double* x,
                         const std::vector<std::int64_t>& mine, double* force, LongRangeList& list,
                         bool with_energy, double* energy_density) {
  const std::int64_t n = table.size();
  if (n == 0 || mine.empty()) return 0.0;
  list.set_skin(law);
  const PairNodes nodes{nullptr, x, table.volume.data(), n};
  const std::int64_t rows = static_cast<std::int64_t>(mine.size());
  if (list.stale(x, n) || list.begin.size() != mine.size() + 1)
    build_long_range_list(law, table, nodes, mine.data(), rows, list);
  return long_range_pair_forces(law, nodes, mine.data(), rows, force, list, with_energy, energy_density);
}

}  // namespace peri
