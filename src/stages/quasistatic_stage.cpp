#include "peri/stages/quasistatic_stage.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "peri/core/petsc.hpp"

namespace peri {

void ProblemEquilibrium::set_displacement(const double* u_owned) {
  {
    const VecArray u(p_.state->displacement());
    std::copy(u_owned, u_owned + 3 * static_cast<std::size_t>(p_.domain.owned), u.data());
  }
  p_.forces->displacement_changed();
  ghosts_current_ = false;  // the force pass exchanges them; add_tangent does if it comes first
}

void ProblemEquilibrium::get_displacement(double* u_owned) {
  const VecArrayRead u(p_.state->displacement());
  std::copy(u.data(), u.data() + 3 * static_cast<std::size_t>(p_.domain.owned), u_owned);
}

bool ProblemEquilibrium::loaded() const {
  return std::any_of(p_.loads.begin(), p_.loads.end(), [](const auto& load) { return load->quasistatic(); });
}

void ProblemEquilibrium::internal_force(double* f_owned) {
  p_.forces->compute(false, true, ledger_.bonds);  // (exchanges the ghosts' displacement)
  ghosts_current_ = true;
  double* force = p_.forces->force();
  const std::size_t n = 3 * static_cast<std::size_t>(p_.domain.owned);
  if (loaded()) {
    // The loads add force densities on top of the bonds'; their part is kept for the work.
    load_force_.assign(force, force + n);
    const LoadTarget target{p_.forces->positions(), p_.forces->position_stride(), force, 0.0};
    EnergyLedger scratch;  // nothing is booked: the loader books the loads' work per increment
    for (const auto& load : p_.loads)
      if (load->quasistatic()) load->add_forces(0.0, target, false, scratch);
    for (std::size_t k = 0; k < n; ++k) load_force_[k] = (force[k] - load_force_[k]) * p_.domain.volume[k / 3];
  }
  for (std::int32_t i = 0; i < p_.domain.owned; ++i)
    for (int c = 0; c < 3; ++c) f_owned[3 * i + c] = force[3 * i + c] * p_.domain.volume[i];
}

bool ProblemEquilibrium::load_force(double* f_owned) {
  if (load_force_.empty()) return false;
  std::copy(load_force_.begin(), load_force_.end(), f_owned);
  return true;
}

void ProblemEquilibrium::set_load_level(double level) {
  for (const auto& load : p_.loads)
    if (load->quasistatic()) load->set_quasistatic_level(level);
}

std::string ProblemEquilibrium::load_text(double level) const {
  std::string text;
  for (const auto& load : p_.loads)
    if (load->quasistatic())
      if (const std::string t = load->quasistatic_text(level); !t.empty()) text += (text.empty() ? "" : ", ") + t;
  return text;
}

void ProblemEquilibrium::add_tangent(Mat J, const DofLayout& layout) {
  if (!ghosts_current_) {
    p_.state->halo_begin();
    p_.state->halo_end();
    ghosts_current_ = true;
  }
  p_.forces->add_tangent(J, layout.block.data(), layout.components);  // (it leaves the current positions in forces->positions())
  if (!loaded()) return;
  const LoadTarget target{p_.forces->positions(), p_.forces->position_stride(), nullptr, 0.0};
  const int bs = layout.components;
  const Load::StiffnessSink sink = [&](std::int32_t i, std::int32_t j, const double* block) {
    const PetscInt row = layout.block[i], col = layout.block[j];
    if (row < 0 || col < 0) return;
    double sub[9];
    for (int r = 0; r < bs; ++r)
      for (int c = 0; c < bs; ++c) sub[bs * r + c] = block[3 * r + c];
    PERI_PETSC(MatSetValuesBlocked(J, 1, &row, 1, &col, sub, ADD_VALUES));
  };
  for (const auto& load : p_.loads)
    if (load->quasistatic()) load->add_stiffness(target, sink);
}

std::int64_t ProblemEquilibrium::break_bonds() {
  const std::int64_t before = ledger_.bonds.newly_broken;
  p_.forces->compute(false, false, ledger_.bonds);
  ghosts_current_ = true;
  long long local = ledger_.bonds.newly_broken - before, global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_LONG_LONG, MPI_SUM, p_.comm);
  return global / 2;
}

