#include "peri/stages/simulation.hpp"

#include <petsclog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <limits>
#include <set>
#include <sstream>
#include <unordered_map>
#include <type_traits>

#include "peri/core/build_info.hpp"
#include "peri/core/json.hpp"
#include "peri/io/checkpoint.hpp"
#include "peri/core/resources.hpp"
#include "peri/io/restart.hpp"
#include "peri/io/run_dir.hpp"
#include "peri/kernels/tangent.hpp"
#include "peri/models/model.hpp"

namespace peri {
namespace {

constexpr int kCheckEvery = 20;  // steps between collective health/progress checks

struct Events {
  PetscLogEvent setup, nodes, partition, bonds, plans, forces, halo, update, output;
  Events() {
    PetscClassId id;
    PetscClassIdRegister("peridrive", &id);
    PetscLogEventRegister("PeriSetup", id, &setup);
    // Phases of PeriSetup: nodes and the neighbour search structure, the partition, this rank's
    // bond families and ghosts, and the bond loop's plans.
    PetscLogEventRegister("PeriNodes", id, &nodes);
    PetscLogEventRegister("PeriPartition", id, &partition);
    PetscLogEventRegister("PeriBonds", id, &bonds);
    PetscLogEventRegister("PeriPlans", id, &plans);
    PetscLogEventRegister("PeriForces", id, &forces);
    PetscLogEventRegister("PeriHalo", id, &halo);
    PetscLogEventRegister("PeriUpdate", id, &update);
    PetscLogEventRegister("PeriOutput", id, &output);
  }
};
const Events& events() {
  static Events e;
  return e;
}

std::string fmt(double v) {
  std::ostringstream s;
  s << std::setprecision(6) << v;
  return s.str();
}

}  // namespace

Simulation::Simulation(const Scene& scene, MPI_Comm comm, RunOptions options)
    : scene_(scene), comm_(comm), options_(std::move(options)) {
  start_ = std::chrono::steady_clock::now();
  PetscLogEventBegin(events().setup, 0, 0, 0, 0);
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &ranks_);
  mark_memory("start");

  // Nodes, and every check that needs them, before anything is allocated per rank.
  PartitionSettings partition_settings = partition_settings_from_options();
  PetscLogEventBegin(events().nodes, 0, 0, 0, 0);
  warn_large_families(estimate_size(scene_));
  check_fits(scene_, comm_, partition_settings.method == PartitionMethod::Bonds);
  stop_point();
  nodes_ = discretize(scene_);
  std::vector<std::vector<std::int64_t>> bc_nodes;
  for (const Boundary& b : scene_.boundaries)
    bc_nodes.push_back(select_nodes(nodes_, scene_, b.region, "boundaries." + b.name + ".region"));
  warn_overlapping_boundaries(bc_nodes);
  for (std::size_t b = 0; b < scene_.bodies.size(); ++b) {
    const Material& m = scene_.material(scene_.bodies[b].material);
    laws_.push_back(scene_.bodies[b].kind == BodyKind::Lattice
                        ? BondLaw{}
                        : calibrate(m, nodes_.bodies[b], scene_.bodies[b].where.str() + ": bodies." + scene_.bodies[b].name));
    density_.push_back(m.density);
    intact_laws_.push_back(laws_.back().empty() ? BondLaw{} : laws_.back().intact());
  }
  check_node_masses();
  stop_point();

  // Bonds, partition, this rank's domain and state.
  {
    double max_reach = 0;
    for (const BodyGeometry& g : nodes_.bodies) max_reach = std::max(max_reach, reach(g));
    const CellList cells(nodes_, max_reach);
    PetscLogEventEnd(events().nodes, 0, 0, 0, 0);
    mark_memory("nodes");
    PetscLogEventBegin(events().partition, 0, 0, 0, 0);
    partition_settings.method = resolve_partition_method(partition_settings.method, nodes_);  // auto: rcb or cells
    partition_ = partition_nodes(nodes_, cells, ranks_, comm_, partition_settings);
    PetscLogEventEnd(events().partition, 0, 0, 0, 0);
    stop_point();
    mark_memory("partition");
    Scene initial_cracks = scene_;  // cracks named by release stages break later
    std::erase_if(initial_cracks.cracks, [&](const Crack& c) { return scene_.released_later(c.name); });
    PetscLogEventBegin(events().bonds, 0, 0, 0, 0);
    domain_ = build_domain(initial_cracks, nodes_, cells, partition_, rank_, [] { return stop_signal() != 0; });
    PetscLogEventEnd(events().bonds, 0, 0, 0, 0);
    stop_point();  // before anything reads a domain the stop left unfinished
    if (partition_.edge_cut < 0) {  // a partitioner without a graph (rcb): the bonds to ghost nodes
      long long cut = 0, all = 0;
      for (std::int32_t i : domain_.boundary_rows)
        for (std::int64_t b = domain_.bonds.offsets[i]; b < domain_.bonds.offsets[i + 1]; ++b)
          cut += domain_.bonds.neighbor[b] >= domain_.owned;
      MPI_Allreduce(&cut, &all, 1, MPI_LONG_LONG, MPI_SUM, comm_);
      partition_.edge_cut = all / 2;  // each cut bond from both ends
    }
  }
  mark_memory("domain");
  health_.emplace(scene_, domain_, laws_, comm_);
  {
    std::vector<int> bc_natural(nodes_.size(), -1), bc(domain_.owned);  // later regions win where they overlap
    for (std::size_t b = 0; b < bc_nodes.size(); ++b)
      for (std::int64_t i : bc_nodes[b]) bc_natural[i] = static_cast<int>(b);
    for (std::int32_t i = 0; i < domain_.owned; ++i) bc[i] = bc_natural[domain_.natural[i]];
    boundaries_.emplace(scene_, std::move(bc));
  }
  if (scene_.long_range) long_range_setup();
  auto pressure = std::make_unique<Pressure>(scene_, nodes_.bodies, domain_);
  // The global node arrays and maps end here: every rank keeps its own nodes (owned and ghosts)
  // in domain_, which is all that the stages, output, checkpoints and crack tips read.
  decltype(bc_nodes)().swap(bc_nodes);
  partition_.release_maps();
  std::vector<double>().swap(nodes_.X);
  std::vector<double>().swap(nodes_.volume);
  std::vector<int>().swap(nodes_.body);
  state_ = std::make_unique<State>(domain_, comm_);
  mark_memory("state");

