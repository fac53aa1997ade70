#include "peri/models/long_range.hpp"

#include "peri/bonds/bonds.hpp"
#include "peri/core/error.hpp"
#include "peri/core/format.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
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

namespace {

/// A run of table nodes of one fiber and one segment, with its reference bounding box.
struct SegmentRun {
  std::int64_t begin, end;
  std::array<double, 3> lo, hi;
};

std::string rule_text(const PairRule& r) {
  switch (r.between) {
    case PairKind::AdjacentSegments: return "adjacent_segments";
    case PairKind::DistantSegments: return "distant_segments";
    case PairKind::OtherFibers: return "other_fibers";
    case PairKind::Segments:
      return "segments [" + std::to_string(r.segments[0]) + ", " + std::to_string(r.segments[1]) + "]";
  }
  return "";
}

}  // namespace

std::vector<std::string> check_pair_rules(const LongRange& spec, const PairLaw& law, const LongRangeTable& table) {
  const double excl2 = law.exclusion > 0 ? law.exclusion * law.exclusion : 0.0;
  std::vector<SegmentRun> runs;
  for (std::int64_t p = 0; p < table.size(); ++p) {
    if (runs.empty() || table.fiber[p] != table.fiber[runs.back().begin] ||
        table.segment[p] != table.segment[runs.back().begin])
      runs.push_back({p, p, {INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}});
    SegmentRun& run = runs.back();
    run.end = p + 1;
    for (int d = 0; d < 3; ++d) {
      run.lo[d] = std::min(run.lo[d], table.X[3 * p + d]);
      run.hi[d] = std::max(run.hi[d], table.X[3 * p + d]);
    }
  }
  auto dist2 = [&](std::int64_t p, std::int64_t q) {
    return std::pow(table.X[3 * q] - table.X[3 * p], 2) + std::pow(table.X[3 * q + 1] - table.X[3 * p + 1], 2) +
           std::pow(table.X[3 * q + 2] - table.X[3 * p + 2], 2);
  };
  // Per rule in effect: 0 applies to no pair, 1 to pairs all excluded, 2 to a pair that may act.
  std::vector<int> seen(static_cast<std::size_t>(law.rules()), 0);
  std::size_t open = 0;  // rules not yet known to act
  for (int k = 0; k < law.rules(); ++k) open += (k >= 3 || law.acts[k]) ? 1 : 0;
  for (std::size_t a = 0; a < runs.size() && open > 0; ++a)
    for (std::size_t b = a + 1; b < runs.size() && open > 0; ++b) {
      const SegmentRun &A = runs[a], &B = runs[b];
      const int rule = law.rule_of(table, A.begin, B.begin);
      if (rule < 0 || seen[static_cast<std::size_t>(rule)] == 2) continue;
      seen[static_cast<std::size_t>(rule)] = 1;
      double far2 = 0;  // the largest distance the two boxes allow
      for (int d = 0; d < 3; ++d) far2 += std::pow(std::max(A.hi[d] - B.lo[d], B.hi[d] - A.lo[d]), 2);
      if (far2 < excl2) continue;
      bool acts = dist2(A.begin, B.end - 1) >= excl2 || dist2(A.end - 1, B.begin) >= excl2 ||
                  dist2(A.begin, B.begin) >= excl2 || dist2(A.end - 1, B.end - 1) >= excl2;
      for (std::int64_t p = A.begin; p < A.end && !acts; ++p)
        for (std::int64_t q = B.begin; q < B.end && !acts; ++q) acts = dist2(p, q) >= excl2;
      if (acts) {
        seen[static_cast<std::size_t>(rule)] = 2;
        --open;
      }
    }
  // The scene's rule behind rule k in effect: the first of its kind, or of its pair of segments.
  auto scene_rule = [&](int k) {
    std::int32_t lo = -1, hi = -1;
    for (const PairLaw::SegmentPair& sp : law.segment_pairs)
      if (sp.rule == k) lo = sp.lo, hi = sp.hi;
    std::size_t r = 0;
    for (; r + 1 < spec.pairs.size(); ++r) {
      const PairRule& pr = spec.pairs[r];
      if (k < 3 ? pr.between == static_cast<PairKind>(k)
                : pr.between == PairKind::Segments && std::min(pr.segments[0], pr.segments[1]) == lo &&
                      std::max(pr.segments[0], pr.segments[1]) == hi)
        break;
    }
    return r;
  };
  auto rule_name = [&](std::size_t r) {
    const PairRule& pr = spec.pairs[r];
    return "long_range.pairs." + std::to_string(r) + " (between: " + rule_text(pr) +
           (pr.where.file.empty() ? "" : ", " + pr.where.str()) + ")";
  };
  for (int k = 0; k < law.rules(); ++k) {
    if (seen[static_cast<std::size_t>(k)] != 1) continue;
    const SourceLoc& at = spec.exclusion_where.file.empty() ? spec.where : spec.exclusion_where;
    std::ostringstream msg;
    msg << at.str() << ": long_range.exclusion: every pair of nodes that " << rule_name(scene_rule(k))
        << " applies to lies closer than the exclusion, " << number_text(law.exclusion) << " m"
        << (spec.exclusion_where.file.empty() ? " (the default: the largest fiber horizon)" : "")
        << ", in the reference configuration, so the rule never acts; expected an exclusion shorter than the "
        << "distance between the nodes it should pull or push (about the fibers' horizon)";
    throw InputError(msg.str());
  }
  // Rules that apply to no pair of the scene's nodes at all: why, from the table's fibers.
  int fibers = 0;
  std::int32_t segments = 0;  // of the fiber with the most
  for (std::int64_t p = 0; p < table.size(); ++p) {
    if (p == 0 || table.fiber[p] != table.fiber[p - 1]) ++fibers;
    segments = std::max(segments, table.segment[p] + 1);
  }
  auto why_none = [&](int k) -> std::string {
    const char* one_segment =
        " (a fiber body's segment_length is 0, the default, or not shorter than its fiber)";
    if (k == static_cast<int>(PairKind::OtherFibers))
      return fibers == 1 ? "the scene has one fiber" : "";
    if (k == static_cast<int>(PairKind::AdjacentSegments) && segments < 2)
      return std::string("each fiber is one segment") + one_segment;
    if (k == static_cast<int>(PairKind::DistantSegments) && segments < 3)
      return std::string(segments < 2 ? "each fiber is one segment" : "no fiber has more than two segments") +
             one_segment;
    return "every such pair of segments has its own segments rule, which comes first";
  };
  std::vector<std::string> warnings, none;
  std::size_t in_effect = 0;
  for (int k = 0; k < law.rules(); ++k) {
    if (!(k >= 3 || law.acts[k])) continue;
    ++in_effect;
    if (seen[static_cast<std::size_t>(k)] != 0) continue;
    none.push_back(rule_name(scene_rule(k)) + " applies to no pair of the scene's fiber nodes: " + why_none(k));
  }
  if (!none.empty() && none.size() == in_effect) {
    std::string msg = spec.where.str() + ": long_range: no rule applies to any pair of nodes, so the section " +
                      "never acts: " + none[0];
    for (std::size_t i = 1; i < none.size(); ++i) msg += "; " + none[i];
    throw InputError(msg + "; expected a rule for the scene's pairs (adjacent_segments and distant_segments " +
                     "need fibers cut into segments by segment_length, other_fibers two fibers)");
  }
  warnings = none;
  // A later rule of a kind, or of a pair of segments, that an earlier one shadows.
  for (std::size_t r = 0; r < spec.pairs.size(); ++r) {
    const PairRule& pr = spec.pairs[r];
    for (std::size_t e = 0; e < r; ++e) {
      const PairRule& pe = spec.pairs[e];
      const bool same = pe.between == pr.between &&
                        (pr.between != PairKind::Segments ||
                         (std::min(pe.segments[0], pe.segments[1]) == std::min(pr.segments[0], pr.segments[1]) &&
                          std::max(pe.segments[0], pe.segments[1]) == std::max(pr.segments[0], pr.segments[1])));
      if (!same) continue;
      warnings.push_back(rule_name(r) + " is never used: " + rule_name(e) +
                         " comes first for the same pairs, and the first rule wins");
      break;
    }
  }
  return warnings;
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
