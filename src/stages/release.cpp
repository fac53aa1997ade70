#include "peri/stages/release.hpp"

#include <vector>

#include "peri/bonds/bonds.hpp"

namespace peri {

std::int64_t release_cracks(Problem& p, const Stage& stage, EnergyLedger& ledger) {
  Domain& domain = p.domain;
  std::vector<const Crack*> cracks;
  for (const std::string& name : stage.cracks)
    for (const Crack& c : p.scene.cracks)
      if (c.name == name) cracks.push_back(&c);
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
      bool cut = false;
      for (const Crack* c : cracks) cut = cut || (c->cuts_dimension(dimension) && crosses(Xi, Xj, *c));
      if (!cut) continue;
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