  const std::size_t nb = scene_.bodies.size();
  interior_by_body_.resize(nb);
  boundary_by_body_.resize(nb);
  for (std::int32_t r : domain_.interior_rows) interior_by_body_[domain_.body[r]].push_back(r);
  for (std::int32_t r : domain_.boundary_rows) boundary_by_body_[domain_.body[r]].push_back(r);
  lattice_setup();
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
  inv_density_.resize(domain_.owned);
  mass_.resize(domain_.owned);
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    inv_density_[i] = 1.0 / density_[domain_.body[i]];
    mass_[i] = density_[domain_.body[i]] * domain_.volume[i];
  }
  // The Verlet update's streams: runs of owned nodes of one body without a boundary (at most 64
  // nodes, so that a run failing the quick motion check is rechecked cheaply), and the others.
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    if (boundaries_->of(i) >= 0) continue;
    FreeRun* last = free_runs_.empty() ? nullptr : &free_runs_.back();
    if (last && last->end == i && last->body == domain_.body[i] && i - last->begin < 64)
      last->end = i + 1;
    else
      free_runs_.push_back({i, i + 1, domain_.body[i]});
  }
  {
    // The smallest energy the balance is judged against: m c_l^2 x 1e-20 summed over the nodes.
    std::vector<double> wave2(nb);
    for (std::size_t b = 0; b < nb; ++b)
      wave2[b] = marder_[b] ? marder_[b]->a
                            : std::pow(elastic_constants(laws_[b], nodes_.bodies[b], density_[b]).c_longitudinal, 2);
    energy_floor_ = energy_floor(mass_, domain_.body.data(), wave2, comm_);
  }
  force_.assign(3 * static_cast<std::size_t>(domain_.owned), 0.0);
  position_stride_ = position_plane_stride(domain_.local());
  positions_.assign(3 * static_cast<std::size_t>(position_stride_), 0.0);
  damage_.assign(domain_.owned, 0.0);

  // Stable time step (collective, per body, then the smallest) and each stage's step.
  BondView view = bond_view();
  std::vector<double> dt_body(nb, std::numeric_limits<double>::infinity());
  for (std::size_t b = 0; b < nb; ++b) {
    if (marder_[b]) {
      if (!interior_by_body_[b].empty() || !boundary_by_body_[b].empty())
        dt_body[b] = marder_stable_time_step(*marder_[b]);
      continue;
    }
    for (const auto* rows : {&interior_by_body_[b], &boundary_by_body_[b]})
      dt_body[b] = std::min(dt_body[b], stable_time_step(laws_[b], density_[b], view, rows->data(), rows->size()));
  }
  check_stable_step(dt_body);
  // Tools, whose penalty stiffness lowers the stable step, then the pressure: the loads in the
  // order their forces add up.
  auto tools = std::make_unique<Tools>(scene_, summary_.dt_stable, *state_, domain_, inv_density_, comm_);
  summary_.dt_stable = tools->stable_step(summary_.dt_stable);
  if (tools->friction())  // (natural id, tool, force) of every friction force, gathered to rank 0
    add_checkpoint_extra(
        "tool_friction", [this] { return tools_->save_friction(); },
        [this](const std::vector<double>* flat) { tools_->restore_friction(flat); });
  if (!tools->empty()) {
    tools_ = tools.get();
    loads_.push_back(std::move(tools));
  }
  if (!pressure->empty()) loads_.push_back(std::move(pressure));
  for (std::size_t s = 0; s < scene_.stages.size(); ++s) {
    const Stage& st = scene_.stages[s];
    if (st.kind != StageKind::Dynamic) {  // no time passes
      stage_dt_.push_back(0.0);
      stage_steps_.push_back(0);
      continue;
    }
    const double dt = st.dt ? *st.dt : st.safety_factor * summary_.dt_stable;
    check_stage(s, dt);
    if (dt > summary_.dt_stable && !st.allow_unstable_dt) {
      std::ostringstream msg;
      msg << st.where.str() << ": stages." << s << ".dt: time step " << fmt(dt)
          << " s exceeds the stable bound " << fmt(summary_.dt_stable)
          << " s (Silling & Askari 2005); expected dt <= " << fmt(summary_.dt_stable)
          << ", or allow_unstable_dt: true to run anyway";
      throw InputError(msg.str());
    }
    // A duration is covered exactly: n steps of duration / n (at most the requested step).
    const std::int64_t n = st.steps ? *st.steps : std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(st.duration / dt - 1e-9)));
    stage_dt_.push_back(st.steps ? dt : st.duration / static_cast<double>(n));
    stage_steps_.push_back(std::max<std::int64_t>(n, 1));
    total_steps_ += stage_steps_.back();
  }
  check_initial_state();
  output_.emplace(scene_.output, total_steps_, rank_);

  // Summary figures known now.
  std::int64_t local_bonds = domain_.bonds.size(), local_pre = domain_.initially_broken;
  MPI_Allreduce(&local_bonds, &summary_.ordered_bonds, 1, MPI_INT64_T, MPI_SUM, comm_);
  MPI_Allreduce(&local_pre, &summary_.precrack_bonds, 1, MPI_INT64_T, MPI_SUM, comm_);
  summary_.precrack_bonds /= 2;
  summary_.nodes = domain_.global_nodes;
  summary_.ranks = ranks_;
  summary_.steps = total_steps_;
  for (std::size_t s = 0; s < stage_dt_.size(); ++s)
    if (scene_.stages[s].kind == StageKind::Dynamic) {
      summary_.dt = stage_dt_[s];
      break;
    }
  double bpb = domain_.bonds.bytes_per_bond(), bpb_max = 0;
  MPI_Allreduce(&bpb, &bpb_max, 1, MPI_DOUBLE, MPI_MAX, comm_);
  summary_.bytes_per_bond = bpb_max;
  summary_.partition_seconds = partition_.seconds;
  summary_.edge_cut = partition_.edge_cut;
  summary_.partition_method = to_string(partition_settings.method);
  {
    // Balance of the bonds each rank actually holds (any partitioner).
    const double mine = static_cast<double>(domain_.bonds.size());
    double most = 0;
    MPI_Allreduce(&mine, &most, 1, MPI_DOUBLE, MPI_MAX, comm_);
    summary_.partition_balance = summary_.ordered_bonds > 0 ? most * ranks_ / double(summary_.ordered_bonds) : 1.0;
  }
  for (std::size_t b = 0; b < nb; ++b) {
    if (marder_[b]) {
      lattice_derived(b);
      continue;
    }
    const std::string p = scene_.bodies[b].name + ".";
    const ElasticConstants e = elastic_constants(laws_[b], nodes_.bodies[b], density_[b]);
    for (const auto& [key, value] : laws_[b].derived()) summary_.derived.push_back({p + key, value});
    summary_.derived.push_back({p + "horizon", laws_[b].horizon()});
    if (nodes_.bodies[b].kind == BodyKind::Fiber) {  // a bar: E and its wave speed only
      summary_.derived.push_back({p + "youngs_modulus", e.youngs});
      summary_.derived.push_back({p + "longitudinal_wave_speed", e.c_longitudinal});
      summary_.derived.push_back({p + "spacing_along_path", nodes_.bodies[b].spacing});
      summary_.derived.push_back({p + "nodes", double(nodes_.bodies[b].count)});
      continue;
    }
    summary_.derived.push_back({p + "shear_modulus", e.mu});
    summary_.derived.push_back({p + "bulk_modulus", e.bulk});
    summary_.derived.push_back({p + "youngs_modulus", e.youngs});
    summary_.derived.push_back({p + "longitudinal_wave_speed", e.c_longitudinal});
    summary_.derived.push_back({p + "shear_wave_speed", e.c_shear});
    summary_.derived.push_back({p + "rayleigh_wave_speed", e.c_rayleigh});
    summary_.derived.push_back({p + "nodes", double(nodes_.bodies[b].count)});
  }
  summary_.derived.push_back({"dt_stable", summary_.dt_stable});
  for (std::size_t s = 0; s < stage_dt_.size(); ++s) {
    if (scene_.stages[s].kind != StageKind::Dynamic) continue;
    summary_.derived.push_back({"stages." + std::to_string(s) + ".dt", stage_dt_[s]});
    summary_.derived.push_back({"stages." + std::to_string(s) + ".steps", double(stage_steps_[s])});
  }
  summary_.derived.push_back({"ordered_bonds", double(summary_.ordered_bonds)});
  resolved_ = emit_scene(scene_, derived_lines());
  if (options_.restart)
    check_restart(*options_.restart, scene_, domain_.global_nodes, summary_.ordered_bonds, stage_steps_);
  tips_ = CrackTipMonitor::create(scene_, laws_, nodes_.bodies, density_,
                                  scene_.output.series_every * *std::max_element(stage_dt_.begin(), stage_dt_.end()),
                                  domain_, comm_);
  if (tips_) {
    summary_.crack_tracking = true;
    summary_.rayleigh_wave_speed = tips_->rayleigh_wave_speed();
    summary_.crack_speed_window = tips_->window();
    // The tip history continues across restarts; the tips themselves are recomputed from damage.
    add_checkpoint_extra(
        "crack_tip_tracks", [this] { return tips_->save(); },
        [this](const std::vector<double>* flat) { tips_->restore(flat); });
  }
  mark_memory("setup");
  PetscLogEventEnd(events().setup, 0, 0, 0, 0);

  // Output last: nothing is written unless every check above passed.
  stop_point();
  if (!options_.out_dir.empty()) {
    std::string columns = tips_ ? tips_->series_columns() : std::string();
    if (tools_) columns += (columns.empty() ? "" : ",") + tools_->series_columns();
    output_->open(options_.out_dir, domain_, *state_, resolved_, scene_.output.write_velocity,
                  options_.restart ? options_.restart->step : -1, columns, tips_ != nullptr, comm_);
  }
  summary_.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

