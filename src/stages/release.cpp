#include "peri/stages/release.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "peri/bonds/bonds.hpp"
#include "peri/bonds/crossing.hpp"
#include "peri/core/error.hpp"
#include "peri/stages/geometry_warnings.hpp"

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

/// Warns (rank 0) where the stage's slits would break bonds of a curved sheet (a sphere, a curved
/// mesh) farther than its horizon from every slit in space: the walls above and below that a slit,
/// taken in the xy plane, cuts too (as for the pre-cracks broken at the start). Collective.
void warn_far_walls(const Problem& p, const Stage& stage, const std::vector<const Crack*>& cracks) {
  const Domain& domain = p.domain;
  const std::size_t nb = p.bodies.size();
  const auto curved = [&](std::size_t b) { return p.bodies[b].traits.dimension == 2 && !p.bodies[b].traits.flat; };
  bool any = false;
  for (std::size_t b = 0; b < nb; ++b) any = any || curved(b);
  if (!any || std::all_of(cracks.begin(), cracks.end(), [](const Crack* c) { return c->is_polygon(); })) return;
  std::vector<std::int64_t> far(nb, 0);
  double most = 0;
  for (std::int32_t i = 0; i < domain.owned; ++i) {
    const std::size_t body = static_cast<std::size_t>(domain.body[i]);
    if (!curved(body)) continue;
    const double* Xi = &domain.X[3 * static_cast<std::size_t>(i)];
    for (std::int64_t b = domain.bonds.offsets[i]; b < domain.bonds.offsets[i + 1]; ++b) {
      const double* Xj = &domain.X[3 * static_cast<std::size_t>(domain.bonds.neighbor[b])];
      const double mid[3] = {0.5 * (Xi[0] + Xj[0]), 0.5 * (Xi[1] + Xj[1]), 0.5 * (Xi[2] + Xj[2])};
      double nearest = INFINITY;
      for (const Crack* c : cracks)
        if (!c->is_polygon() && crosses(Xi, Xj, *c)) nearest = std::min(nearest, c->slit_distance(mid));
      if (std::isfinite(nearest) && nearest > p.bodies[body].horizon) {
        ++far[body];
        most = std::max(most, nearest);
      }
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, far.data(), static_cast<int>(nb), MPI_INT64_T, MPI_SUM, p.comm);
  MPI_Allreduce(MPI_IN_PLACE, &most, 1, MPI_DOUBLE, MPI_MAX, p.comm);
  for (std::size_t b = 0; b < nb && p.rank == 0; ++b) {
    if (far[b] == 0) continue;
    warn_slit_far_walls(stage.where.str() + ": stages." + stage.name + ".cracks: the slits", "would break",
                        static_cast<long long>(far[b] / 2), p.scene.bodies[b].name, p.bodies[b].horizon, "them", most);
  }
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
    warn_far_walls(p, stage, cracks);
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
