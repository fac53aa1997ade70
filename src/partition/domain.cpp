#include "peri/partition/domain.hpp"

#include <algorithm>
#include <unordered_map>

#include "peri/bonds/crack_index.hpp"
#include "peri/bonds/crossing.hpp"

namespace peri {

Domain build_domain(const Scene& scene, const Nodes& nodes, const CellList& cells,
                    const Partition& partition, int rank, const std::function<bool()>& stop) {
  // Rows between polls of `stop`: a stopped build returns at once, unfinished.
  constexpr std::int64_t kPollRows = 4096;
  Domain d;
  d.rank = rank;
  d.ranks = partition.parts;
  d.global_nodes = nodes.size();
  d.global_begin = partition.part_begin[rank];
  const std::int64_t end = partition.part_begin[rank + 1];
  d.owned = static_cast<std::int32_t>(end - d.global_begin);

  // Pass 1: family sizes and the ghost set. Families are recomputed in pass 2 rather than kept in
  // natural ids, so setup holds no per-bond temporaries beyond the final arrays.
  std::vector<std::int64_t> ids;
  std::vector<double> w;
  std::vector<std::int64_t> ghost_globals;
  d.bonds.offsets.assign(1, 0);
  d.bonds.offsets.reserve(d.owned + 1);
  std::size_t compact_at = 4096;
  for (std::int64_t g = d.global_begin; g < end; ++g) {
    const std::int64_t i = partition.global_to_natural[g];
    neighbours_of(nodes, cells, i, ids, w);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const std::int64_t gj = partition.natural_to_global[ids[k]];
      if (gj < d.global_begin || gj >= end) ghost_globals.push_back(gj);
    }
    d.bonds.offsets.push_back(d.bonds.offsets.back() + static_cast<std::int64_t>(ids.size()));
    if (ghost_globals.size() > compact_at) {  // keep the duplicates bounded (amortised O(1))
      std::sort(ghost_globals.begin(), ghost_globals.end());
      ghost_globals.erase(std::unique(ghost_globals.begin(), ghost_globals.end()), ghost_globals.end());
      compact_at = 2 * ghost_globals.size() + 4096;
    }
    if ((g - d.global_begin) % kPollRows == 0 && stop && stop()) return d;
  }
  std::sort(ghost_globals.begin(), ghost_globals.end());
  ghost_globals.erase(std::unique(ghost_globals.begin(), ghost_globals.end()), ghost_globals.end());
  d.ghosts = static_cast<std::int32_t>(ghost_globals.size());

  // Local numbering: owned in global order, then ghosts in global order.
  const std::int32_t nlocal = d.local();
  d.global.resize(nlocal);
  d.natural.resize(nlocal);
  for (std::int32_t l = 0; l < d.owned; ++l) d.global[l] = d.global_begin + l;
  for (std::int32_t k = 0; k < d.ghosts; ++k) d.global[d.owned + k] = ghost_globals[k];
  std::unordered_map<std::int64_t, std::int32_t> ghost_local;
  ghost_local.reserve(d.ghosts * 2);
  for (std::int32_t k = 0; k < d.ghosts; ++k) ghost_local[ghost_globals[k]] = d.owned + k;
  d.X.resize(3 * static_cast<std::size_t>(nlocal));
  d.volume.resize(nlocal);
  d.body.resize(nlocal);
  for (std::int32_t l = 0; l < nlocal; ++l) {
    const std::int64_t i = partition.global_to_natural[d.global[l]];
    d.natural[l] = i;
    for (int c = 0; c < 3; ++c) d.X[3 * l + c] = nodes.X[3 * i + c];
    d.volume[l] = nodes.volume[i];
    d.body[l] = nodes.body[i];
  }