Simulation::~Simulation() = default;

BondView Simulation::bond_view() {
  return BondView{domain_.X.data(), nullptr, domain_.volume.data(), domain_.bonds.offsets.data(),
                  domain_.bonds.neighbor.data(), domain_.bonds.broken.data(), &domain_.bonds.patterns,
                  positions_.data(), position_stride_, domain_.bonds.row_broken.data()};
}

std::vector<std::string> Simulation::derived_lines() const { return peri::derived_lines(summary_); }

void Simulation::apply_initial_conditions() {
  const Initial& ic = scene_.initial;
  const double pi = 3.14159265358979323846;
  double* u;
  double* v;
  PERI_PETSC(VecGetArray(state_->displacement(), &u));
  PERI_PETSC(VecGetArray(state_->velocity(), &v));
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    double r[3];
    for (int c = 0; c < 3; ++c) r[c] = domain_.X[3 * i + c] - ic.center[c];
    for (int a = 0; a < 3; ++a) {
      u[3 * i + a] = 0;
      v[3 * i + a] = 0;
      for (int c = 0; c < 3; ++c) {
        u[3 * i + a] += ic.displacement_gradient[3 * a + c] * r[c];
        v[3 * i + a] += ic.velocity_gradient[3 * a + c] * r[c];
      }
    }
    if (ic.seed_amplitude != 0) {
      double s = ic.seed_amplitude;
      if (ic.seed_wavelength_x > 0) s *= std::sin(2 * pi * domain_.X[3 * i] / ic.seed_wavelength_x);
      if (ic.seed_wavelength_y > 0) s *= std::sin(2 * pi * domain_.X[3 * i + 1] / ic.seed_wavelength_y);
      u[3 * i + 2] += s;
    }
  }
  boundaries_->apply_initial(v);
  PERI_PETSC(VecRestoreArray(state_->velocity(), &v));
  PERI_PETSC(VecRestoreArray(state_->displacement(), &u));
}

void Simulation::compute_forces(bool with_energy, bool intact) {
  PetscLogEventBegin(events().forces, 0, 0, 0, 0);
  const std::vector<BondLaw>& laws = intact ? intact_laws_ : laws_;
  BondView view = bond_view();
  BondTally t;
  if (with_energy) {  // the bond loop writes each bond row's energy density (lattice rows: 0)
    energy_density_.assign(domain_.owned, 0.0);
    view.energy_density = energy_density_.data();
  }
  density_current_ = with_energy;
  if (has_kelvin_) {  // ghost velocities for the dashpots (not overlapped: the two ghosted Vecs
    state_->velocity_halo_begin();  // share one scatter, which holds one exchange at a time)
    state_->velocity_halo_end();
  }
  state_->halo_begin();  // interior rows need no ghost: overlap them with the exchange
  {
    LocalArray u(state_->displacement());
    std::optional<LocalArray> vel;
    if (has_kelvin_) vel.emplace(state_->velocity());
    view.u = u.data();
    current_positions(domain_.X.data(), u.data(), 0, domain_.owned, position_stride_, positions_.data());
    for (std::size_t b = 0; b < laws_.size(); ++b)
      if (!marder_[b]) bond_forces(laws[b], view, interior_plan_[b], force_.data(), with_energy, t);
    if (has_lattice_) lattice_forces(view, true, with_energy, t, vel ? vel->data() : nullptr);
  }
  PetscLogEventBegin(events().halo, 0, 0, 0, 0);
  state_->halo_end();
  PetscLogEventEnd(events().halo, 0, 0, 0, 0);
  {
    LocalArray u(state_->displacement());
    std::optional<LocalArray> vel;
    if (has_kelvin_) vel.emplace(state_->velocity());
    view.u = u.data();
    current_positions(domain_.X.data(), u.data(), domain_.owned, domain_.local(), position_stride_, positions_.data());
    for (std::size_t b = 0; b < laws_.size(); ++b)
      if (!marder_[b]) bond_forces(laws[b], view, boundary_plan_[b], force_.data(), with_energy, t);
    if (has_lattice_) lattice_forces(view, false, with_energy, t, vel ? vel->data() : nullptr);
  }
  if (has_lattice_) lattice_reduce();
  if (long_range_) {
    LocalArray u(state_->displacement());
    t.strain_energy += add_long_range_forces(u.data(), with_energy);
  }
  ledger_.bonds.dissipated += t.dissipated;
  ledger_.bonds.newly_broken += t.newly_broken;
  ledger_.bonds.strain_energy = t.strain_energy;
  PetscLogEventEnd(events().forces, 0, 0, 0, 0);
}

void Simulation::long_range_setup() {
  LongRangeState lr(PairLaw(*scene_.long_range), long_range_table(nodes_));
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const std::int64_t p = lr.table.index_of(domain_.natural[i]);
    if (p < 0) continue;
    lr.mine.push_back(p);
    lr.mine_local.push_back(i);
  }
  const int n = static_cast<int>(lr.mine.size());
  lr.counts.resize(ranks_);
  lr.displs.assign(ranks_, 0);
  MPI_Allgather(&n, 1, MPI_INT, lr.counts.data(), 1, MPI_INT, comm_);
  for (int r = 1; r < ranks_; ++r) lr.displs[r] = lr.displs[r - 1] + lr.counts[r - 1];
  lr.gathered.resize(lr.table.size());
  MPI_Allgatherv(lr.mine.data(), n, MPI_INT64_T, lr.gathered.data(), lr.counts.data(), lr.displs.data(),
                 MPI_INT64_T, comm_);
  for (int r = 0; r < ranks_; ++r) {  // positions travel as 3 doubles per node
    lr.counts[r] *= 3;
    lr.displs[r] *= 3;
  }
  lr.send.resize(3 * static_cast<std::size_t>(n));
  lr.recv.resize(3 * static_cast<std::size_t>(lr.table.size()));
  lr.x.resize(lr.recv.size());
  lr.force.resize(lr.send.size());
  // The list at the reference positions: a cutoff that takes in most of the scene would hold
  // O(N^2) pairs (12 bytes each); refuse it before anything is written.
  long_range_forces(lr.law, lr.table, lr.table.X.data(), lr.mine, lr.force.data(), lr.list, false);
  double pairs = static_cast<double>(lr.list.partner.size()), all_pairs = 0;
  MPI_Allreduce(&pairs, &all_pairs, 1, MPI_DOUBLE, MPI_SUM, comm_);
  const double per_node = all_pairs / std::max<double>(1.0, static_cast<double>(lr.table.size()));
  if (all_pairs > 2e8 || per_node > 5000) {
    std::ostringstream msg;
    msg << scene_.long_range->where.str() << ": long_range.cutoff: " << fmt(lr.law.cutoff) << " m takes in "
        << all_pairs << " node pairs, " << fmt(per_node) << " per node (with the Verlet list's skin of a quarter "
        << "cutoff) at the reference positions; expected a cutoff of a few a (length " << fmt(lr.law.length)
        << " m): at most 5000 pairs per node and 2e8 in all";
    throw InputError(msg.str());
  }
  std::fill(lr.force.begin(), lr.force.end(), 0.0);
  long_range_.emplace(std::move(lr));
}