DofLayout dof_layout(const Problem& p, const std::vector<std::uint8_t>* held) {
  const Domain& d = p.domain;
  DofLayout layout;
  // Two in-plane components per node where every node's out-of-plane one is held (flat
  // membranes in an in_plane stage), on all ranks.
  int planar = held ? 1 : 0, all_planar = 0;
  for (std::int32_t i = 0; planar && i < d.owned; ++i) planar = (*held)[3 * static_cast<std::size_t>(i) + 2];
  MPI_Allreduce(&planar, &all_planar, 1, MPI_INT, MPI_LAND, p.comm);
  layout.components = all_planar ? 2 : 3;
  for (std::int32_t i = 0; i < d.owned; ++i) {
    bool any = !held;
    for (int c = 0; !any && c < layout.components; ++c) any = !(*held)[3 * static_cast<std::size_t>(i) + c];
    if (any) layout.nodes.push_back(i);
  }
  long long mine = static_cast<long long>(layout.nodes.size()), first = 0;
  MPI_Exscan(&mine, &first, 1, MPI_LONG_LONG, MPI_SUM, p.comm);
  int rank = 0;
  MPI_Comm_rank(p.comm, &rank);
  if (rank == 0) first = 0;  // (MPI_Exscan leaves rank 0's result undefined)
  layout.block.assign(static_cast<std::size_t>(d.local()), -1);
  for (std::size_t k = 0; k < layout.nodes.size(); ++k) layout.block[layout.nodes[k]] = static_cast<PetscInt>(first + k);
  p.state->exchange_ghosts(layout.block.data(), sizeof(PetscInt));
  for (const std::int32_t i : layout.nodes) {
    PetscInt in = 1, out = 0;
    for (std::int64_t b = d.bonds.offsets[i]; b < d.bonds.offsets[i + 1]; ++b) {
      const std::int32_t j = d.bonds.neighbor[b];
      if (layout.block[j] >= 0) (j < d.owned ? in : out) += 1;
    }
    layout.d_nnz.push_back(in);
    layout.o_nnz.push_back(out);
  }
  return layout;
}

std::unique_ptr<QuasiStaticLoader> make_loader(const Problem& p, const Stage& stage,
                                               const std::vector<std::uint8_t>* held) {
  const Domain& d = p.domain;
  double local[2] = {p.forces->reference_stiffness_sum(), double(d.owned)}, global[2];
  MPI_Allreduce(local, global, 2, MPI_DOUBLE, MPI_SUM, p.comm);
  double spacing = INFINITY;
  for (const Body& b : p.scene.bodies) spacing = std::min(spacing, b.spacing);
  return std::make_unique<QuasiStaticLoader>(p.comm, d.owned, dof_layout(p, held),
                                             global[0] / std::max(global[1], 1.0), spacing, stage);
}

QuasiStaticStats run_quasistatic(Problem& p, const Stage& stage, double t, EquilibriumModel& model,
                                 EnergyLedger& ledger, bool verbose, const IncrementObserver& observer) {
  for (const auto& load : p.loads)
    if (load->quasistatic()) load->begin_quasistatic(t);
  const std::size_t n = 3 * static_cast<std::size_t>(p.domain.owned);
  std::vector<std::uint8_t> constrained(n, 0);
  std::vector<double> increment(n, 0.0);
  p.boundaries->quasistatic_targets(stage, p.domain, constrained, increment);
  // Flat sheets under in-plane load have no out-of-plane stiffness at the flat state.
  if (stage.in_plane)
    for (std::int32_t i = 0; i < p.domain.owned; ++i)
      if (p.bodies[p.domain.body[i]].traits.flat) constrained[3 * static_cast<std::size_t>(i) + 2] = 1;
  // Components held where they are over the stage are no unknowns (prescribed: eliminated, the
  // default), or unknowns held by scaled rows (scaled_rows). Components the stage moves stay
  // unknowns with scaled rows either way: the first increment starts with them where they are,
  // so that its first Newton step is the tangent predictor (QuasiStaticLoader::run); eliminated,
  // they would jump to their targets with the free nodes left behind (29 instead of 10 Newton
  // iterations for example 7.1's 102k-node sheet).
  std::vector<std::uint8_t> held(n, 0);
  for (std::size_t k = 0; k < n; ++k) held[k] = constrained[k] && increment[k] == 0.0;
  std::unique_ptr<QuasiStaticLoader> loader =
      make_loader(p, stage, stage.prescribed == Stage::Prescribed::Eliminated ? &held : nullptr);
  {  // the bodies' rigid motions at the current positions, for the multigrid preconditioner
    std::vector<double> x(n);
    model.get_displacement(x.data());
    for (std::size_t k = 0; k < n; ++k) x[k] += p.domain.X[k];
    loader->set_near_null_space(x, constrained);
  }
  QuasiStaticStats stats = loader->run(model, constrained, increment, verbose, observer);
  p.state->halo_begin();  // the ghosts of the final state (the model leaves them to the force pass)
  p.state->halo_end();
  ledger.external_work += stats.external_work;
  // Equilibrium: at rest.
  PERI_PETSC(VecSet(p.state->velocity(), 0.0));
  double work = 0, local = stats.external_work;
  MPI_Allreduce(&local, &work, 1, MPI_DOUBLE, MPI_SUM, p.comm);
  stats.external_work = work;
  return stats;
}

}  // namespace peri
