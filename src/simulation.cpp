#include "peri/simulation.hpp"

#include <petsclog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <limits>
#include <set>
#include <sstream>

#include "peri/build_info.hpp"

namespace peri {
namespace {

constexpr int kCheckEvery = 20;  // steps between collective health/progress checks
constexpr int kTipColumns = 4;   // crack tip tracks with their own columns in series.csv

// Velocity ramp: v(t) = v_target * ramp(t); its integral P(t) gives exact prescribed displacements.
double ramp(double t, double tr) { return tr > 0 ? std::min(t / tr, 1.0) : 1.0; }
double ramp_integral(double t, double tr) {
  if (tr <= 0) return t;
  return t < tr ? 0.5 * t * t / tr : t - 0.5 * tr;
}

struct Events {
  PetscLogEvent setup, forces, halo, update, output;
  Events() {
    PetscClassId id;
    PetscClassIdRegister("peridrive", &id);
    PetscLogEventRegister("PeriSetup", id, &setup);
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

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream s;
  s << std::setprecision(12) << v;
  return s.str();
}

}  // namespace

std::string RunSummary::to_json() const {
  std::ostringstream j;
  j << "{\n"
    << "  \"peridrive_version\": \"" << version() << "\",\n"
    << "  \"git_revision\": \"" << git_revision() << "\",\n"
    << "  \"nodes\": " << nodes << ",\n"
    << "  \"bonds\": " << ordered_bonds / 2 << ",\n"
    << "  \"ordered_bonds\": " << ordered_bonds << ",\n"
    << "  \"ranks\": " << ranks << ",\n"
    << "  \"dt\": " << json_number(dt) << ",\n"
    << "  \"dt_stable\": " << json_number(dt_stable) << ",\n"
    << "  \"steps\": " << steps << ",\n"
    << "  \"simulated_time\": " << json_number(simulated_time) << ",\n"
    << "  \"frames\": " << frames << ",\n"
    << "  \"wall_seconds\": " << json_number(wall_seconds) << ",\n"
    << "  \"setup_seconds\": " << json_number(setup_seconds) << ",\n"
    << "  \"step_seconds\": " << json_number(step_seconds) << ",\n"
    << "  \"output_seconds\": " << json_number(output_seconds) << ",\n"
    << "  \"bond_updates_per_second\": "
    << json_number(step_seconds > 0 ? double(ordered_bonds) * steps / step_seconds : 0) << ",\n"
    << "  \"bond_updates_per_second_per_rank\": "
    << json_number(step_seconds > 0 ? double(ordered_bonds) * steps / step_seconds / ranks : 0) << ",\n"
    << "  \"bytes_per_bond\": " << json_number(bytes_per_bond) << ",\n"
    << "  \"partition_seconds\": " << json_number(partition_seconds) << ",\n"
    << "  \"edge_cut\": " << edge_cut << ",\n"
    << "  \"precrack_bonds\": " << precrack_bonds << ",\n"
    << "  \"broken_bonds\": " << final_energy.broken_bonds << ",\n"
    << "  \"final\": {\"kinetic_energy\": " << json_number(final_energy.kinetic)
    << ", \"strain_energy\": " << json_number(final_energy.strain)
    << ", \"external_work\": " << json_number(final_energy.external_work)
    << ", \"dissipated_energy\": " << json_number(final_energy.dissipated)
    << ", \"total_energy\": " << json_number(final_energy.total()) << "},\n"
    << "  \"initial_total_energy\": " << json_number(initial_total_energy) << ",\n"
    << "  \"energy_balance_error\": " << json_number(energy_balance_error) << ",\n";
  if (crack_tracking)
    j << "  \"crack_tips\": " << crack_tips_json << ",\n"
      << "  \"max_crack_speed\": " << json_number(max_crack_speed) << ",\n"
      << "  \"mean_crack_speed\": " << json_number(mean_crack_speed) << ",\n"
      << "  \"crack_speed_window\": " << json_number(crack_speed_window) << ",\n"
      << "  \"crack_tip_seconds\": " << json_number(crack_tip_seconds) << ",\n"
      << "  \"rayleigh_wave_speed\": " << json_number(rayleigh_wave_speed) << ",\n"
      << "  \"max_crack_speed_over_rayleigh\": " << json_number(max_crack_speed / rayleigh_wave_speed) << ",\n"
      << "  \"mean_crack_speed_over_rayleigh\": " << json_number(mean_crack_speed / rayleigh_wave_speed) << ",\n";
  j << "  \"derived\": {";  for (std::size_t k = 0; k < derived.size(); ++k)
    j << (k ? ", " : "") << "\"" << derived[k].first << "\": " << json_number(derived[k].second);
  j << "}\n}\n";
  return j.str();
}

Simulation::Simulation(const Scene& scene, MPI_Comm comm, RunOptions options)
    : scene_(scene), comm_(comm), options_(std::move(options)) {
  start_ = std::chrono::steady_clock::now();
  PetscLogEventBegin(events().setup, 0, 0, 0, 0);
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &ranks_);