void Simulation::gather_fiber_positions(const double* u) {
  LongRangeState& lr = *long_range_;
  for (std::size_t k = 0; k < lr.mine.size(); ++k)
    for (int c = 0; c < 3; ++c) {
      const std::size_t i = static_cast<std::size_t>(lr.mine_local[k]);
      lr.send[3 * k + c] = domain_.X[3 * i + c] + u[3 * i + c];
    }
  MPI_Allgatherv(lr.send.data(), static_cast<int>(lr.send.size()), MPI_DOUBLE, lr.recv.data(), lr.counts.data(),
                 lr.displs.data(), MPI_DOUBLE, comm_);
  for (std::size_t g = 0; g < lr.gathered.size(); ++g)
    for (int c = 0; c < 3; ++c) lr.x[3 * lr.gathered[g] + c] = lr.recv[3 * g + c];
}

double Simulation::add_long_range_forces(const double* u, bool with_energy) {
  LongRangeState& lr = *long_range_;
  gather_fiber_positions(u);
  std::fill(lr.force.begin(), lr.force.end(), 0.0);
  const double energy = long_range_forces(lr.law, lr.table, lr.x.data(), lr.mine, lr.force.data(), lr.list, with_energy);
  for (std::size_t k = 0; k < lr.mine.size(); ++k)
    for (int c = 0; c < 3; ++c) force_[3 * static_cast<std::size_t>(lr.mine_local[k]) + c] += lr.force[3 * k + c];
  return energy;
}

void Simulation::flags_changed() {
  for (const RowBlocks& plan : interior_plan_) plan.forget_broken();
  for (const RowBlocks& plan : boundary_plan_) plan.forget_broken();
}

bool Simulation::has_intact_bond(std::int32_t row) const {
  for (std::int64_t b = domain_.bonds.offsets[row]; b < domain_.bonds.offsets[row + 1]; ++b)
    if (!(domain_.bonds.broken[b] & 1)) return true;  // bit 0: broken (lattices keep other bits)
  return false;
}

void Simulation::settle_kick() {
  if (!kick_pending_) return;
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  double* v;
  PERI_PETSC(VecGetArray(state_->velocity(), &v));
  second_kick_free(v, dt_);
  PERI_PETSC(VecRestoreArray(state_->velocity(), &v));
  kick_pending_ = false;
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
}

void Simulation::second_kick_free(double* v, double dt) const {
  for (const FreeRun& r : free_runs_) {  // kick with damp_new = 1, one stream per run
    const double ir = inv_density_[r.begin];
    const std::size_t k0 = 3 * static_cast<std::size_t>(r.begin), n = 3 * static_cast<std::size_t>(r.end - r.begin);
    double* __restrict vr = v + k0;
    const double* __restrict fr = force_.data() + k0;
    for (std::size_t k = 0; k < n; ++k) vr[k] = vr[k] + 0.5 * dt * fr[k] * ir;
  }
}