  // Pass 2: families again, neighbours mapped to local indices, reference geometry to shared
  // family patterns, pre-cracks to broken flags.
  const std::int64_t nb = d.bonds.offsets.back();
  d.bonds.neighbor.resize(nb);
  d.bonds.broken.assign(nb, 0);
  d.bonds.row_broken.assign(d.owned, 0);  // set with the flags below
  PatternBuilder patterns;
  std::vector<double> xi2, measure;
  std::unordered_map<std::int64_t, std::int32_t> pattern_of_class;  // family_class -> pattern
  double longest = 0;  // bond of a body that some crack cuts
  std::vector<const Crack*> crack_list;
  for (const Crack& c : scene.cracks) crack_list.push_back(&c);
  auto cut = [&](int dimension) {
    return std::any_of(scene.cracks.begin(), scene.cracks.end(), [&](const Crack& c) { return c.cuts_dimension(dimension); });
  };
  for (const BodyGeometry& g : nodes.bodies)
    if (cut(g.traits.dimension)) longest = std::max(longest, reach(g));
  const bool crack_list_empty = crack_list.empty();
  d.crack_met.assign(crack_list.size(), 0);
  d.crack_far.assign(crack_list.size() * nodes.bodies.size(), 0);
  d.crack_far_most.assign(crack_list.size(), 0.0);
  const bool any_slit = std::any_of(scene.cracks.begin(), scene.cracks.end(), [](const Crack& c) { return !c.is_polygon(); });
  const CrackIndex cracks(std::move(crack_list), longest);
  // A bond of a curved sheet that slits broke: those whose midpoint is beyond the horizon from the
  // slit's segment in space are counted (Domain::crack_far).
  const auto far_walls = [&](const double* a, const double* c, int body, double horizon) {
    const double mid[3] = {0.5 * (a[0] + c[0]), 0.5 * (a[1] + c[1]), 0.5 * (a[2] + c[2])};
    for (std::size_t k = 0; k < scene.cracks.size(); ++k) {
      const Crack& crack = scene.cracks[k];
      if (crack.is_polygon() || !segments_cross(a, c, crack.from.data(), crack.to.data())) continue;
      const double far = crack.slit_distance(mid);
      if (!(far > horizon)) continue;
      ++d.crack_far[k * nodes.bodies.size() + static_cast<std::size_t>(body)];
      d.crack_far_most[k] = std::max(d.crack_far_most[k], far);
    }
  };
  for (std::int32_t r = 0; r < d.owned; ++r) {
    if (r % kPollRows == 0 && stop && stop()) return d;
    bool touches_ghost = false;
    const std::int64_t i = d.natural[r];
    const std::int64_t family = family_class(nodes, cells, i);
    const auto known = family >= 0 ? pattern_of_class.find(family) : pattern_of_class.end();
    const BodyGeometry& g = nodes.bodies[nodes.body[i]];
    // A row with a new pattern needs its bonds' |xi|^2 and measures; a free row its weights alone.
    const bool new_pattern = known == pattern_of_class.end() && !g.irregular;
    neighbours_of(nodes, cells, i, ids, w, new_pattern ? &xi2 : nullptr);
    measure.clear();
    for (std::int64_t b = d.bonds.offsets[r]; b < d.bonds.offsets[r + 1]; ++b) {
      const std::size_t k = static_cast<std::size_t>(b - d.bonds.offsets[r]);
      const std::int64_t j = ids[k];
      const std::int64_t gj = partition.natural_to_global[j];
      std::int32_t lj;
      if (gj >= d.global_begin && gj < end) {
        lj = static_cast<std::int32_t>(gj - d.global_begin);
      } else {
        lj = ghost_local.at(gj);
        touches_ghost = true;
      }
      d.bonds.neighbor[b] = lj;
      // Weights are kept to float precision, as the per-bond weights they replace were.
      if (new_pattern)
        measure.push_back(static_cast<double>(static_cast<float>(w[k])) * nodes.volume[j]);
      if (!crack_list_empty) {
        // Canonical orientation (lower natural id first) so both ends decide alike.
        const double* a = &nodes.X[3 * std::min(i, j)];
        const double* c = &nodes.X[3 * std::max(i, j)];
        if (cracks.crosses_any(a, c, g.traits.dimension, &d.crack_met)) {
          d.bonds.broken[b] = 1;
          d.bonds.row_broken[r] = 1;
          ++d.initially_broken;
          if (any_slit && g.traits.dimension == 2 && !g.traits.flat) far_walls(a, c, nodes.body[i], g.horizon);
        }
      }
    }
    if (known != pattern_of_class.end()) {
      patterns.repeat_pattern(known->second, static_cast<std::int64_t>(ids.size()));
    } else if (g.irregular) {
      patterns.add_free_row(w);
    } else {
      patterns.add_row(xi2, measure, g.horizon);
      if (family >= 0) pattern_of_class.emplace(family, patterns.last_pattern());
    }
    (touches_ghost ? d.boundary_rows : d.interior_rows).push_back(r);
  }
  d.bonds.patterns = patterns.finish();
  return d;
}

}  // namespace peri
