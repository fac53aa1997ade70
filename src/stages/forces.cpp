#include "peri/stages/forces.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <numeric>
#include <sstream>

#include "peri/core/error.hpp"
#include "peri/core/format.hpp"
#include "peri/kernels/dashpots.hpp"
#include "peri/kernels/tangent.hpp"
#include "peri/models/model.hpp"
#include "peri/stages/events.hpp"

namespace peri {
void LongRangeForces::refresh(const double* X, const double* u) {
  const std::size_t own = mine_local.size();
  for (std::size_t k = 0; k < own; ++k)
    for (int c = 0; c < 3; ++c) {
      const std::size_t i = static_cast<std::size_t>(mine_local[k]);
      x[3 * k + c] = u ? X[3 * i + c] + u[3 * i + c] : X[3 * i + c];
    }
  halo.exchange(x.data(), x.data() + 3 * own);
  // The list and the halo hold while no node has moved more than skin / 2 since they were built
  // (LongRangeList: no pair within its cutoff can be missing). Each rank looks at the nodes it
  // sees; every node is some rank's own, so the ranks' verdicts together cover all nodes, and
  // every rank follows the same (global) decision.
  if (!halo.on_any_rank(list.stale(x.data(), static_cast<std::int64_t>(id.size())))) return;
  // A node flung to infinity (a failing run, between two health checks) has no cell: stop the
  // run as the health check would, on every rank.
  bool finite = true;
  for (std::size_t k = 0; k < 3 * own; ++k) finite = finite && std::isfinite(x[k]);
  if (halo.on_any_rank(!finite))
    throw RuntimeFailure("unstable explicit integration: a node of the long-range pairs is no longer at a finite "
                         "position; likely cause: the time step is too large for the current state, or nodes "
                         "pressed together far closer than the long-range law's cutoff");
  PetscLogEventBegin(events().long_range_build, 0, 0, 0, 0);
  halo.rebuild(static_cast<std::int64_t>(own), id, x, law.reach + list.skin);
  volume.resize(id.size());
  for (std::size_t k = 0; k < id.size(); ++k) volume[k] = table.volume[static_cast<std::size_t>(id[k])];
  build_long_range_list(law, table, nodes(), rows.data(), static_cast<std::int64_t>(own), list);
  PetscLogEventEnd(events().long_range_build, 0, 0, 0, 0);
}

LongRangeForces make_long_range(const Scene& scene, const Nodes& nodes, const Domain& domain, MPI_Comm comm) {
  LongRangeForces lr(PairLaw(*scene.long_range), long_range_table(nodes), comm);
  check_segment_rules(*scene.long_range, lr.table);
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  for (const std::string& w : check_pair_rules(*scene.long_range, lr.law, lr.table))
    if (rank == 0) std::fprintf(stderr, "peridrive: warning: %s\n", w.c_str());
  for (std::int32_t i = 0; i < domain.owned; ++i) {
    const std::int64_t p = lr.table.index_of(domain.natural[i]);
    if (p < 0) continue;
    lr.id.push_back(p);
    lr.mine_local.push_back(i);
  }
  const std::size_t own = lr.mine_local.size();
  lr.rows.resize(own);
  std::iota(lr.rows.begin(), lr.rows.end(), std::int64_t{0});
  lr.x.resize(3 * own);
  lr.force.resize(3 * own);
  lr.list.set_skin(lr.law);
  // The list at the reference positions: a cutoff that takes in most of the scene would hold
  // O(N^2) pairs (6 bytes each); refuse it before anything is written.
  lr.refresh(domain.X.data(), nullptr);
  double pairs = static_cast<double>(lr.list.begin.back()), all_pairs = 0;
  MPI_Allreduce(&pairs, &all_pairs, 1, MPI_DOUBLE, MPI_SUM, comm);
  const double per_node = all_pairs / std::max<double>(1.0, static_cast<double>(lr.table.size()));
  if (all_pairs > 2e8 || per_node > 5000) {
    std::ostringstream msg;
    // Name the rule whose cutoff is the list's reach when it is not the section's.
    SourceLoc where = scene.long_range->where;
    std::string key = "long_range.cutoff";
    const std::vector<PairRule>& rules = scene.long_range->pairs;
    for (std::size_t r = 0; r < rules.size() && lr.law.reach > lr.law.cutoff; ++r)
      if (rules[r].cutoff == lr.law.reach) {
        where = rules[r].where;
        key = "long_range.pairs." + std::to_string(r) + ".cutoff";
        break;
      }
    msg << where.str() << ": " << key << ": " << number_text(lr.law.reach) << " m takes in " << all_pairs
        << " node pairs, " << number_text(per_node) << " per node (with the Verlet list's skin of a quarter "
        << "cutoff) at the reference positions; expected a cutoff of a few a (length " << number_text(lr.law.length)
        << " m): at most 5000 pairs per node and 2e8 in all";
    throw InputError(msg.str());
  }
  return lr;
}

Forces::Forces(const Scene& scene, const std::vector<BodyGeometry>& bodies, Domain& domain, State& state,
               std::vector<BondLaw> laws, std::optional<LongRangeForces> long_range, MPI_Comm comm)
    : domain_(domain), state_(state), comm_(comm), laws_(std::move(laws)), long_range_(std::move(long_range)) {
  const std::size_t nb = scene.bodies.size();
  for (const BondLaw& law : laws_) intact_laws_.push_back(law.empty() ? BondLaw{} : law.intact());
  force_.assign(3 * static_cast<std::size_t>(domain_.owned), 0.0);
  position_stride_ = position_plane_stride(domain_.local());
  positions_.assign(3 * static_cast<std::size_t>(position_stride_), 0.0);
  damage_.assign(domain_.owned, 0.0);
  interior_by_body_.resize(nb);
  boundary_by_body_.resize(nb);
  for (std::int32_t r : domain_.interior_rows) interior_by_body_[domain_.body[r]].push_back(r);
  for (std::int32_t r : domain_.boundary_rows) boundary_by_body_[domain_.body[r]].push_back(r);
  lattice_setup(scene, bodies);
  dashpot_setup(scene, bodies);
  std::vector<double> tip_radius(nb, -1.0);
  std::vector<std::uint8_t> tips_by_body(nb, 0);
  for (std::size_t b = 0; b < nb; ++b)
    if (const Material& m = scene.material(scene.bodies[b].material); m.tip_advance && !marder_[b]) {
      tip_radius[b] = *m.tip_advance;
      tips_by_body[b] = m.tip_advance_tips == TipScope::Body ? 1 : 0;
    }
  if (std::any_of(tip_radius.begin(), tip_radius.end(), [](double r) { return r >= 0; }))
    tip_advance_.emplace(tip_radius, tips_by_body, domain_, state_);
  interior_plan_.resize(nb);
  boundary_plan_.resize(nb);
  PetscLogEventBegin(events().plans, 0, 0, 0, 0);
  {
    const BondView topology = bond_view();
    for (std::size_t b = 0; b < nb; ++b) {
      if (marder_[b]) continue;
      interior_plan_[b] = plan_rows(topology, interior_by_body_[b].data(), interior_by_body_[b].size());
      boundary_plan_[b] = plan_rows(topology, boundary_by_body_[b].data(), boundary_by_body_[b].size());
    }
  }
  PetscLogEventEnd(events().plans, 0, 0, 0, 0);
}

std::size_t Forces::plan_bytes() const {
  std::size_t bytes = 0;
  for (const std::vector<RowBlocks>* plans : {&interior_plan_, &boundary_plan_})
    for (const RowBlocks& plan : *plans) bytes += plan.extra_bytes();
  return bytes;
}

BondView Forces::bond_view() {
  BondView v{domain_.X.data(), nullptr, domain_.volume.data(), domain_.bonds.offsets.data(),
             domain_.bonds.neighbor.data(), domain_.bonds.broken.data(), &domain_.bonds.patterns,
             positions_.data(), position_stride_, domain_.bonds.row_broken.data()};
  if (domain_.bonds.history_stride > 0) {  // laws with per-bond history read it; force passes commit
    v.history = domain_.bonds.history.data();
    v.history_stride = domain_.bonds.history_stride;
  }
  return v;
}

void Forces::compute(bool with_energy, bool intact, BondTally& tally) {
  PetscLogEventBegin(events().forces, 0, 0, 0, 0);
  const std::vector<BondLaw>& laws = intact ? intact_laws_ : laws_;
  BondView view = bond_view();
  view.commit_history = !intact;  // (quasi-static residuals evaluate, they do not load the bonds)
  BondTally t;
  if (with_energy) {  // the bond loop writes each bond row's energy density (lattice rows: 0)
    energy_density_.assign(domain_.owned, 0.0);
    view.energy_density = energy_density_.data();
  }
  density_current_ = with_energy;
  // The crack-tip rule: its bodies run the intact law in the bond loop, then (after the halo) the
  // rows with a bond that may break run again in the portable walk with the rule, replacing their
  // forces, energy densities and energies (the same bits where nothing breaks).
  const bool rule = tip_advance_ && !intact;
  if (rule) {
    tip_advance_->prepare(view, time_);
    view.may_break = tip_advance_->may_break();
  }
  auto loop = [&](std::size_t b, const RowBlocks& plan) {
    const bool held = rule && tip_advance_->applies(static_cast<int>(b));
    bond_forces(held ? intact_laws_[b] : laws[b], view, plan, force_.data(), with_energy, t);
  };
  if (has_kelvin_) {  // ghost velocities for the dashpots (not overlapped: the two ghosted Vecs
    state_.velocity_halo_begin();  // share one scatter, which holds one exchange at a time)
    state_.velocity_halo_end();
  }
  state_.halo_begin();  // interior rows need no ghost: overlap them with the exchange
  {
    LocalArray u(state_.displacement());
    std::optional<LocalArray> vel;
    if (has_kelvin_) {
      vel.emplace(state_.velocity());
      dashpot_velocity_.assign(vel->data(), vel->data() + 3 * static_cast<std::size_t>(domain_.owned));
    }
    view.u = u.data();
    current_positions(domain_.X.data(), u.data(), 0, domain_.owned, position_stride_, positions_.data());
    for (std::size_t b = 0; b < laws_.size(); ++b)
      if (!marder_[b]) loop(b, interior_plan_[b]);
    if (has_lattice_) lattice_forces(view, true, with_energy, t, vel ? vel->data() : nullptr);
  }
  PetscLogEventBegin(events().halo, 0, 0, 0, 0);
  state_.halo_end();
  PetscLogEventEnd(events().halo, 0, 0, 0, 0);
  {
    LocalArray u(state_.displacement());
    std::optional<LocalArray> vel;
    if (has_kelvin_) vel.emplace(state_.velocity());
    view.u = u.data();
    current_positions(domain_.X.data(), u.data(), domain_.owned, domain_.local(), position_stride_, positions_.data());
    for (std::size_t b = 0; b < laws_.size(); ++b)
      if (!marder_[b]) loop(b, boundary_plan_[b]);
    if (has_lattice_) lattice_forces(view, false, with_energy, t, vel ? vel->data() : nullptr);
    if (rule)
      for (std::size_t b = 0; b < laws_.size(); ++b) {
        const RowBlocks& rows = tip_advance_->rows(static_cast<int>(b));
        if (!tip_advance_->applies(static_cast<int>(b)) || rows.rest.empty()) continue;
        if (with_energy)  // the intact pass's energies of these rows
          for (std::int32_t i : rows.rest) t.strain_energy -= domain_.volume[i] * energy_density_[i];
        const std::int64_t before = t.newly_broken;
        laws[b].entry().portable_forces(laws[b].constants(), view, rows, force_.data(), with_energy, t);
        if (t.newly_broken != before) flags_changed();
      }
    if (rule) tip_advance_->stamp(view, time_);
    if (!dashpot_tau_.empty() && !intact) add_dashpots(view, vel->data());
  }
  if (has_lattice_) lattice_reduce();
  if (long_range_) {
    LocalArray u(state_.displacement());
    t.strain_energy += add_long_range_forces(u.data(), with_energy);
  }
  tally.dissipated += t.dissipated;
  tally.newly_broken += t.newly_broken;
  tally.strain_energy = t.strain_energy;
  PetscLogEventEnd(events().forces, 0, 0, 0, 0);
}

void Forces::dashpot_setup(const Scene& scene, const std::vector<BodyGeometry>& bodies) {
  std::vector<double> tau(laws_.size(), 0.0);
  bool any = false;
  for (std::size_t b = 0; b < laws_.size(); ++b) {
    const Material& m = scene.material(scene.bodies[b].material);
    if (marder_[b] || !(m.kelvin_viscosity > 0) || laws_[b].empty()) continue;
    const ElasticConstants e = elastic_constants(laws_[b], bodies[b], m.density);
    if (!(e.mu > 0) || bodies[b].traits.dimension == 1)
      throw InputError(m.where.str() + ": materials." + m.name + ".kelvin_viscosity: bodies." + scene.bodies[b].name +
                       " is a fiber, which has no shear modulus to define the dashpots by (tau = rho nu / mu)");
    tau[b] = m.density * m.kelvin_viscosity / e.mu;
    any = true;
  }
  if (!any) return;
  dashpot_tau_ = std::move(tau);
  has_kelvin_ = true;
  viscous_.assign(3 * static_cast<std::size_t>(domain_.local()), 0.0);  // (a lattice's rows too: it writes them)
  const BondView view = bond_view();
  dashpot_lanes_.assign(dashpot_tau_.size(), {});
  for (std::size_t b = 0; b < dashpot_tau_.size(); ++b)
    if (dashpot_tau_[b] > 0)
      for (int part = 0; part < 2; ++part) {
        const std::vector<std::int32_t>& rows = part == 0 ? interior_by_body_[b] : boundary_by_body_[b];
        dashpot_lanes_[b][part] = dashpot_lanes(laws_[b], dashpot_tau_[b], view, rows.data(), rows.size());
      }
}

void Forces::add_dashpots(const BondView& view, const double* velocity) {
  dashpot_records_.resize(static_cast<std::size_t>(kDashpotRecord * domain_.local()));
  dashpot_records(view, velocity, domain_.local(), dashpot_records_.data());
  for (std::size_t b = 0; b < dashpot_tau_.size(); ++b) {
    if (!(dashpot_tau_[b] > 0)) continue;
    for (int part = 0; part < 2; ++part) {
      const std::vector<std::int32_t>* rows = part == 0 ? &interior_by_body_[b] : &boundary_by_body_[b];
      bond_dashpots(view, dashpot_records_.data(), dashpot_lanes_[b][part], rows->data(), rows->size(), viscous_.data());
      for (std::int32_t i : *rows)
        for (int c = 0; c < 3; ++c) force_[3 * static_cast<std::size_t>(i) + c] += viscous_[3 * static_cast<std::size_t>(i) + c];
    }
  }
}

double Forces::add_long_range_forces(const double* u, bool with_energy) {
  PetscLogEventBegin(events().long_range, 0, 0, 0, 0);
  LongRangeForces& lr = *long_range_;
  lr.refresh(domain_.X.data(), u);
  std::fill(lr.force.begin(), lr.force.end(), 0.0);
  const std::int64_t own = static_cast<std::int64_t>(lr.rows.size());
  const double energy =
      long_range_pair_forces(lr.law, lr.nodes(), lr.rows.data(), own, lr.force.data(), lr.list, with_energy);
  for (std::size_t k = 0; k < lr.mine_local.size(); ++k)
    for (int c = 0; c < 3; ++c) force_[3 * static_cast<std::size_t>(lr.mine_local[k]) + c] += lr.force[3 * k + c];
  PetscLogEventEnd(events().long_range, 0, 0, 0, 0);
  return energy;
}

void Forces::flags_changed() {
  for (const RowBlocks& plan : interior_plan_) plan.forget_broken();
  for (const RowBlocks& plan : boundary_plan_) plan.forget_broken();
}

double Forces::strain_energy() {
  BondView view = bond_view();
  double strain = 0;
  LocalArray u(state_.displacement());
  view.u = u.data();
  current_positions(domain_.X.data(), u.data(), 0, domain_.local(), position_stride_, positions_.data());
  if (has_lattice_) strain += lattice_energy(view);
  for (std::size_t b = 0; b < laws_.size(); ++b) {
    if (marder_[b]) continue;
    strain += bond_energy(laws_[b], view, interior_by_body_[b].data(), interior_by_body_[b].size());
    strain += bond_energy(laws_[b], view, boundary_by_body_[b].data(), boundary_by_body_[b].size());
  }
  return strain;
}

const double* Forces::energy_density() {
  // Bonds (lattice bodies: 0, their energy is kept per bond direction, not per node), then the
  // long-range pairs; the current ghost displacements are those of the last force evaluation.
  BondView view = bond_view();
  LocalArray u(state_.displacement());
  view.u = u.data();
  if (!density_current_) {  // else the last force evaluation's (an energy call on this state)
    current_positions(domain_.X.data(), u.data(), 0, domain_.local(), position_stride_, positions_.data());
    energy_density_.assign(domain_.owned, 0.0);
    for (std::size_t b = 0; b < laws_.size(); ++b) {
      if (marder_[b]) continue;
      bond_energy(laws_[b], view, interior_by_body_[b].data(), interior_by_body_[b].size(), energy_density_.data());
      bond_energy(laws_[b], view, boundary_by_body_[b].data(), boundary_by_body_[b].size(), energy_density_.data());
    }
  }
  if (long_range_) {
    LongRangeForces& lr = *long_range_;
    lr.refresh(domain_.X.data(), u.data());
    std::vector<double> scratch(lr.force.size(), 0.0), share(lr.mine_local.size(), 0.0);
    long_range_pair_forces(lr.law, lr.nodes(), lr.rows.data(), static_cast<std::int64_t>(lr.rows.size()),
                           scratch.data(), lr.list, true, share.data());
    for (std::size_t k = 0; k < lr.mine_local.size(); ++k) energy_density_[lr.mine_local[k]] += share[k];
  }
  density_current_ = false;  // it holds the long-range shares now: a second call starts over
  return energy_density_.data();
}

const double* Forces::damage() {
  const BondView view = bond_view();
  for (const std::vector<std::int32_t>* rows : {&domain_.interior_rows, &domain_.boundary_rows})
    node_damage(view, rows->data(), rows->size(), damage_.data());
  return damage_.data();
}

std::vector<double> Forces::stable_time_steps(const std::vector<double>& density, std::vector<double>* undamped) {
  const BondView view = bond_view();
  const std::size_t nb = laws_.size();
  std::vector<double> dt_body(nb, std::numeric_limits<double>::infinity());
  if (undamped) undamped->clear();
  for (std::size_t b = 0; b < nb; ++b) {
    if (marder_[b]) {
      if (!interior_by_body_[b].empty() || !boundary_by_body_[b].empty())
        dt_body[b] = marder_stable_time_step(*marder_[b]);
      if (undamped) undamped->push_back(dt_body[b]);  // (its dashpots are the lattice's own)
      continue;
    }
    for (const auto* rows : {&interior_by_body_[b], &boundary_by_body_[b]})
      dt_body[b] = std::min(dt_body[b], stable_time_step(laws_[b], density[b], view, rows->data(), rows->size()));
    if (undamped) undamped->push_back(dt_body[b]);
    if (!dashpot_tau_.empty() && std::isfinite(dt_body[b]))
      dt_body[b] = dashpot_stable_time_step(dt_body[b], dashpot_tau_[b]);
  }
  return dt_body;
}

double Forces::reference_stiffness_sum() {
  const BondView view = bond_view();
  double sum = 0;
  for (std::size_t b = 0; b < laws_.size(); ++b)
    for (const auto* rows : {&interior_by_body_[b], &boundary_by_body_[b]})
      sum += peri::reference_stiffness_sum(laws_[b], view, rows->data(), rows->size());
  return sum;
}

void Forces::add_tangent(Mat J, const PetscInt* block, int components) {
  BondView view = bond_view();
  LocalArray u(state_.displacement());  // ghosts current: the loader's displacement was exchanged
  view.u = u.data();
  current_positions(domain_.X.data(), u.data(), 0, domain_.local(), position_stride_, positions_.data());
  std::vector<std::int32_t> cols;
  std::vector<PetscInt> block_cols;
  std::vector<double> blocks;
  const int bs = components;
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const PetscInt row = block[i];
    if (row < 0) continue;
    row_tangent(intact_laws_[domain_.body[i]], view, i, cols, blocks);
    const std::size_t nc = cols.size();
    block_cols.resize(nc);
    for (std::size_t k = 0; k < nc; ++k) block_cols[k] = block[cols[k]];  // -1 (no unknowns): ignored
    if (bs < 3)  // the leading bs x bs part of each 3 x 3 block, in place (row r of the 3 x 3nc row)
      for (int r = 0; r < bs; ++r)
        for (std::size_t k = 0; k < nc; ++k)
          for (int c = 0; c < bs; ++c) blocks[(r * nc + k) * bs + c] = blocks[(r * nc + k) * 3 + c];
    PERI_PETSC(MatSetValuesBlocked(J, 1, &row, static_cast<PetscInt>(nc), block_cols.data(), blocks.data(), ADD_VALUES));
  }
}

}  // namespace peri