void Simulation::step(bool with_energy, bool defer_kick) {
  const double dt = dt_, t0 = time_, t1 = time_ + dt;
  // Mass-proportional damping alpha (force -rho alpha v), integrated semi-implicitly:
  // v_half = (1 - alpha dt/2) v + dt/2 a(t),  v(t+dt) = (v_half + dt/2 a(t+dt)) / (1 + alpha dt/2).
  const double damp_old = 1.0 - 0.5 * damping_ * dt, damp_new = 1.0 / (1.0 + 0.5 * damping_ * dt);
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  double* u;
  double* v;
  PERI_PETSC(VecGetArray(state_->displacement(), &u));
  PERI_PETSC(VecGetArray(state_->velocity(), &v));
  Boundaries& boundaries = *boundaries_;
  double damped = 0;  // energy removed by damping: alpha m v.v dt, trapezoidal in time
  // Energy removed by lattice dashpots: the kick by the dashpot force F_d over dt/2 changes the
  // kinetic energy by F_d . (v_before + v_after)/2 dt/2 (exactly the share of F_d in
  // m (v_after^2 - v_before^2)/2), booked as dissipated with the opposite sign.
  double viscous = 0;
  const bool kelvin = has_kelvin_;
  // Half kick and drift (velocity Verlet); prescribed components follow their boundary.
  const bool damped_run = damping_ > 0;
  // Free component k of node i: half kick, drift; returns the squared motion.
  auto kick_drift = [&](std::int32_t i, std::size_t k) {
    if (damped_run) damped += mass_[i] * v[k] * v[k];
    const double before = v[k];
    v[k] = damp_old * v[k] + 0.5 * dt * force_[k] * inv_density_[i];
    if (kelvin) viscous -= viscous_[k] * domain_.volume[i] * 0.5 * (before + v[k]);
    u[k] += dt * v[k];
    return dt * dt * v[k] * v[k];
  };
  // Instability detector: no stable explicit step moves a node by a sizeable part of the spacing.
  // (A node without intact bonds flies ballistically: exact at any speed, never unstable.)
  // The first such node in local order is reported (the streams below visit the nodes in another).
  std::int32_t unstable_row = -1;
  double unstable_moved2 = 0;
  auto check_motion = [&](std::int32_t i, double moved2) {
    if (!(moved2 <= health_->motion_limit2(domain_.body[i])) && health_->unstable_node() < 0 &&
        (unstable_row < 0 || i < unstable_row) &&
        has_intact_bond(i)) {
      unstable_row = i;
      unstable_moved2 = moved2;
    }
  };
  auto kick_drift_node = [&](std::int32_t i) {
    const int bi = boundaries.of(i);
    const std::size_t k0 = 3 * static_cast<std::size_t>(i);
    double moved2 = 0;
    if (bi < 0) {  // most nodes: no per-component boundary test
      for (int c = 0; c < 3; ++c) moved2 += kick_drift(i, k0 + c);
    }
    for (int c = 0; c < 3 && bi >= 0; ++c) {
      const std::size_t k = k0 + c;
      if (boundaries.prescribes(bi, c)) {
        moved2 += boundaries.drift(i, bi, c, k, t0, t1, u, v, force_.data());
      } else {
        moved2 += kick_drift(i, k);
      }
    }
    check_motion(i, moved2);
  };
  const bool streaming = !damped_run && !kelvin;
  // The free nodes' second half kick of the step before, when it was deferred to this pass (a
  // stage, which alone sets damping and dt, begins with none pending).
  const bool pending = kick_pending_;
  kick_pending_ = false;
  if (streaming) {
    // Free runs: the same half kick and drift as kick_drift (damp_old = 1), one contiguous
    // stream of 3 (end - begin) components. Each component within (motion limit)^2 / 3 bounds
    // the node's squared motion by the limit; a run with any component beyond it (or a NaN) is
    // checked node by node.
    for (const FreeRun& r : free_runs_) {
      const double ir = inv_density_[r.begin];
      const double v2_third = health_->motion_limit2(r.body) / (3 * dt * dt) * (1 - 1e-12);
      const std::size_t k0 = 3 * static_cast<std::size_t>(r.begin), n = 3 * static_cast<std::size_t>(r.end - r.begin);
      double* __restrict vr = v + k0;
      double* __restrict ur = u + k0;
      const double* __restrict fr = force_.data() + k0;
      auto stream = [&](auto both) {  // (a compile-time choice: a test in the loop kept it scalar)
        for (std::size_t k = 0; k < n; ++k) {
          double vk = vr[k] + 0.5 * dt * fr[k] * ir;
          if constexpr (decltype(both)::value) vk = vk + 0.5 * dt * fr[k] * ir;  // two kicks, each rounded alone
          vr[k] = vk;
          ur[k] += dt * vk;
        }
      };
      if (pending) stream(std::true_type{});
      else stream(std::false_type{});
      int slow = 0;
      for (std::size_t k = 0; k < n; ++k) slow |= !(vr[k] * vr[k] <= v2_third);
      if (slow)
        for (std::int32_t i = r.begin; i < r.end; ++i) {
          const std::size_t k = 3 * static_cast<std::size_t>(i);
          check_motion(i, dt * dt * v[k] * v[k] + dt * dt * v[k + 1] * v[k + 1] + dt * dt * v[k + 2] * v[k + 2]);
        }
    }
    for (std::int32_t i : boundaries.rows()) kick_drift_node(i);
  } else {
    for (std::int32_t i = 0; i < domain_.owned; ++i) kick_drift_node(i);
  }
  if (unstable_row >= 0) health_->note_unstable(domain_.natural[unstable_row], std::sqrt(unstable_moved2));
  PERI_PETSC(VecRestoreArray(state_->displacement(), &u));
  PERI_PETSC(VecRestoreArray(state_->velocity(), &v));
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
  // Forces at x(t + dt); lattice dashpots see the half-step velocity v(t + dt/2) (README
  // "Kelvin dissipation").
  compute_forces(with_energy);
  add_load_forces(t1, true);
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  PERI_PETSC(VecGetArray(state_->velocity(), &v));
  // Free component k of node i: second half kick.
  auto kick = [&](std::int32_t i, std::size_t k) {
    const double before = v[k];
    v[k] = damp_new * (v[k] + 0.5 * dt * force_[k] * inv_density_[i]);
    if (kelvin) viscous -= viscous_[k] * domain_.volume[i] * 0.5 * (before + v[k]);
    if (damped_run) damped += mass_[i] * v[k] * v[k];
  };
  auto kick_node = [&](std::int32_t i) {
    const int bi = boundaries.of(i);
    const std::size_t k0 = 3 * static_cast<std::size_t>(i);
    for (int c = 0; c < 3; ++c) {
      const std::size_t k = k0 + c;
      if (bi >= 0 && boundaries.prescribes(bi, c)) {
        ledger_.external_work += boundaries.reaction_work(i, c, k, v, force_.data(), domain_.volume[i], mass_[i]);
      } else {
        kick(i, k);
      }
    }
  };
  if (streaming) {
    // The free nodes' second half kick: now, or (defer_kick, no tool reading v below) in the next
    // step's first pass, which then reads and writes velocity once for both kicks.
    if (defer_kick && !tools_) {
      kick_pending_ = true;
    } else {
      second_kick_free(v, dt);
    }
    for (std::int32_t i : boundaries.rows()) kick_node(i);
  } else {
    for (std::int32_t i = 0; i < domain_.owned; ++i) kick_node(i);
  }
  // The loads' work that needs the velocity just computed (friction).
  for (const auto& load : loads_) load->end_step(dt, v, ledger_);
  PERI_PETSC(VecRestoreArray(state_->velocity(), &v));
  if (damping_ > 0) ledger_.damping_work += 0.5 * damping_ * dt * damped;
  if (kelvin) ledger_.damping_work += 0.5 * dt * viscous;
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
  time_ = t1;
  ++step_;
}

void Simulation::add_load_forces(double t, bool book) {
  if (loads_.empty()) return;
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  const LoadTarget target{positions_.data(), position_stride_, force_.data(), dt_};
  for (const auto& load : loads_) load->add_forces(t, target, book, ledger_);
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
}

double Simulation::kinetic_energy() {
  settle_kick();
  const VecArrayRead v(state_->velocity());
  return peri::kinetic_energy(v.data(), mass_, comm_);
}

EnergyRow Simulation::energies() {
  // Strain energy of the current state from a separate (non-breaking) pass.
  BondView view = bond_view();
  double strain = 0;
  {
    LocalArray u(state_->displacement());
    view.u = u.data();
    current_positions(domain_.X.data(), u.data(), 0, domain_.local(), position_stride_, positions_.data());
    if (has_lattice_) strain += lattice_energy(view);
    for (std::size_t b = 0; b < laws_.size(); ++b) {
      if (marder_[b]) continue;
      strain += bond_energy(laws_[b], view, interior_by_body_[b].data(), interior_by_body_[b].size());
      strain += bond_energy(laws_[b], view, boundary_by_body_[b].data(), boundary_by_body_[b].size());
    }
  }
  return reduce_energies(strain);
}

double Simulation::energy_balance_error(const EnergyRow& row) const {
  return peri::energy_balance_error(row, summary_.initial_total_energy, energy_floor_);
}

EnergyRow Simulation::reduce_energies(double local_strain) {
  const double kinetic = kinetic_energy();
  return peri::reduce_energies(ledger_, local_strain, kinetic, step_, time_, comm_);
}

void Simulation::write_series_row() {
  const EnergyRow row = reduce_energies(ledger_.bonds.strain_energy);
  // Energy growth detector (after the first row, which sets the reference).
  if (step_ > 0)
    health_->check_energy(row, energy_balance_error(row), summary_.initial_total_energy, dt_, summary_.dt_stable);
  std::string extra;
  if (tips_) {
    extra = tips_->sample(row, [this] {
      update_damage();
      return damage_.data();
    });
    output_->write_tips(tips_->csv_rows(row));
  }
  if (tools_) extra += tools_->series_values(time_, !extra.empty());
  output_->write_series(row, extra);
  summary_.final_energy = row;
}

void Simulation::mark_memory(const char* phase) { peri::mark_memory(summary_, phase, comm_); }

void Simulation::update_energy_density() {
  // Bonds (lattice bodies: 0, their energy is kept per bond direction, not per node), then the
  // long-range pairs; the current ghost displacements are those of the last force evaluation.
  BondView view = bond_view();
  LocalArray u(state_->displacement());
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
    LongRangeState& lr = *long_range_;
    gather_fiber_positions(u.data());
    std::vector<double> scratch(lr.force.size(), 0.0), share(lr.mine.size(), 0.0);
    long_range_forces(lr.law, lr.table, lr.x.data(), lr.mine, scratch.data(), lr.list, true, share.data());
    for (std::size_t k = 0; k < lr.mine.size(); ++k) energy_density_[lr.mine_local[k]] += share[k];
  }
  density_current_ = false;  // it holds the long-range shares now: a second call starts over
}