  // Nodes, and every check that needs them, before anything is allocated per rank.
  nodes_ = discretize(scene_);
  std::vector<std::vector<std::int64_t>> bc_nodes;
  for (const Boundary& b : scene_.boundaries)
    bc_nodes.push_back(select_nodes(nodes_, scene_, b.region, "boundaries." + b.name + ".region"));
  for (std::size_t b = 0; b < scene_.bodies.size(); ++b) {
    const Material& m = scene_.material(scene_.bodies[b].material);
    laws_.push_back(calibrate(m, nodes_.bodies[b], scene_.bodies[b].where.str() + ": bodies." + scene_.bodies[b].name));
    density_.push_back(m.density);
  }

  // Bonds, partition, this rank's domain and state.
  double max_reach = 0;
  for (const BodyGeometry& g : nodes_.bodies) max_reach = std::max(max_reach, reach(g));
  CellList cells(nodes_, max_reach);
  partition_ = partition_nodes(nodes_, cells, ranks_, comm_);
  domain_ = build_domain(scene_, nodes_, cells, partition_, rank_);
  state_ = std::make_unique<State>(domain_, comm_);

  const std::size_t nb = scene_.bodies.size();
  interior_by_body_.resize(nb);
  boundary_by_body_.resize(nb);
  for (std::int32_t r : domain_.interior_rows) interior_by_body_[domain_.body[r]].push_back(r);
  for (std::int32_t r : domain_.boundary_rows) boundary_by_body_[domain_.body[r]].push_back(r);
  inv_density_.resize(domain_.owned);
  mass_.resize(domain_.owned);
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    inv_density_[i] = 1.0 / density_[domain_.body[i]];
    mass_[i] = density_[domain_.body[i]] * domain_.volume[i];
  }
  force_.assign(3 * static_cast<std::size_t>(domain_.owned), 0.0);
  prev_force_ = force_;
  damage_.assign(domain_.owned, 0.0);
  bc_.assign(domain_.owned, -1);
  du_bc_.assign(3 * static_cast<std::size_t>(domain_.owned), 0.0);
  v_old_bc_ = du_bc_;
  {
    std::vector<int> bc_natural(nodes_.size(), -1);  // later regions win where they overlap
    for (std::size_t b = 0; b < bc_nodes.size(); ++b)
      for (std::int64_t i : bc_nodes[b]) bc_natural[i] = static_cast<int>(b);
    for (std::int32_t i = 0; i < domain_.owned; ++i) bc_[i] = bc_natural[domain_.natural[i]];
  }

  // Stable time step (collective) and each stage's step.
  BondView view = bond_view();
  double dt_local = std::numeric_limits<double>::infinity();
  for (std::size_t b = 0; b < nb; ++b) {
    for (const auto* rows : {&interior_by_body_[b], &boundary_by_body_[b]})
      dt_local = std::min(dt_local, stable_time_step(laws_[b], density_[b], view, rows->data(), rows->size()));
  }
  MPI_Allreduce(&dt_local, &summary_.dt_stable, 1, MPI_DOUBLE, MPI_MIN, comm_);
  if (!std::isfinite(summary_.dt_stable))
    throw InputError(scene_.file + ": no node has a bond; the horizon is too small for the spacing");
  for (std::size_t s = 0; s < scene_.stages.size(); ++s) {
    const Stage& st = scene_.stages[s];
    const double dt = st.dt ? *st.dt : st.safety_factor * summary_.dt_stable;
    if (dt > summary_.dt_stable && !st.allow_unstable_dt) {
      std::ostringstream msg;
      msg << st.where.str() << ": stages." << s << ".dt: time step " << fmt(dt)
          << " s exceeds the stable bound " << fmt(summary_.dt_stable)
          << " s (Silling & Askari 2005); expected dt <= " << fmt(summary_.dt_stable)
          << ", or allow_unstable_dt: true to run anyway";
      throw InputError(msg.str());
    }
    const std::int64_t n = st.steps ? *st.steps : static_cast<std::int64_t>(std::ceil(st.duration / dt - 1e-9));
    stage_dt_.push_back(dt);
    stage_steps_.push_back(std::max<std::int64_t>(n, 1));
    total_steps_ += stage_steps_.back();
  }
  const int frames = std::max(1, scene_.output.frames);
  for (int k = 0; k < frames; ++k)
    frame_steps_.push_back(frames == 1 ? total_steps_ : std::llround(double(k) * total_steps_ / (frames - 1)));

