#include "peri/stages/release.hpp"

#include <mpi.h>

#include <vector>

#include "peri/bonds/bonds.hpp"
#include "peri/bonds/crossing.hpp"
#include "peri/core/error.hpp"

namespace peri {

namespace {

/// Whether the bond (X_i, X_j) of a body of `dimension` crosses one of `cracks`.
bool cut_by(const std::vector<const Crack*>& cracks, int dimension, const double* Xi, const double* Xj) {
  for (const Crack* c : cracks)
    if (c->cuts_dimension(dimension) && crosses(Xi, Xj, *c)) return true;
  return false;
}

std::vector<const Crack*> stage_cracks(const Scene& scene, const Stage& stage) {
  std::vector<const Crack*> cracks;
  for (const std::string& name : stage.cracks)
    for (const Crack& c : scene.cracks)
      if (c.name == name) cracks.push_back(&c);
  return cracks;
}

}  // namespace

void check_release_stages(const Problem& p) {
  const Domain& domain = p.domain;
  for (const Stage& stage : p.scene.stages) {
    if (stage.kind != StageKind::Release) continue;
    const std::vector<const Crack*> cracks = stage_cracks(p.scene, stage);
    int met = 0;
    for (std::int32_t i = 0; i < domain.owned && !met; ++i) {
      const int dimension = p.bodies[domain.body[i]].traits.dimension;
      const double* Xi = &domain.X[3 * static_cast<std::size_t>(i)];
      for (std::int64_t b = domain.bonds.offsets[i]; b < domain.bonds.offsets[i + 1] && !met; ++b)
        met = cut_by(cracks, dimension, Xi, &domain.X[3 * static_cast<std::size_t>(domain.bonds.neighbor[b])]);
    }
    MPI_Allreduce(MPI_IN_PLACE, &met, 1, MPI_INT, MPI_MAX, p.comm);
    if (!met)
      throw InputError(stage.where.str() + ": stages." + stage.name + ".cracks: the named cracks cross no bond of " +
                       "a body they cut (a slit: membrane, lattice, fiber or sphere; a polygon: any); expected " +
                       "cracks that meet the bodies");
  }
}

std::int64_t release_cracks(Problem& p, const Stage& stage, EnergyLedger& ledger) {
  Domain& domain = p.domain;
  const std::vector<const Crack*> cracks = stage_cracks(p.scene, stage);
  p.state->halo_begin();
  p.state->halo_end();
  LocalArray u(p.state->displacement());
  std::int64_t released = 0;
  double energy = 0;
  const BondView view = p.forces->bond_view();
  for (std::int32_t i = 0; i < domain.owned; ++i) {
    const BondLaw& law = p.forces->laws()[domain.body[i]];
    const double* Xi = &domain.X[3 * static_cast<std::size_t>(i)];
    const int dimension = p.bodies[domain.body[i]].traits.dimension;  // a slit cuts no volume
    for (std::int64_t b = domain.bonds.offsets[i]; b < domain.bonds.offsets[i + 1]; ++b) {
      if (domain.bonds.broken[b]) continue;
      const std::int32_t j = domain.bonds.neighbor[b];
      const double* Xj = &domain.X[3 * static_cast<std::size_t>(j)];
      if (!cut_by(cracks, dimension, Xi, Xj)) continue;
      double y2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double e = Xj[c] - Xi[c] + u.data()[3 * j + c] - u.data()[3 * i + c];
        y2 += e * e;
      }
      energy += 0.5 * domain.volume[i] * view.measure(i, b) * law.energy(view.xi2(i, b), y2);  // eq. (5), one end
      domain.bonds.broken[b] = 1;
      domain.bonds.row_broken[i] = 1;
      ++released;
    }
  }
  p.forces->flags_changed();
  ledger.bonds.dissipated += energy;
  ledger.bonds.newly_broken += released;
  long long global = 0, local = released;
  MPI_Allreduce(&local, &global, 1, MPI_LONG_LONG, MPI_SUM, p.comm);
  return global / 2;
}

}  // namespace peri