void Simulation::write_frame() {
  settle_kick();
  PetscLogEventBegin(events().output, 0, 0, 0, 0);
  const auto t0 = std::chrono::steady_clock::now();
  update_damage();
  update_energy_density();
  const double* u;
  const double* v;
  PERI_PETSC(VecGetArrayRead(state_->displacement(), &u));
  PERI_PETSC(VecGetArrayRead(state_->velocity(), &v));
  output_->write_frame(step_, time_, u, v, damage_.data(), energy_density_.data());
  PERI_PETSC(VecRestoreArrayRead(state_->velocity(), &v));
  PERI_PETSC(VecRestoreArrayRead(state_->displacement(), &u));
  summary_.output_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  PetscLogEventEnd(events().output, 0, 0, 0, 0);
}

void Simulation::check_health(std::int64_t step, double time) {
  settle_kick();
  {
    const VecArrayRead u(state_->displacement()), v(state_->velocity());
    health_->check(step, time, u.data(), v.data(), dt_, summary_.dt_stable);
  }
  if (options_.quiet) return;
  const auto now = std::chrono::steady_clock::now();
  int print = rank_ == 0 && std::chrono::duration<double>(now - last_progress_).count() >= scene_.output.progress_seconds;
  MPI_Bcast(&print, 1, MPI_INT, 0, comm_);
  if (!print) return;
  long long broken_local = ledger_.bonds.newly_broken, broken = 0;
  MPI_Reduce(&broken_local, &broken, 1, MPI_LONG_LONG, MPI_SUM, 0, comm_);
  if (rank_ == 0) {
    const double elapsed = std::chrono::duration<double>(now - loop_start_).count();
    const double rate = (step - loop_start_step_) / std::max(elapsed, 1e-9);
    std::printf("[peridrive] step %lld/%lld  t = %.4g s  %.0f steps/s  ETA %.0f s  broken bonds %lld\n",
                static_cast<long long>(step), static_cast<long long>(total_steps_), time, rate,
                (total_steps_ - step) / std::max(rate, 1e-9), broken / 2);
    std::fflush(stdout);
  }
  last_progress_ = now;
}

void Simulation::run() {
  begin();
  advance(total_steps_);
  if (!cadence_.stopped()) finish();
}

void Simulation::begin() {
  cadence_.start(options_.restart ? options_.restart->step : -1);
  if (options_.restart) {
    restore(*options_.restart);
    return;
  }
  apply_initial_conditions();
  // Stages that take no time and come first (preload, release) shape the initial state.
  while (stage_ < scene_.stages.size() && scene_.stages[stage_].kind != StageKind::Dynamic) {
    start_stage();
    ++stage_;
  }
  compute_forces(true);
  add_load_forces(time_, false);
  write_series_row();
  summary_.initial_total_energy = summary_.final_energy.total();
  // Without a leading preload the whole run's balance starts here too (run_quasistatic sets it
  // before the first preload's work).
  if (summary_.quasistatic.empty()) summary_.run_initial_total_energy = summary_.initial_total_energy;
  if (output_->frame_due(0)) write_frame();
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] %lld nodes, %lld bonds, %d rank%s; dt = %.4g s (stable bound %.4g s), %lld steps; bond kernel %s\n",
                static_cast<long long>(summary_.nodes), static_cast<long long>(summary_.ordered_bonds / 2),
                ranks_, ranks_ > 1 ? "s" : "", summary_.dt, summary_.dt_stable,
                static_cast<long long>(total_steps_), bond_kernel_isa());
    std::fflush(stdout);
  }
  loop_start_ = std::chrono::steady_clock::now();
  loop_start_step_ = step_;
  output_seconds_at_loop_start_ = summary_.output_seconds;  // the first frame is not the loop's
  last_progress_ = loop_start_;
}

void Simulation::start_stage() {
  settle_kick();  // with the force and time step it was deferred with
  const Stage& st = scene_.stages[stage_];
  if (st.kind == StageKind::QuasiStatic) {
    run_quasistatic(st);
    return;
  }
  if (st.kind == StageKind::Release) {
    run_release(st);
    return;
  }
  dt_ = stage_dt_[stage_];
  damping_ = st.damping;
  boundaries_->start_stage(st);
}

std::int64_t Simulation::advance(std::int64_t n) {
  std::int64_t taken = 0;
  while (stage_ < scene_.stages.size() && !cadence_.stopped()) {
    if (scene_.stages[stage_].kind != StageKind::Dynamic) {
      // A later stage that takes no time: run it, and restart the energy balance after a
      // quasi-static one (it removes kinetic energy by construction).
      start_stage();
      ++stage_;
      compute_forces(true);
      add_load_forces(time_, false);
      write_series_row();
      if (scene_.stages[stage_ - 1].kind == StageKind::QuasiStatic)
        summary_.initial_total_energy = summary_.final_energy.total();
      continue;
    }
    if (!stage_started_) {
      start_stage();
      stage_started_ = true;
    }
    if (stage_step_ >= stage_steps_[stage_]) {
      ++stage_;
      stage_step_ = 0;
      stage_started_ = false;
      continue;
    }
    if (taken >= n) break;
    const bool series = (step_ + 1) % scene_.output.series_every == 0 || step_ + 1 == total_steps_;
    // A frame's step is an energy call too: the bond loop then writes the energy density.
    const bool frame_next = output_->frame_due(step_ + 1);
    step(series || frame_next, true);
    ++stage_step_;
    ++taken;
    const bool frame = output_->frame_due(step_);
    // Nothing is written before the state is checked: no non-finite value reaches a file.
    // (Each reader of the velocity applies a deferred kick first: settle_kick().)
    if (series || frame || step_ % kCheckEvery == 0 || step_ == total_steps_) check_health(step_, time_);
    if (series) write_series_row();
    if (frame) write_frame();
    if (cadence_.due(step_, step_ % kCheckEvery == 0 || step_ == total_steps_)) write_checkpoint();
  }
  settle_kick();  // v(t) whole when the call returns
  return taken;
}