  // Summary figures known now.
  std::int64_t local_bonds = domain_.bonds.size(), local_pre = domain_.initially_broken;
  MPI_Allreduce(&local_bonds, &summary_.ordered_bonds, 1, MPI_INT64_T, MPI_SUM, comm_);
  MPI_Allreduce(&local_pre, &summary_.precrack_bonds, 1, MPI_INT64_T, MPI_SUM, comm_);
  summary_.precrack_bonds /= 2;
  summary_.nodes = domain_.global_nodes;
  summary_.ranks = ranks_;
  summary_.steps = total_steps_;
  summary_.dt = stage_dt_.front();
  double bpb = domain_.bonds.bytes_per_bond(), bpb_max = 0;
  MPI_Allreduce(&bpb, &bpb_max, 1, MPI_DOUBLE, MPI_MAX, comm_);
  summary_.bytes_per_bond = bpb_max;
  summary_.partition_seconds = partition_.seconds;
  summary_.edge_cut = partition_.edge_cut;
  for (std::size_t b = 0; b < nb; ++b) {
    const std::string p = scene_.bodies[b].name + ".";
    const ElasticConstants e = elastic_constants(laws_[b], nodes_.bodies[b], density_[b]);
    summary_.derived.push_back({p + "micromodulus", laws_[b].c});
    summary_.derived.push_back({p + "horizon", laws_[b].horizon});
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
    summary_.derived.push_back({"stages." + std::to_string(s) + ".dt", stage_dt_[s]});
    summary_.derived.push_back({"stages." + std::to_string(s) + ".steps", double(stage_steps_[s])});
  }
  summary_.derived.push_back({"ordered_bonds", double(summary_.ordered_bonds)});
  resolved_ = emit_scene(scene_, derived_lines());
  setup_crack_tips();
  PetscLogEventEnd(events().setup, 0, 0, 0, 0);

  // Output last: nothing is written unless every check above passed.
  if (!options_.out_dir.empty()) {
    make_output_dir(options_.out_dir, comm_);
    if (rank_ == 0) {
      // A previous run's completion marker must not vouch for this one until it finishes.
      std::remove((options_.out_dir + "/summary.json").c_str());
      std::remove((options_.out_dir + "/FAILED").c_str());
      write_text_file(options_.out_dir + "/scene.resolved.yaml", resolved_);
    }
    MPI_Barrier(comm_);
    frames_ = std::make_unique<FrameWriter>(options_.out_dir, "frames", domain_, *state_, resolved_,
                                            scene_.output.write_velocity);
    std::string tip_columns;
    if (tracker_) {
      tip_columns = "crack_tips";
      for (int k = 0; k < kTipColumns; ++k)
        for (const char* c : {"_x", "_y", "_speed"}) tip_columns += ",tip" + std::to_string(k) + c;
      if (rank_ == 0) {
        tips_csv_ = std::make_unique<std::ofstream>(options_.out_dir + "/tips.csv", std::ios::trunc);
        if (!*tips_csv_) throw Error("cannot write '" + options_.out_dir + "/tips.csv'");
        *tips_csv_ << "step,time,track,x,y,z,path_length,speed\n" << std::setprecision(12);
      }
    }
    series_ = std::make_unique<SeriesWriter>(options_.out_dir + "/series.csv", rank_ == 0, tip_columns);
  }
  summary_.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

Simulation::~Simulation() = default;

BondView Simulation::bond_view() {
  return BondView{domain_.X.data(), nullptr, domain_.volume.data(), domain_.bonds.offsets.data(),
                  domain_.bonds.neighbor.data(), domain_.bonds.broken.data(),
                  domain_.bonds.weight.empty() ? nullptr : domain_.bonds.weight.data()};
}

std::vector<std::string> Simulation::derived_lines() const {
  std::vector<std::string> lines;
  lines.push_back(std::string("derived by peridrive ") + version() + " (" + git_revision() + "):");
  for (const auto& [k, v] : summary_.derived) {
    std::ostringstream s;
    s << k << " = " << std::setprecision(10) << v;
    lines.push_back(s.str());
  }
  return lines;
}

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
    if (bc_[i] >= 0) {
      const Boundary& b = scene_.boundaries[bc_[i]];
      for (int c = 0; c < 3; ++c)
        if (b.components[c]) v[3 * i + c] = b.velocity[c] * ramp(0.0, b.ramp_time);
    }
  }
  PERI_PETSC(VecRestoreArray(state_->velocity(), &v));
  PERI_PETSC(VecRestoreArray(state_->displacement(), &u));
}

