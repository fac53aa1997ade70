// Simulation: the Marder lattice bodies. Their node-centred energies give forces on neighbours
// that may be ghosts, so they are written into the State's ghosted force accumulator (one slot
// per node and lattice direction, see marder.hpp) and reduced to the owners by a reverse ghost
// update; the peridynamic bodies of the same scene keep their owner-computes loop. A scene
// without a lattice body builds none of this.
#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include "peri/stages/simulation.hpp"

namespace peri {

void Simulation::lattice_setup() {
  const std::size_t nb = scene_.bodies.size();
  marder_.assign(nb, std::nullopt);
  for (std::size_t b = 0; b < nb; ++b) {
    if (scene_.bodies[b].kind != BodyKind::Lattice) continue;
    const Material& m = scene_.material(scene_.bodies[b].material);
    const BodyGeometry& g = nodes_.bodies[b];
    const MarderParams& p = *m.marder;
    const double node_mass = m.density * g.cell_area * g.thickness;  // the rho of eq. (27)
    marder_[b] = marder_law(p.a, p.b, g.spacing, p.cutoff, p.fracture_separation, node_mass, p.reversible,
                            p.kelvin_viscosity);
    has_lattice_ = true;
    has_kelvin_ = has_kelvin_ || marder_[b]->dashpot > 0;
  }
  if (!has_lattice_) return;
  for (std::size_t s = 0; s < scene_.stages.size(); ++s)
    if (scene_.stages[s].kind != StageKind::Dynamic)
      throw InputError(scene_.stages[s].where.str() + ": stages." + scene_.stages[s].name +
                       ".kind: a scene with a lattice body runs dynamic stages only (the quasi-static "
                       "loader and the release stage use the peridynamic bond laws); got a " +
                       (scene_.stages[s].kind == StageKind::QuasiStatic ? "quasistatic" : "release") + " stage");
  state_->enable_force_accumulation(3 * kMarderSlots);
  if (has_kelvin_) viscous_.assign(3 * static_cast<std::size_t>(domain_.local()), 0.0);
  lattice_direction_ = marder_directions(bond_view(), domain_.owned);
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const std::optional<MarderLaw>& law = marder_[domain_.body[i]];
    if (!law) continue;
    const std::int64_t b0 = domain_.bonds.offsets[i], b1 = domain_.bonds.offsets[i + 1];
    if (b1 - b0 > kMarderMaxNeighbours)
      throw InputError(scene_.bodies[domain_.body[i]].where.str() + ": bodies." +
                       scene_.bodies[domain_.body[i]].name + ": a lattice node has " + std::to_string(b1 - b0) +
                       " neighbours; a triangular lattice has at most 6");
    // Pre-cracks stay cut in the reversible mode too.
    if (law->reversible)
      for (std::int64_t k = b0; k < b1; ++k)
        if (domain_.bonds.broken[k]) domain_.bonds.broken[k] |= kMarderCut;
    // Bonds with an end outside the breakable box never break (same decision at both ends).
    const auto& box = scene_.bodies[domain_.body[i]].breakable;
    if (!box) continue;
    auto inside = [&](std::int32_t l) {
      for (int c = 0; c < 3; ++c)
        if (domain_.X[3 * l + c] < (*box)[0][c] || domain_.X[3 * l + c] > (*box)[1][c]) return false;
      return true;
    };
    for (std::int64_t k = b0; k < b1; ++k)
      if (!inside(i) || !inside(domain_.bonds.neighbor[k])) domain_.bonds.broken[k] |= kMarderUnbreakable;
  }
  domain_.bonds.summarize_rows();
}

void Simulation::lattice_forces(const BondView& view, bool interior, bool with_energy, BondTally& tally,
                                const double* velocity) {
  LocalArray f(state_->force_accumulator());
  if (interior) std::fill(f.data(), f.data() + 3 * kMarderSlots * static_cast<std::size_t>(domain_.local()), 0.0);
  for (std::size_t b = 0; b < marder_.size(); ++b) {
    if (!marder_[b]) continue;
    const std::vector<std::int32_t>& rows = interior ? interior_by_body_[b] : boundary_by_body_[b];
    marder_forces(*marder_[b], view, rows.data(), rows.size(), lattice_direction_.data(), f.data(), with_energy,
                  tally, velocity, has_kelvin_ ? viscous_.data() : nullptr);
  }
}

void Simulation::lattice_reduce() {
  state_->reverse_begin();
  state_->reverse_end();
  const double* f;
  PERI_PETSC(VecGetArrayRead(state_->force_accumulator(), &f));
  // Forces [N] -> force densities [N/m^3], the unit of force_; the dashpot force (computed by the
  // node's own row, never on a ghost) added after the slot sum, also kept apart (viscous_) for
  // the dissipation booked by step().
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
  PERI_PETSC(VecRestoreArrayRead(state_->force_accumulator(), &f));
}

double Simulation::lattice_energy(const BondView& view) {
  double e = 0;
  for (std::size_t b = 0; b < marder_.size(); ++b) {
    if (!marder_[b]) continue;
    for (const auto* rows : {&interior_by_body_[b], &boundary_by_body_[b]})
      e += marder_energy(*marder_[b], view, rows->data(), rows->size());
  }
  return e;
}

void Simulation::lattice_derived(std::size_t b) {
  const MarderLaw& law = *marder_[b];
  const std::string p = scene_.bodies[b].name + ".";
  // Stretches of the initial homogeneous deformation along x and y (F = I + displacement gradient).
  const std::array<double, 9>& G = scene_.initial.displacement_gradient;
  const double lx = std::hypot(1 + G[0], G[3]), ly = std::hypot(G[1], 1 + G[4]);
  const WaveSpeeds along_x = mooney_rivlin_wave_speeds(law.a, law.b, lx, ly);
  const WaveSpeeds along_y = mooney_rivlin_wave_speeds(law.a, law.b, ly, lx);
  summary_.derived.push_back({p + "A", law.A});
  summary_.derived.push_back({p + "B", law.B});
  summary_.derived.push_back({p + "node_mass", law.mass});
  summary_.derived.push_back({p + "initial_stretch_x", lx});
  summary_.derived.push_back({p + "initial_stretch_y", ly});
  // Reference-frame speeds (reference distance per time) at the initial stretch.
  summary_.derived.push_back({p + "longitudinal_wave_speed_x", along_x.longitudinal});
  summary_.derived.push_back({p + "longitudinal_wave_speed_y", along_y.longitudinal});
  summary_.derived.push_back({p + "shear_wave_speed", along_x.shear});
  // The lattice's own long-wave speeds at that stretch (differ from the Mooney-Rivlin ones where
  // bonds are near u_c or on the cutoff branch; README "Marder lattice").
  const WaveSpeeds lat_x = marder_lattice_wave_speeds(law, lx, ly), lat_y = marder_lattice_wave_speeds(law, ly, lx, true);
  summary_.derived.push_back({p + "lattice_longitudinal_speed_x", lat_x.longitudinal});
  summary_.derived.push_back({p + "lattice_shear_speed_x", lat_x.shear});
  summary_.derived.push_back({p + "lattice_longitudinal_speed_y", lat_y.longitudinal});
  summary_.derived.push_back({p + "lattice_shear_speed_y", lat_y.shear});
  summary_.derived.push_back({p + "nodes", double(nodes_.bodies[b].count)});
}

}  // namespace peri
