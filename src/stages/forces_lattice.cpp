// Forces: the Marder lattice bodies. Their node-centred energies give forces on neighbours
// that may be ghosts, so they are written into the State's ghosted force accumulator (one slot
// per node and lattice direction, see marder.hpp) and reduced to the owners by a reverse ghost
// update; the peridynamic bodies of the same scene keep their owner-computes loop. A scene
// without a lattice body builds none of this.
#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include "peri/stages/forces.hpp"

namespace peri {

void Forces::lattice_setup(const Scene& scene, const std::vector<BodyGeometry>& bodies) {
  const std::size_t nb = scene.bodies.size();
  marder_.assign(nb, std::nullopt);
  for (std::size_t b = 0; b < nb; ++b) {
    if (!scene.bodies[b].kind->traits.lattice) continue;
    const Material& m = scene.material(scene.bodies[b].material);
    const BodyGeometry& g = bodies[b];
    const MarderParams& p = *m.marder;
    const double node_mass = m.density * g.cell_area * g.thickness;  // the rho of eq. (27)
    marder_[b] = marder_law(p.a, p.b, g.spacing, p.cutoff, p.fracture_separation, node_mass, p.reversible,
                            p.options);
    has_lattice_ = true;
    has_kelvin_ = has_kelvin_ || marder_[b]->dashpot > 0;
  }
  if (!has_lattice_) return;
  for (std::size_t s = 0; s < scene.stages.size(); ++s)
    if (scene.stages[s].kind != StageKind::Dynamic)
      throw InputError(scene.stages[s].where.str() + ": stages." + scene.stages[s].name +
                       ".kind: a scene with a lattice body runs dynamic stages only (the quasi-static "
                       "loader and the release stage use the peridynamic bond laws); got a " +
                       (scene.stages[s].kind == StageKind::QuasiStatic ? "quasistatic" : "release") + " stage");
  state_.enable_force_accumulation(3 * kMarderSlots);
  if (has_kelvin_) viscous_.assign(3 * static_cast<std::size_t>(domain_.local()), 0.0);
  lattice_direction_ = marder_directions(bond_view(), domain_.owned);
  std::vector<long long> breakable(scene.bodies.size(), 0);  // per body: ordered bonds that may break
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const std::optional<MarderLaw>& law = marder_[domain_.body[i]];
    if (!law) continue;
    const std::int64_t b0 = domain_.bonds.offsets[i], b1 = domain_.bonds.offsets[i + 1];
    if (b1 - b0 > kMarderMaxNeighbours)
      throw InputError(scene.bodies[domain_.body[i]].where.str() + ": bodies." +
                       scene.bodies[domain_.body[i]].name + ": a lattice node has " + std::to_string(b1 - b0) +
                       " neighbours; a triangular lattice has at most 6");
    // Pre-cracks stay cut in the reversible mode too.
    if (law->reversible)
      for (std::int64_t k = b0; k < b1; ++k)
        if (domain_.bonds.broken[k]) domain_.bonds.broken[k] |= kMarderCut;
    // Bonds with an end outside the breakable box never break (same decision at both ends).
    const auto& box = scene.bodies[domain_.body[i]].breakable;
    if (!box) continue;
    auto inside = [&](std::int32_t l) {
      for (int c = 0; c < 3; ++c)
        if (domain_.X[3 * l + c] < (*box)[0][c] || domain_.X[3 * l + c] > (*box)[1][c]) return false;
      return true;
    };
    for (std::int64_t k = b0; k < b1; ++k)
      if (!inside(i) || !inside(domain_.bonds.neighbor[k])) domain_.bonds.broken[k] |= kMarderUnbreakable;
      else ++breakable[static_cast<std::size_t>(domain_.body[i])];
  }
  // A box that holds no bond leaves the body unbreakable: surely not what it was given for.
  std::vector<long long> all(breakable.size());
  MPI_Allreduce(breakable.data(), all.data(), static_cast<int>(all.size()), MPI_LONG_LONG, MPI_SUM, comm_);
  for (std::size_t b = 0; b < all.size(); ++b)
    if (marder_[b] && scene.bodies[b].breakable && all[b] == 0)
      throw InputError(scene.bodies[b].where.str() + ": bodies." + scene.bodies[b].name +
                       ".breakable: the box holds no bond of the body (no two lattice neighbours inside it), so "
                       "nothing may break; expected a box around the nodes that may break");
  domain_.bonds.summarize_rows();
}

void Forces::lattice_forces(const BondView& view, bool interior, bool with_energy, BondTally& tally,
                                const double* velocity) {
  LocalArray f(state_.force_accumulator());
  if (interior) std::fill(f.data(), f.data() + 3 * kMarderSlots * static_cast<std::size_t>(domain_.local()), 0.0);
  for (std::size_t b = 0; b < marder_.size(); ++b) {
    if (!marder_[b]) continue;
    const std::vector<std::int32_t>& rows = interior ? interior_by_body_[b] : boundary_by_body_[b];
    marder_forces(*marder_[b], view, rows.data(), rows.size(), lattice_direction_.data(), f.data(), with_energy,
                  tally, velocity, has_kelvin_ ? viscous_.data() : nullptr);
  }
}

void Forces::lattice_reduce() {
  state_.reverse_begin();
  state_.reverse_end();
  const VecArrayRead slots(state_.force_accumulator());
  const double* f = slots.data();
  // Forces [N] -> force densities [N/m^3], the unit of force_; the dashpot force (computed by the
  // node's own row, never on a ghost) added after the slot sum, also kept apart (viscous_) for
  // the dissipation booked by the explicit update.
  for (std::size_t b = 0; b < marder_.size(); ++b) {
    if (!marder_[b]) continue;
    const bool dashpots = marder_[b]->dashpot > 0;
    for (const auto* rows : {&interior_by_body_[b], &boundary_by_body_[b]}) {
      marder_sum_slots(f, rows->data(), rows->size(), force_.data());
      for (std::int32_t i : *rows)
        for (int c = 0; c < 3; ++c) {
          const std::size_t k = 3 * static_cast<std::size_t>(i) + c;
          if (dashpots) {
            force_[k] += viscous_[k];
            viscous_[k] /= domain_.volume[i];
          }
          force_[k] /= domain_.volume[i];
        }
    }
  }
}

double Forces::lattice_energy(const BondView& view) {
  double e = 0;
  for (std::size_t b = 0; b < marder_.size(); ++b) {
    if (!marder_[b]) continue;
    for (const auto* rows : {&interior_by_body_[b], &boundary_by_body_[b]})
      e += marder_energy(*marder_[b], view, rows->data(), rows->size());
  }
  return e;
}

}  // namespace peri