void Simulation::compute_forces(bool with_energy) {
  PetscLogEventBegin(events().forces, 0, 0, 0, 0);
  BondView view = bond_view();
  BondTally t;
  state_->halo_begin();  // interior rows need no ghost: overlap them with the exchange
  {
    LocalArray u(state_->displacement());
    view.u = u.data();
    for (std::size_t b = 0; b < laws_.size(); ++b)
      bond_forces(laws_[b], view, interior_by_body_[b].data(), interior_by_body_[b].size(),
                  force_.data(), with_energy, t);
  }
  PetscLogEventBegin(events().halo, 0, 0, 0, 0);
  state_->halo_end();
  PetscLogEventEnd(events().halo, 0, 0, 0, 0);
  {
    LocalArray u(state_->displacement());
    view.u = u.data();
    for (std::size_t b = 0; b < laws_.size(); ++b)
      bond_forces(laws_[b], view, boundary_by_body_[b].data(), boundary_by_body_[b].size(),
                  force_.data(), with_energy, t);
  }
  tally_.dissipated += t.dissipated;
  tally_.newly_broken += t.newly_broken;
  tally_.strain_energy = t.strain_energy;
  PetscLogEventEnd(events().forces, 0, 0, 0, 0);
}

void Simulation::step(bool with_energy) {
  const double dt = dt_, t0 = time_, t1 = time_ + dt;
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  double* u;
  double* v;
  PERI_PETSC(VecGetArray(state_->displacement(), &u));
  PERI_PETSC(VecGetArray(state_->velocity(), &v));
  std::vector<double>& du_bc = du_bc_;  // read only where written below (prescribed components)
  std::vector<double>& v_old_bc = v_old_bc_;
  // Half kick and drift (velocity Verlet); prescribed components follow their boundary.
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const Boundary* b = bc_[i] >= 0 ? &scene_.boundaries[bc_[i]] : nullptr;
    for (int c = 0; c < 3; ++c) {
      const std::size_t k = 3 * static_cast<std::size_t>(i) + c;
      if (b && b->components[c]) {
        v_old_bc[k] = v[k];
        du_bc[k] = b->velocity[c] * (ramp_integral(t1, b->ramp_time) - ramp_integral(t0, b->ramp_time));
        u[k] += du_bc[k];
        v[k] = b->velocity[c] * ramp(t1, b->ramp_time);
      } else {
        v[k] += 0.5 * dt * force_[k] * inv_density_[i];
        u[k] += dt * v[k];
      }
    }
  }
  PERI_PETSC(VecRestoreArray(state_->displacement(), &u));
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
  std::swap(force_, prev_force_);
  compute_forces(with_energy);
  PetscLogEventBegin(events().update, 0, 0, 0, 0);
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const Boundary* b = bc_[i] >= 0 ? &scene_.boundaries[bc_[i]] : nullptr;
    for (int c = 0; c < 3; ++c) {
      const std::size_t k = 3 * static_cast<std::size_t>(i) + c;
      if (b && b->components[c]) {
        // Work of the reaction that enforces the motion: change of the node's kinetic energy
        // minus the work of the internal force along the prescribed path (trapezoidal).
        const double fi = 0.5 * (force_[k] + prev_force_[k]) * domain_.volume[i];
        external_work_ += 0.5 * mass_[i] * (v[k] * v[k] - v_old_bc[k] * v_old_bc[k]) - fi * du_bc[k];
      } else {
        v[k] += 0.5 * dt * force_[k] * inv_density_[i];
      }
    }
  }
  PERI_PETSC(VecRestoreArray(state_->velocity(), &v));
  PetscLogEventEnd(events().update, 0, 0, 0, 0);
  time_ = t1;
  ++step_;
}