void Simulation::run_release(const Stage& stage) {
  // Break every intact bond crossing the named cracks in the current (e.g. preloaded) state; its
  // current energy becomes dissipated energy, so the energy balance continues exactly.
  std::vector<const Crack*> cracks;
  for (const std::string& name : stage.cracks)
    for (const Crack& c : scene_.cracks)
      if (c.name == name) cracks.push_back(&c);
  state_->halo_begin();
  state_->halo_end();
  LocalArray u(state_->displacement());
  std::int64_t released = 0;
  double energy = 0;
  const BondView view = bond_view();
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const BondLaw& law = laws_[domain_.body[i]];
    const double* Xi = &domain_.X[3 * static_cast<std::size_t>(i)];
    for (std::int64_t b = domain_.bonds.offsets[i]; b < domain_.bonds.offsets[i + 1]; ++b) {
      if (domain_.bonds.broken[b]) continue;
      const std::int32_t j = domain_.bonds.neighbor[b];
      const double* Xj = &domain_.X[3 * static_cast<std::size_t>(j)];
      bool cut = false;
      for (const Crack* c : cracks) cut = cut || crosses(Xi, Xj, *c);
      if (!cut) continue;
      double y2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double e = Xj[c] - Xi[c] + u.data()[3 * j + c] - u.data()[3 * i + c];
        y2 += e * e;
      }
      energy += 0.5 * domain_.volume[i] * view.measure(i, b) * law.energy(view.xi2(i, b), y2);  // eq. (5), one end
      domain_.bonds.broken[b] = 1;
      domain_.bonds.row_broken[i] = 1;
      ++released;
    }
  }
  flags_changed();
  ledger_.bonds.dissipated += energy;
  ledger_.bonds.newly_broken += released;
  long long global = 0, local = released;
  MPI_Allreduce(&local, &global, 1, MPI_LONG_LONG, MPI_SUM, comm_);
  summary_.precrack_bonds += global / 2;
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] release '%s': %lld bonds broken\n", stage.name.c_str(), global / 2);
    std::fflush(stdout);
  }
  if (global == 0)
    throw InputError(stage.where.str() + ": stages." + stage.name + ".cracks: no intact bond crosses the named cracks");
}

std::unique_ptr<QuasiStaticLoader> Simulation::make_loader(const Stage& stage) {
  std::vector<PetscInt> d_nnz(domain_.owned), o_nnz(domain_.owned);
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    PetscInt d = 1, o = 0;
    for (std::int64_t b = domain_.bonds.offsets[i]; b < domain_.bonds.offsets[i + 1]; ++b)
      (domain_.bonds.neighbor[b] < domain_.owned ? d : o) += 1;
    d_nnz[i] = d;
    o_nnz[i] = o;
  }
  BondView view = bond_view();
  double local[2] = {0, double(domain_.owned)}, global[2];
  for (std::size_t b = 0; b < laws_.size(); ++b)
    for (const auto* rows : {&interior_by_body_[b], &boundary_by_body_[b]})
      local[0] += reference_stiffness_sum(laws_[b], view, rows->data(), rows->size());
  MPI_Allreduce(local, global, 2, MPI_DOUBLE, MPI_SUM, comm_);
  double spacing = INFINITY;
  for (const Body& b : scene_.bodies) spacing = std::min(spacing, b.spacing);
  return std::make_unique<QuasiStaticLoader>(comm_, domain_.owned, d_nnz, o_nnz, global[0] / std::max(global[1], 1.0),
                                             spacing, stage);
}

void Simulation::run_quasistatic(const Stage& stage) {
  const std::size_t n = 3 * static_cast<std::size_t>(domain_.owned);
  std::vector<std::uint8_t> constrained(n, 0);
  std::vector<double> increment(n, 0.0);
  boundaries_->quasistatic_targets(stage, domain_, constrained, increment);
  // Flat membranes under in-plane load have no out-of-plane stiffness at the flat state.
  if (stage.in_plane)
    for (std::int32_t i = 0; i < domain_.owned; ++i)
      if (scene_.bodies[domain_.body[i]].kind == BodyKind::Membrane) constrained[3 * static_cast<std::size_t>(i) + 2] = 1;
  const EnergyRow before = energies();
  if (step_ == 0 && summary_.quasistatic.empty()) summary_.run_initial_total_energy = before.total();
  std::unique_ptr<QuasiStaticLoader> loader = make_loader(stage);
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] quasistatic '%s': %ld initial load steps\n", stage.name.c_str(), stage.load_steps);
    std::fflush(stdout);
  }
  QuasiStaticStats stats = loader->run(*this, constrained, increment, !options_.quiet);
  ledger_.external_work += stats.external_work;
  // Equilibrium: at rest.
  PERI_PETSC(VecSet(state_->velocity(), 0.0));
  const EnergyRow after = energies();
  double work = 0, local = stats.external_work;
  MPI_Allreduce(&local, &work, 1, MPI_DOUBLE, MPI_SUM, comm_);
  stats.external_work = work;
  const double stored = (after.strain - before.strain) + (after.dissipated - before.dissipated) - before.kinetic;
  summary_.quasistatic.push_back({stage.name, stats});
  summary_.quasistatic_work_error.push_back(std::fabs(work - stored) / std::max(std::fabs(work), 1e-300));
  // Work the supports did that the body neither holds nor dissipated: bonds that break between
  // two equilibria (a preload that tears the sheet) release energy no stage follows. The explicit
  // part's balance restarts after this stage and would not show it; run_energy_balance_error does.
  const double tolerance = scene_.stability.energy_error;
  if (rank_ == 0 && tolerance > 0 && !(summary_.quasistatic_work_error.back() <= tolerance))
    std::fprintf(stderr,
                 "peridrive: warning: %s: stages.%zu ('%s'): the quasi-static supports did %.6g J of work, but "
                 "the body stores and dissipated %.6g J (%.3g%% apart, more than stability.energy_error = %g; "
                 "%lld bonds broke in the stage); summary.json's run_energy_balance_error counts the difference\n",
                 stage.where.str().c_str(), stage_, stage.name.c_str(), work, stored,
                 100 * summary_.quasistatic_work_error.back(), tolerance, static_cast<long long>(stats.broken));
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] quasistatic '%s': %zu increments, %d cut-backs, %ld Newton and %ld linear iterations, "
                "%lld bonds broken, %.3g s; support work %.6g J vs stored + dissipated %.6g J\n",
                stage.name.c_str(), stats.increments.size(), stats.cutbacks, stats.newton_iterations,
                stats.linear_iterations, static_cast<long long>(stats.broken), stats.seconds, work, stored);
    std::fflush(stdout);
  }
}

void Simulation::set_displacement(const double* u_owned) {
  double* u;
  PERI_PETSC(VecGetArray(state_->displacement(), &u));
  std::copy(u_owned, u_owned + 3 * static_cast<std::size_t>(domain_.owned), u);
  PERI_PETSC(VecRestoreArray(state_->displacement(), &u));
  density_current_ = false;
  state_->halo_begin();
  state_->halo_end();
}

void Simulation::get_displacement(double* u_owned) {
  const double* u;
  PERI_PETSC(VecGetArrayRead(state_->displacement(), &u));
  std::copy(u, u + 3 * static_cast<std::size_t>(domain_.owned), u_owned);
  PERI_PETSC(VecRestoreArrayRead(state_->displacement(), &u));
}

void Simulation::internal_force(double* f_owned) {
  compute_forces(false, true);
  for (std::int32_t i = 0; i < domain_.owned; ++i)
    for (int c = 0; c < 3; ++c) f_owned[3 * i + c] = force_[3 * i + c] * domain_.volume[i];
}

void Simulation::add_tangent(Mat J) {
  BondView view = bond_view();
  LocalArray u(state_->displacement());  // ghosts current: set_displacement exchanged them
  view.u = u.data();
  current_positions(domain_.X.data(), u.data(), 0, domain_.local(), position_stride_, positions_.data());
  std::vector<std::int32_t> cols;
  std::vector<PetscInt> global_cols;
  std::vector<double> blocks;
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    row_tangent(intact_laws_[domain_.body[i]], view, i, cols, blocks);
    global_cols.resize(cols.size());
    for (std::size_t k = 0; k < cols.size(); ++k) global_cols[k] = static_cast<PetscInt>(domain_.global[cols[k]]);
    const PetscInt row = static_cast<PetscInt>(domain_.global[i]);
    PERI_PETSC(MatSetValuesBlocked(J, 1, &row, static_cast<PetscInt>(cols.size()), global_cols.data(), blocks.data(),
                                   ADD_VALUES));
  }
}