double Simulation::kinetic_energy() {
  const double* v;
  PERI_PETSC(VecGetArrayRead(state_->velocity(), &v));
  double ke = 0;
  for (std::int32_t i = 0; i < domain_.owned; ++i)
    ke += 0.5 * mass_[i] * (v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
  PERI_PETSC(VecRestoreArrayRead(state_->velocity(), &v));
  double total = 0;
  MPI_Allreduce(&ke, &total, 1, MPI_DOUBLE, MPI_SUM, comm_);
  return total;
}

EnergyRow Simulation::energies() {
  // Strain energy of the current state from a separate (non-breaking) pass.
  BondView view = bond_view();
  double strain = 0;
  {
    LocalArray u(state_->displacement());
    view.u = u.data();
    for (std::size_t b = 0; b < laws_.size(); ++b) {
      strain += bond_energy(laws_[b], view, interior_by_body_[b].data(), interior_by_body_[b].size());
      strain += bond_energy(laws_[b], view, boundary_by_body_[b].data(), boundary_by_body_[b].size());
    }
  }
  return reduce_energies(strain);
}

EnergyRow Simulation::reduce_energies(double local_strain) {
  double local[4] = {local_strain, tally_.dissipated, external_work_, double(tally_.newly_broken)};
  double global[4];
  MPI_Allreduce(local, global, 4, MPI_DOUBLE, MPI_SUM, comm_);
  EnergyRow row;
  row.step = step_;
  row.time = time_;
  row.kinetic = kinetic_energy();
  row.strain = global[0];
  row.dissipated = global[1];
  row.external_work = global[2];
  row.broken_bonds = std::llround(global[3]) / 2;  // ordered bonds -> bonds
  return row;
}

void Simulation::write_series_row() {
  const EnergyRow row = reduce_energies(tally_.strain_energy);
  const std::string tip_values = tracker_ ? track_crack_tips(row) : std::string();
  if (series_) series_->write(row, tip_values);
  summary_.final_energy = row;
}

void Simulation::setup_crack_tips() {
  // Tracking runs when some material breaks. Lengths from the breaking bodies (crack_tips.hpp):
  // link 2 dx, tip separation 2 delta, window 10 delta / c_l, jumps up to 2 delta + 2 c_l x the
  // time between samples. Seeds: the pre-cracks' midpoints.
  double dx = 0, delta = 0, c_l = INFINITY, c_r = INFINITY;
  for (std::size_t b = 0; b < laws_.size(); ++b) {
    if (!laws_[b].breaks) continue;
    const ElasticConstants e = elastic_constants(laws_[b], nodes_.bodies[b], density_[b]);
    dx = std::max(dx, nodes_.bodies[b].spacing);
    delta = std::max(delta, laws_[b].horizon);
    c_l = std::min(c_l, e.c_longitudinal);
    c_r = std::min(c_r, e.c_rayleigh);
  }
  if (!(delta > 0)) return;
  CrackTipSettings s;
  s.link_distance = 2 * dx;
  s.tip_separation = 2 * delta;
  const double sample = scene_.output.series_every * *std::max_element(stage_dt_.begin(), stage_dt_.end());
  tracker_ = std::make_unique<CrackTipTracker>(s, 10 * delta / c_l, s.tip_separation + 2 * c_l * sample);
  for (const Crack& c : scene_.cracks)
    for (int k = 0; k < 3; ++k) tip_seeds_.push_back(0.5 * (c.from[k] + c.to[k]));
  summary_.crack_tracking = true;
  summary_.rayleigh_wave_speed = c_r;
  summary_.crack_speed_window = tracker_->window();
}

std::string Simulation::track_crack_tips(const EnergyRow& row) {
  const auto t0 = std::chrono::steady_clock::now();
  // The damage field changes only when bonds break: otherwise the last tips stand.
  if (row.broken_bonds != tips_broken_at_) {
    tips_broken_at_ = row.broken_bonds;
    update_damage();
    std::vector<std::int64_t> ids;
    std::vector<double> X;
    for (std::int32_t i = 0; i < domain_.owned; ++i)
      if (damage_[i] >= tracker_->settings().damage_threshold) {
        ids.push_back(domain_.natural[i]);
        X.insert(X.end(), &domain_.X[3 * i], &domain_.X[3 * i] + 3);
      }
    // Every rank gathers the (few) damaged nodes, sorts them by natural id, finds the same tips.
    const int n = static_cast<int>(ids.size());
    std::vector<int> counts(ranks_), displs(ranks_, 0), counts3(ranks_), displs3(ranks_, 0);
    MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
    for (int r = 0; r < ranks_; ++r) {
      if (r > 0) displs[r] = displs[r - 1] + counts[r - 1];
      counts3[r] = 3 * counts[r];
      displs3[r] = 3 * displs[r];
    }
    const int total = displs.back() + counts.back();
    std::vector<std::int64_t> all_ids(total);
    std::vector<double> all_X(3 * static_cast<std::size_t>(total));
    MPI_Allgatherv(ids.data(), n, MPI_INT64_T, all_ids.data(), counts.data(), displs.data(), MPI_INT64_T, comm_);
    MPI_Allgatherv(X.data(), 3 * n, MPI_DOUBLE, all_X.data(), counts3.data(), displs3.data(), MPI_DOUBLE, comm_);
    std::vector<int> order(total);
    for (int k = 0; k < total; ++k) order[k] = k;
    std::sort(order.begin(), order.end(), [&](int a, int b) { return all_ids[a] < all_ids[b]; });
    std::vector<std::int64_t> sorted_ids(total);
    std::vector<double> sorted_X(3 * static_cast<std::size_t>(total));
    for (int k = 0; k < total; ++k) {
      sorted_ids[k] = all_ids[order[k]];
      for (int c = 0; c < 3; ++c) sorted_X[3 * k + c] = all_X[3 * order[k] + c];
    }
    last_tips_ = find_crack_tips(sorted_ids, sorted_X, tip_seeds_, tracker_->settings());
  }
  tracker_->update(row.time, last_tips_);
  // Series columns: tip count, then position and speed of tracks 0..kTipColumns-1 if sampled now.
  std::ostringstream out;
  out << std::setprecision(12) << last_tips_.size();
  for (int k = 0; k < kTipColumns; ++k) {
    const CrackTrack* t = k < static_cast<int>(tracker_->tracks().size()) ? &tracker_->tracks()[k] : nullptr;
    if (t && t->active && t->time.back() == row.time) {
      out << ',' << t->position.back()[0] << ',' << t->position.back()[1] << ',';
      if (std::isfinite(t->speed.back())) out << t->speed.back();
    } else {
      out << ",,,";
    }
  }
  if (tips_csv_) {
    for (const CrackTrack& t : tracker_->tracks()) {
      if (!t.active || t.time.back() != row.time) continue;
      *tips_csv_ << row.step << ',' << row.time << ',' << t.id << ',' << t.position.back()[0] << ','
                 << t.position.back()[1] << ',' << t.position.back()[2] << ',' << t.path_length.back() << ',';
      if (std::isfinite(t.speed.back())) *tips_csv_ << t.speed.back();
      *tips_csv_ << '\n';
    }
    tips_csv_->flush();
  }
  summary_.crack_tip_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out.str();
}

void Simulation::summarize_crack_tips() {
  summary_.max_crack_speed = tracker_->max_speed();
  summary_.mean_crack_speed = tracker_->mean_speed();
  std::ostringstream j;
  j << "[";
  for (const CrackTrack& t : tracker_->tracks()) {
    const auto& p = t.position.back();
    const auto& p0 = t.position.front();
    double vmax = 0;
    for (double v : t.speed)
      if (std::isfinite(v)) vmax = std::max(vmax, v);
    const auto steady = tracker_->steady_part(t);
    j << (t.id ? "," : "") << "\n    {\"track\": " << t.id << ", \"active\": " << (t.active ? "true" : "false")
      << ", \"position\": [" << json_number(p[0]) << ", " << json_number(p[1]) << ", " << json_number(p[2]) << "]"
      << ", \"path_length\": " << json_number(t.path_length.back())
      << ", \"speed\": " << json_number(t.speed.back()) << ", \"max_speed\": " << json_number(vmax)
      << ", \"first_time\": " << json_number(t.time.front()) << ", \"last_time\": " << json_number(t.time.back())
      << ", \"first_position\": [" << json_number(p0[0]) << ", " << json_number(p0[1]) << ", "
      << json_number(p0[2]) << "]"
      << ", \"steady_from\": " << json_number(steady[0]) << ", \"steady_to\": " << json_number(steady[1])
      << ", \"steady_mean_speed\": " << json_number(steady[2] / (steady[1] - steady[0])) << "}";
  }
  j << (tracker_->tracks().empty() ? "]" : "\n  ]");
  summary_.crack_tips_json = j.str();
}

void Simulation::write_frame() {
  PetscLogEventBegin(events().output, 0, 0, 0, 0);
  const auto t0 = std::chrono::steady_clock::now();
  update_damage();
  const double* u;
  const double* v;
  PERI_PETSC(VecGetArrayRead(state_->displacement(), &u));
  PERI_PETSC(VecGetArrayRead(state_->velocity(), &v));
  frames_->write(step_, time_, u, v, damage_.data());
  PERI_PETSC(VecRestoreArrayRead(state_->velocity(), &v));
  PERI_PETSC(VecRestoreArrayRead(state_->displacement(), &u));
  summary_.output_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  PetscLogEventEnd(events().output, 0, 0, 0, 0);
}

void Simulation::check_health(std::int64_t step, double time) {
  // Collective: first non-finite node (natural id) and the broken-bond count.
  const double* u;
  const double* v;
  PERI_PETSC(VecGetArrayRead(state_->displacement(), &u));
  PERI_PETSC(VecGetArrayRead(state_->velocity(), &v));
  long long bad = std::numeric_limits<long long>::max();
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    bool ok = true;
    for (int c = 0; c < 3; ++c) ok &= std::isfinite(u[3 * i + c]) && std::isfinite(v[3 * i + c]);
    if (!ok) bad = std::min<long long>(bad, domain_.natural[i]);
  }
  PERI_PETSC(VecRestoreArrayRead(state_->velocity(), &v));
  PERI_PETSC(VecRestoreArrayRead(state_->displacement(), &u));
  long long bad_global;
  MPI_Allreduce(&bad, &bad_global, 1, MPI_LONG_LONG, MPI_MIN, comm_);
  if (bad_global != std::numeric_limits<long long>::max()) {
    const double* X = &nodes_.X[3 * bad_global];
    std::ostringstream msg;
    msg << "non-finite displacement or velocity at step " << step << " (t = " << fmt(time)
        << " s), node " << bad_global << " at reference position (" << fmt(X[0]) << ", " << fmt(X[1])
        << ", " << fmt(X[2]) << "); likely cause: time step " << fmt(dt_) << " s above the stable bound "
        << fmt(summary_.dt_stable) << " s, or a boundary velocity too violent for the resolution";
    throw RuntimeFailure(msg.str());
  }
  if (options_.quiet) return;
  const auto now = std::chrono::steady_clock::now();
  int print = rank_ == 0 && std::chrono::duration<double>(now - last_progress_).count() >= scene_.output.progress_seconds;
  MPI_Bcast(&print, 1, MPI_INT, 0, comm_);
  if (!print) return;
  long long broken_local = tally_.newly_broken, broken = 0;
  MPI_Reduce(&broken_local, &broken, 1, MPI_LONG_LONG, MPI_SUM, 0, comm_);
  if (rank_ == 0) {
    const double elapsed = std::chrono::duration<double>(now - start_).count() - summary_.setup_seconds;
    const double rate = step / std::max(elapsed, 1e-9);
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
  finish();
}

void Simulation::begin() {
  apply_initial_conditions();
  compute_forces(true);
  write_series_row();
  summary_.initial_total_energy = summary_.final_energy.total();
  if (frames_ && next_frame_ < frame_steps_.size() && frame_steps_[next_frame_] == 0) {
    write_frame();
    while (next_frame_ < frame_steps_.size() && frame_steps_[next_frame_] == 0) ++next_frame_;
  }
  if (rank_ == 0 && !options_.quiet) {
    std::printf("[peridrive] %lld nodes, %lld bonds, %d rank%s; dt = %.4g s (stable bound %.4g s), %lld steps\n",
                static_cast<long long>(summary_.nodes), static_cast<long long>(summary_.ordered_bonds / 2),
                ranks_, ranks_ > 1 ? "s" : "", summary_.dt, summary_.dt_stable,
                static_cast<long long>(total_steps_));
    std::fflush(stdout);
  }
  loop_start_ = std::chrono::steady_clock::now();
  last_progress_ = loop_start_;
}

std::int64_t Simulation::advance(std::int64_t n) {
  std::int64_t taken = 0;
  while (taken < n && stage_ < stage_steps_.size()) {
    if (stage_step_ >= stage_steps_[stage_]) {
      ++stage_;
      stage_step_ = 0;
      continue;
    }
    dt_ = stage_dt_[stage_];
    const bool series = (step_ + 1) % scene_.output.series_every == 0 || step_ + 1 == total_steps_;
    step(series);
    ++stage_step_;
    ++taken;
    if (series) write_series_row();
    if (step_ % kCheckEvery == 0 || step_ == total_steps_) check_health(step_, time_);
    if (frames_ && next_frame_ < frame_steps_.size() && frame_steps_[next_frame_] <= step_) {
      write_frame();
      while (next_frame_ < frame_steps_.size() && frame_steps_[next_frame_] <= step_) ++next_frame_;
    }
  }
  return taken;
}

void Simulation::finish() {
  const auto t_end = std::chrono::steady_clock::now();
  summary_.step_seconds = std::chrono::duration<double>(t_end - loop_start_).count() - summary_.output_seconds;
  summary_.wall_seconds = std::chrono::duration<double>(t_end - start_).count();
  summary_.simulated_time = time_;
  summary_.frames = frames_ ? frames_->frames() : 0;
  const EnergyRow& f = summary_.final_energy;
  const double scale = std::max({std::fabs(f.kinetic) + std::fabs(f.strain) + std::fabs(f.dissipated),
                                 std::fabs(f.external_work), std::fabs(summary_.initial_total_energy), 1e-300});
  summary_.energy_balance_error = std::fabs(f.total() - summary_.initial_total_energy) / scale;
  if (tracker_) summarize_crack_tips();
  // Timings of the slowest rank: the job's figures.
  double times[4] = {summary_.step_seconds, summary_.output_seconds, summary_.wall_seconds,
                     summary_.crack_tip_seconds}, tmax[4];
  MPI_Allreduce(times, tmax, 4, MPI_DOUBLE, MPI_MAX, comm_);
  summary_.crack_tip_seconds = tmax[3];
  summary_.step_seconds = tmax[0];
  summary_.output_seconds = tmax[1];
  summary_.wall_seconds = tmax[2];
  if (!options_.out_dir.empty() && rank_ == 0)
    write_text_file(options_.out_dir + "/summary.json", summary_.to_json());
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
      if (domain_.bonds.broken[b]) {
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
  const double* u;
  const double* v;
  PERI_PETSC(VecGetArrayRead(state_->displacement(), &u));
  PERI_PETSC(VecGetArrayRead(state_->velocity(), &v));
  std::array<double, 6> p{}, total{};
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    const double m = mass_[i];
    const double x[3] = {domain_.X[3 * i] + u[3 * i], domain_.X[3 * i + 1] + u[3 * i + 1], domain_.X[3 * i + 2] + u[3 * i + 2]};
    const double* w = &v[3 * i];
    for (int c = 0; c < 3; ++c) p[c] += m * w[c];
    p[3] += m * (x[1] * w[2] - x[2] * w[1]);
    p[4] += m * (x[2] * w[0] - x[0] * w[2]);
    p[5] += m * (x[0] * w[1] - x[1] * w[0]);
  }
  PERI_PETSC(VecRestoreArrayRead(state_->velocity(), &v));
  PERI_PETSC(VecRestoreArrayRead(state_->displacement(), &u));
  MPI_Allreduce(p.data(), total.data(), 6, MPI_DOUBLE, MPI_SUM, comm_);
  return total;
}

}  // namespace peri