std::int64_t Simulation::break_bonds() {
  const std::int64_t before = ledger_.bonds.newly_broken;
  compute_forces(false);
  long long local = ledger_.bonds.newly_broken - before, global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_LONG_LONG, MPI_SUM, comm_);
  return global / 2;
}

void Simulation::finish() {
  const auto t_end = std::chrono::steady_clock::now();
  summary_.step_seconds = std::chrono::duration<double>(t_end - loop_start_).count() -
                          (summary_.output_seconds - output_seconds_at_loop_start_);
  summary_.steps_timed = step_ - loop_start_step_;
  summary_.wall_seconds = std::chrono::duration<double>(t_end - start_).count();
  summary_.simulated_time = time_;
  summary_.frames = output_->frames();
  summary_.energy_balance_error = energy_balance_error(summary_.final_energy);
  summary_.run_energy_balance_error =
      peri::energy_balance_error(summary_.final_energy, summary_.run_initial_total_energy, energy_floor_);
  if (tips_) {
    summary_.max_crack_speed = tips_->max_speed();
    summary_.mean_crack_speed = tips_->mean_speed();
    summary_.crack_tips_json = tips_->tracks_json();
    summary_.crack_tip_seconds = tips_->seconds();
  }
  // Timings of the slowest rank: the job's figures.
  double times[4] = {summary_.step_seconds, summary_.output_seconds, summary_.wall_seconds,
                     summary_.crack_tip_seconds}, tmax[4];
  MPI_Allreduce(times, tmax, 4, MPI_DOUBLE, MPI_MAX, comm_);
  summary_.crack_tip_seconds = tmax[3];
  summary_.step_seconds = tmax[0];
  summary_.output_seconds = tmax[1];
  summary_.wall_seconds = tmax[2];
  mark_memory("end");
  output_->write_summary(summary_.to_json());
}

std::vector<double> Simulation::gather_natural(const double* owned, int bs) {
  const double* slice = state_->to_natural(owned, bs);
  const int n = static_cast<int>(bs * state_->natural_count());
  std::vector<int> counts(ranks_), displs(ranks_, 0);
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
  for (int r = 1; r < ranks_; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(static_cast<std::size_t>(bs) * domain_.global_nodes);
  MPI_Allgatherv(slice, n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, comm_);
  return all;
}

std::vector<double> Simulation::natural_positions() {
  const double* u;
  PERI_PETSC(VecGetArrayRead(state_->displacement(), &u));
  std::vector<double> x(3 * static_cast<std::size_t>(domain_.owned));
  for (std::size_t a = 0; a < x.size(); ++a) x[a] = domain_.X[a] + u[a];
  PERI_PETSC(VecRestoreArrayRead(state_->displacement(), &u));
  return gather_natural(x.data(), 3);
}

std::vector<double> Simulation::natural_velocities() {
  settle_kick();
  const double* v;
  PERI_PETSC(VecGetArrayRead(state_->velocity(), &v));
  std::vector<double> copy(v, v + 3 * static_cast<std::size_t>(domain_.owned));
  PERI_PETSC(VecRestoreArrayRead(state_->velocity(), &v));
  return gather_natural(copy.data(), 3);
}

void Simulation::update_damage() {
  const BondView view = bond_view();
  for (const std::vector<std::int32_t>* rows : {&domain_.interior_rows, &domain_.boundary_rows})
    node_damage(view, rows->data(), rows->size(), damage_.data());
}

std::vector<double> Simulation::natural_damage() {
  update_damage();
  return gather_natural(damage_.data(), 1);
}

std::vector<std::pair<std::int64_t, std::int64_t>> Simulation::broken_bonds() {
  std::vector<long long> mine;
  for (std::int32_t i = 0; i < domain_.owned; ++i)
    for (std::int64_t b = domain_.bonds.offsets[i]; b < domain_.bonds.offsets[i + 1]; ++b)
      if (domain_.bonds.broken[b] & 1) {  // bit 0: broken (lattices keep other bits)
        const long long a = domain_.natural[i], c = domain_.natural[domain_.bonds.neighbor[b]];
        if (a < c) mine.insert(mine.end(), {a, c});
        else mine.insert(mine.end(), {c, a});
      }
  const int n = static_cast<int>(mine.size());
  std::vector<int> counts(ranks_), displs(ranks_, 0);
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
  for (int r = 1; r < ranks_; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<long long> all(displs.back() + counts.back());
  MPI_Allgatherv(mine.data(), n, MPI_LONG_LONG, all.data(), counts.data(), displs.data(), MPI_LONG_LONG, comm_);
  std::set<std::pair<std::int64_t, std::int64_t>> set;
  for (std::size_t k = 0; k < all.size(); k += 2) set.insert({all[k], all[k + 1]});
  return {set.begin(), set.end()};
}

std::array<double, 6> Simulation::momentum() {
  const VecArrayRead u(state_->displacement()), v(state_->velocity());
  return peri::momentum(domain_.X.data(), u.data(), v.data(), mass_, comm_);
}

}  // namespace peri

// ------------------------------------------------------------------------------------------------
// Checkpoints and restart

namespace peri {

void Simulation::add_checkpoint_extra(std::string name, std::function<std::vector<double>()> save,
                                      std::function<void(const std::vector<double>*)> restore) {
  extras_.add(std::move(name), std::move(save), std::move(restore));
}

Checkpoint Simulation::make_checkpoint() {
  return peri::make_checkpoint(scene_, domain_, *state_, ledger_, {step_, time_, stage_, stage_step_}, summary_, extras_,
                               comm_);
}

void Simulation::write_checkpoint() {
  settle_kick();
  PetscLogEventBegin(events().output, 0, 0, 0, 0);
  const auto t0 = std::chrono::steady_clock::now();
  store_checkpoint(checkpoint_path(), make_checkpoint(), comm_);
  cadence_.written(step_);
  summary_.output_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  PetscLogEventEnd(events().output, 0, 0, 0, 0);
}

void Simulation::restore(const Checkpoint& c) {
  restore_state(c, domain_, *state_, ledger_, comm_);
  flags_changed();
  restore_summary(c, scene_, summary_);
  step_ = c.step;
  time_ = c.time;
  stage_ = static_cast<std::size_t>(c.stage);
  stage_step_ = c.stage_step;
  summary_.initial_total_energy = c.initial_total_energy;
  extras_.restore(c);

  // Forces at the restored positions, computed as the uninterrupted run did at the end of this
  // step; every bond past its critical stretch there is already broken, so none breaks now.
  compute_forces(true);
  add_load_forces(time_, false);
  summary_.final_energy = reduce_energies(ledger_.bonds.strain_energy);
  output_->skip_frames_through(step_);
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] resumed at step %lld/%lld (t = %.6g s) from a checkpoint written on %d rank%s\n",
                static_cast<long long>(step_), static_cast<long long>(total_steps_), time_, c.ranks,
                c.ranks > 1 ? "s" : "");
    std::fflush(stdout);
  }
  loop_start_ = std::chrono::steady_clock::now();
  loop_start_step_ = step_;  // the steps before the checkpoint were timed by the run that took them
  output_seconds_at_loop_start_ = summary_.output_seconds;  // the first frame is not the loop's
  last_progress_ = loop_start_;
}

}  // namespace peri
