// The setup: build_problem() builds a run's problem once, step by step along the data flow. Each
// step is a function of what the steps before it made, so the order is the data's: the nodes
// (and every check they allow) before anything is allocated per rank; the boundaries' regions
// and the bodies' laws from the nodes; the partition and this rank's domain; what each rank
// keeps of the global node arrays (boundaries, long-range table, pressure triangles), which end
// there; the state; the force model; the time steps, which need the force model's bound and the
// tools' penalty; the initial state's checks; the figures and the resolved scene.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>

#include "peri/bonds/bonds.hpp"
#include "peri/core/error.hpp"
#include "peri/core/format.hpp"
#include "peri/core/petsc.hpp"
#include "peri/core/resources.hpp"
#include "peri/io/output.hpp"
#include "peri/io/restart.hpp"
#include "peri/io/summary.hpp"
#include "peri/loads/pressure.hpp"
#include "peri/models/model.hpp"
#include "peri/partition/partition.hpp"
#include "peri/stages/events.hpp"
#include "peri/stages/geometry_warnings.hpp"
#include "peri/stages/problem.hpp"
#include "peri/stages/release.hpp"
#include "peri/stages/setup_checks.hpp"

namespace peri {
namespace {

/// The nodes of every body, after the checks that need only the scene (family sizes, memory).
Nodes discretize_checked(const Scene& scene, const PartitionSettings& settings, MPI_Comm comm, int rank) {
  warn_large_families(scene, estimate_size(scene), rank);
  warn_cloud_spacing(scene, rank);
  warn_flattened_meshes(scene, rank);
  warn_unused_safety_factor(scene, rank);
  warn_aliased_seed(scene, rank);
  check_fits(scene, comm, settings.method == PartitionMethod::Bonds);
  stop_point(comm);
  Nodes nodes = discretize(scene);
  check_node_positions(scene, nodes, rank);
  warn_thick_bodies(scene, nodes, rank);
  check_polygon_cracks(scene, nodes);
  return nodes;
}

/// Per boundary, the nodes of its region (natural ids, ascending).
std::vector<std::vector<std::int64_t>> boundary_regions(const Scene& scene, const Nodes& nodes, int rank) {
  std::vector<std::vector<std::int64_t>> regions;
  for (const Boundary& b : scene.boundaries)
    regions.push_back(select_nodes(nodes, scene, b.region, "boundaries." + b.name + ".region"));
  warn_overlapping_boundaries(scene, regions, rank);
  return regions;
}

/// Each body's bond law, calibrated from its material and geometry (lattice bodies: none, their
/// law is the Forces'), and its density.
std::vector<BondLaw> calibrate_bodies(const Scene& scene, const Nodes& nodes, std::vector<double>& density) {
  std::vector<BondLaw> laws;
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    const Material& m = scene.material(scene.bodies[b].material);
    laws.push_back(nodes.bodies[b].traits.lattice
                       ? BondLaw{}
                       : calibrate(m, nodes.bodies[b], scene.bodies[b].where.str() + ": bodies." + scene.bodies[b].name));
    density.push_back(m.density);
    // The crack-tip rule reads the tip flags of a family's nodes: r within the horizon.
    if (m.tip_advance && !laws.back().empty() && !(*m.tip_advance <= laws.back().horizon()))
      throw InputError(m.where.str() + ": materials." + m.name + ".tip_advance: expected at most the horizon " +
                       number_text(laws.back().horizon()) + " m of body '" + scene.bodies[b].name + "', got " +
                       number_text(*m.tip_advance));
    if (m.tip_advance && !laws.back().empty() && laws.back().entry().history > 0)
      throw InputError(m.where.str() + ": materials." + m.name + ".tip_advance: not available for the " +
                       laws.back().name() + " law, which keeps a per-bond history");
  }
  check_node_masses(scene, nodes, laws, density);
  return laws;
}

/// Nodes the frames hold (every node_stride-th natural id, inside output.region); InputError naming
/// output.region when it holds none.
std::int64_t frame_node_count(const Scene& scene, const Nodes& nodes) {
  const Output& o = scene.output;
  std::int64_t n = 0;
  for (std::int64_t i = 0; i < nodes.size(); i += o.node_stride) {
    bool inside = true;
    for (int c = 0; c < 3 && o.region; ++c)
      inside = inside && nodes.X[3 * i + c] >= (*o.region)[0][c] && nodes.X[3 * i + c] <= (*o.region)[1][c];
    n += inside;
  }
  if (n == 0) {
    const auto& r = *o.region;
    std::ostringstream msg;
    msg << o.where.str() << ": output.region: the box [" << number_text(r[0][0]) << ", " << number_text(r[0][1]) << ", "
        << number_text(r[0][2]) << "] .. [" << number_text(r[1][0]) << ", " << number_text(r[1][1]) << ", "
        << number_text(r[1][2]) << "] holds none of the nodes the frames take (output.node_stride " << o.node_stride
        << "); expected a box around some of the bodies' nodes";
    throw InputError(msg.str());
  }
  return n;
}

/// The per-bond history of laws that keep one: the largest number of values any body's law keeps,
/// per ordered bond, zero at the start (rows of laws that keep fewer use the first ones).
void allocate_history(Domain& d, const std::vector<BondLaw>& laws) {
  int stride = 0;
  for (const BondLaw& law : laws)
    if (!law.empty()) stride = std::max(stride, law.entry().history);
  d.bonds.history_stride = stride;
  d.bonds.history.assign(static_cast<std::size_t>(stride) * static_cast<std::size_t>(d.bonds.size()), 0.0);
}

/// A partitioner without a graph (rcb) reports no edge cut: the bonds to ghost nodes are it.
void count_edge_cut(Partition& partition, const Domain& domain, MPI_Comm comm) {
  if (partition.edge_cut >= 0) return;
  long long cut = 0, all = 0;
  for (std::int32_t i : domain.boundary_rows)
    for (std::int64_t b = domain.bonds.offsets[i]; b < domain.bonds.offsets[i + 1]; ++b)
      cut += domain.bonds.neighbor[b] >= domain.owned;
  MPI_Allreduce(&cut, &all, 1, MPI_LONG_LONG, MPI_SUM, comm);
  partition.edge_cut = all / 2;  // each cut bond from both ends
}

/// Per owned node, the boundary whose region holds it (later regions win where they overlap), or -1.
std::vector<int> node_boundaries(const std::vector<std::vector<std::int64_t>>& regions, std::int64_t nodes,
                                 const Domain& domain) {
  std::vector<int> bc_natural(nodes, -1), bc(domain.owned);
  for (std::size_t b = 0; b < regions.size(); ++b)
    for (std::int64_t i : regions[b]) bc_natural[i] = static_cast<int>(b);
  for (std::int32_t i = 0; i < domain.owned; ++i) bc[i] = bc_natural[domain.natural[i]];
  return bc;
}

/// Node masses and inverse densities, and the balance's energy floor: a uniform strain of 1e-10
/// in every body, sum m c_l^2 x 1e-20 (a body at rest holds only round-off, ~1e-21 J).
void node_masses(Problem& p) {
  const Domain& d = p.domain;
  p.inv_density.resize(d.owned);
  p.mass.resize(d.owned);
  for (std::int32_t i = 0; i < d.owned; ++i) {
    p.inv_density[i] = 1.0 / p.density[d.body[i]];
    p.mass[i] = p.density[d.body[i]] * d.volume[i];
  }
  std::vector<double> wave2(p.bodies.size());
  for (std::size_t b = 0; b < wave2.size(); ++b) {
    const MarderLaw* lattice = p.forces->marder(b);
    wave2[b] = lattice ? lattice->a
                       : std::pow(elastic_constants(p.forces->laws()[b], p.bodies[b], p.density[b]).c_longitudinal, 2);
  }
  p.energy_floor = energy_floor(p.mass, d.body.data(), wave2, p.comm);
}

/// Each stage's time step and steps: the scene's dt or safety_factor x the stable bound, refused
/// above the bound unless allowed; a duration is covered exactly, by n steps of duration / n (at
/// most the requested step).
StagePlan plan_stages(const Scene& scene, double dt_stable) {
  StagePlan plan;
  plan.dt_stable = dt_stable;
  for (std::size_t s = 0; s < scene.stages.size(); ++s) {
    const Stage& st = scene.stages[s];
    if (st.kind != StageKind::Dynamic) {  // no time passes
      plan.dt.push_back(0.0);
      plan.steps.push_back(0);
      continue;
    }
    const double dt = st.dt ? *st.dt : st.safety_factor * dt_stable;
    check_stage(scene, s, dt, dt_stable);
    if (dt > dt_stable && !st.allow_unstable_dt) {
      std::ostringstream msg;
      msg << st.where.str() << ": stages." << s << ".dt: time step " << number_text(dt) << " s exceeds the stable bound "
          << number_text(dt_stable) << " s (Silling & Askari 2005); expected dt <= " << number_text(dt_stable)
          << ", or allow_unstable_dt: true to run anyway";
      throw InputError(msg.str());
    }
    const std::int64_t n = st.steps ? *st.steps : std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(st.duration / dt - 1e-9)));
    plan.dt.push_back(st.steps ? dt : st.duration / static_cast<double>(n));
    plan.steps.push_back(std::max<std::int64_t>(n, 1));
    plan.total += plan.steps.back();
  }
  return plan;
}

/// Sizes, time steps and the partition's figures.
/// The halo's terms over the ranks (summary.json "halo"): ghosts, neighbour ranks (the owners of
/// this rank's ghosts: bonds are symmetric, so these are also the ranks it sends to), owned
/// ordered bonds and those of boundary rows. Collective.
void halo_figures(const Problem& p, RunSummary::Halo& halo) {
  const Domain& d = p.domain;
  std::vector<std::int64_t> begins(p.ranks + 1);
  MPI_Allgather(&d.global_begin, 1, MPI_INT64_T, begins.data(), 1, MPI_INT64_T, p.comm);
  begins[p.ranks] = d.global_nodes;
  std::vector<char> neighbour(p.ranks, 0);
  for (std::int32_t k = 0; k < d.ghosts; ++k)
    neighbour[std::upper_bound(begins.begin(), begins.end(), d.global[d.owned + k]) - begins.begin() - 1] = 1;
  std::int64_t boundary = 0;
  for (std::int32_t i : d.boundary_rows) boundary += d.bonds.offsets[i + 1] - d.bonds.offsets[i];
  const std::int64_t mine[4] = {d.ghosts, std::count(neighbour.begin(), neighbour.end(), 1),
                                static_cast<std::int64_t>(d.bonds.size()), boundary};
  std::int64_t most[4], sum[4];
  MPI_Allreduce(mine, most, 4, MPI_INT64_T, MPI_MAX, p.comm);
  MPI_Allreduce(mine, sum, 4, MPI_INT64_T, MPI_SUM, p.comm);
  halo.max_ghosts = most[0];
  halo.max_neighbour_ranks = most[1];
  halo.max_owned_bonds = most[2];
  halo.max_boundary_bonds = most[3];
  halo.mean_ghosts = static_cast<double>(sum[0]) / p.ranks;
  halo.mean_neighbour_ranks = static_cast<double>(sum[1]) / p.ranks;
  halo.mean_boundary_bonds = static_cast<double>(sum[3]) / p.ranks;
}

void setup_figures(const Problem& p, const Partition& partition, PartitionMethod method, RunSummary& summary) {
  const Domain& d = p.domain;
  std::int64_t local_bonds = d.bonds.size(), local_pre = d.initially_broken;
  MPI_Allreduce(&local_bonds, &summary.ordered_bonds, 1, MPI_INT64_T, MPI_SUM, p.comm);
  MPI_Allreduce(&local_pre, &summary.precrack_bonds, 1, MPI_INT64_T, MPI_SUM, p.comm);
  summary.precrack_bonds /= 2;
  // Pre-cracks broken at the start that cut nothing are misplaced (outside every body they cut),
  // each named, also beside others that cut.
  std::vector<int> met(d.crack_met.begin(), d.crack_met.end());
  if (!met.empty()) MPI_Allreduce(MPI_IN_PLACE, met.data(), static_cast<int>(met.size()), MPI_INT, MPI_MAX, p.comm);
  std::vector<const Crack*> idle;
  std::size_t k = 0;
  for (const Crack& c : p.scene.cracks)
    if (!p.scene.released_later(c.name) && k < met.size() && !met[k++]) idle.push_back(&c);
  if (p.rank == 0 && !idle.empty()) {
    std::string names;
    for (const Crack* c : idle) names += (names.empty() ? "'" : ", '") + c->name + "'";
    std::fprintf(stderr,
                 "peridrive: warning: %s: cracks: %s broken at the start (%s) %s no bond: %s of a body it cuts "
                 "(a slit: membrane, lattice, fiber or sphere; a polygon: any)\n",
                 idle[0]->where.str().c_str(), idle.size() > 1 ? "the pre-cracks" : "the pre-crack", names.c_str(),
                 idle.size() > 1 ? "cut" : "cuts", idle.size() > 1 ? "none of them meets a bond" : "it meets no bond");
  }
  warn_far_slit_walls(p);
  summary.nodes = d.global_nodes;
  summary.ranks = p.ranks;
  summary.steps = p.stages.total;
  summary.dt_stable = p.stages.dt_stable;
  for (std::size_t s = 0; s < p.stages.dt.size(); ++s)
    if (p.scene.stages[s].kind == StageKind::Dynamic) {
      summary.dt = p.stages.dt[s];
      break;
    }
  double bpb = d.bonds.bytes_per_bond(), bpb_max = 0;
  if (!d.bonds.neighbor.empty()) bpb += static_cast<double>(p.forces->plan_bytes()) / static_cast<double>(d.bonds.size());
  MPI_Allreduce(&bpb, &bpb_max, 1, MPI_DOUBLE, MPI_MAX, p.comm);
  summary.bytes_per_bond = bpb_max;
  summary.partition_seconds = partition.seconds;
  summary.edge_cut = partition.edge_cut;
  summary.partition_method = to_string(method);
  // Balance of the bonds each rank actually holds (any partitioner).
  const double mine = static_cast<double>(d.bonds.size());
  double most = 0;
  MPI_Allreduce(&mine, &most, 1, MPI_DOUBLE, MPI_MAX, p.comm);
  summary.partition_balance = summary.ordered_bonds > 0 ? most * p.ranks / double(summary.ordered_bonds) : 1.0;
  halo_figures(p, summary.halo);
}

/// A lattice body's derived constants: its law's A, B, node mass; the initial stretches and the
/// wave speeds at them (Mooney-Rivlin and the lattice's own).
void lattice_derived(const Problem& p, std::size_t b, RunSummary& summary) {
  const MarderLaw& law = *p.forces->marder(b);
  const std::string pre = p.scene.bodies[b].name + ".";
  // Stretches of the initial homogeneous deformation along x and y (F = I + displacement gradient).
  const auto [lx, ly] = lattice_initial_stretches(p.scene.initial.displacement_gradient);
  const WaveSpeeds along_x = mooney_rivlin_wave_speeds(law.a, law.b, lx, ly);
  const WaveSpeeds along_y = mooney_rivlin_wave_speeds(law.a, law.b, ly, lx);
  auto& out = summary.derived;
  out.push_back({pre + "A", law.A});
  out.push_back({pre + "B", law.B});
  out.push_back({pre + "node_mass", law.mass});
  out.push_back({pre + "initial_stretch_x", lx});
  out.push_back({pre + "initial_stretch_y", ly});
  // Reference-frame speeds (reference distance per time) at the initial stretch.
  out.push_back({pre + "longitudinal_wave_speed_x", along_x.longitudinal});
  out.push_back({pre + "longitudinal_wave_speed_y", along_y.longitudinal});
  out.push_back({pre + "shear_wave_speed", along_x.shear});
  // The lattice's own long-wave speeds at that stretch (differ from the Mooney-Rivlin ones where
  // bonds are near u_c or on the cutoff branch; README "Marder lattice").
  const WaveSpeeds lat_x = marder_lattice_wave_speeds(law, lx, ly), lat_y = marder_lattice_wave_speeds(law, ly, lx, true);
  out.push_back({pre + "lattice_longitudinal_speed_x", lat_x.longitudinal});
  out.push_back({pre + "lattice_shear_speed_x", lat_x.shear});
  out.push_back({pre + "lattice_longitudinal_speed_y", lat_y.longitudinal});
  out.push_back({pre + "lattice_shear_speed_y", lat_y.shear});
  out.push_back({pre + "nodes", double(p.bodies[b].count)});
}

/// Each body's derived constants (its law's, elastic constants, wave speeds), the time steps and
/// the bond count.
void derived_constants(const Problem& p, RunSummary& summary) {
  auto& out = summary.derived;
  for (std::size_t b = 0; b < p.bodies.size(); ++b) {
    if (p.forces->marder(b)) {
      lattice_derived(p, b, summary);
      continue;
    }
    const BondLaw& law = p.forces->laws()[b];
    const BodyGeometry& g = p.bodies[b];
    const std::string pre = p.scene.bodies[b].name + ".";
    const ElasticConstants e = elastic_constants(law, g, p.density[b]);
    for (const auto& [key, value] : law.derived()) out.push_back({pre + key, value});
    out.push_back({pre + "horizon", law.horizon()});
    if (g.traits.dimension == 1) {  // a bar: E and its wave speed only
      out.push_back({pre + "youngs_modulus", e.youngs});
      out.push_back({pre + "longitudinal_wave_speed", e.c_longitudinal});
      out.push_back({pre + "spacing_along_path", g.spacing});
      out.push_back({pre + "nodes", double(g.count)});
      continue;
    }
    if (g.mesh_mean_edge > 0) {  // the mesh's mean edge, and the spacing the horizon is measured in
      out.push_back({pre + "mesh_mean_edge_length", g.mesh_mean_edge});
      out.push_back({pre + "spacing", g.spacing});
    }
    out.push_back({pre + "shear_modulus", e.mu});
    out.push_back({pre + "bulk_modulus", e.bulk});
    out.push_back({pre + "youngs_modulus", e.youngs});
    out.push_back({pre + "longitudinal_wave_speed", e.c_longitudinal});
    out.push_back({pre + "shear_wave_speed", e.c_shear});
    out.push_back({pre + "rayleigh_wave_speed", e.c_rayleigh});
    out.push_back({pre + "nodes", double(g.count)});
  }
  out.push_back({"dt_stable", p.stages.dt_stable});
  for (std::size_t s = 0; s < p.stages.dt.size(); ++s) {
    if (p.scene.stages[s].kind != StageKind::Dynamic) continue;
    out.push_back({"stages." + std::to_string(s) + ".dt", p.stages.dt[s]});
    out.push_back({"stages." + std::to_string(s) + ".steps", double(p.stages.steps[s])});
  }
  out.push_back({"ordered_bonds", double(summary.ordered_bonds)});
  // The output a fresh run writes (--dry-run shows it; the run refuses what will not fit).
  const std::int64_t frames = output_frames(p.scene.output, p.stages.total);
  summary.output = {{"frames", double(frames)},
                    {"frame_nodes", double(p.frame_nodes)},
                    {"frame_bytes", frame_bytes(p.scene.output, p.frame_nodes)},
                    {"bytes", output_bytes(p.scene.output, frames, p.frame_nodes, p.domain.global_nodes, true,
                                           static_cast<std::int64_t>(mesh_triangles(p.bodies).size()))}};
}

}  // namespace

Problem::Problem(const Scene& s, MPI_Comm c) : scene(s), comm(c) {
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
}

void apply_initial_conditions(const Problem& p) {
  const Initial& ic = p.scene.initial;
  const Domain& d = p.domain;
  const double pi = 3.14159265358979323846;
  const VecArray u(p.state->displacement()), v(p.state->velocity());
  for (std::int32_t i = 0; i < d.owned; ++i) {
    double r[3];
    for (int c = 0; c < 3; ++c) r[c] = d.X[3 * i + c] - ic.center[c];
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
      if (ic.seed_wavelength_x > 0) s *= std::sin(2 * pi * d.X[3 * i] / ic.seed_wavelength_x);
      if (ic.seed_wavelength_y > 0) s *= std::sin(2 * pi * d.X[3 * i + 1] / ic.seed_wavelength_y);
      u[3 * i + 2] += s;
    }
  }
  p.boundaries->apply_initial(v.data());
}

std::unique_ptr<Problem> build_problem(const Scene& scene, MPI_Comm comm, RunSummary& summary) {
  PetscLogEventBegin(events().setup, 0, 0, 0, 0);
  auto problem = std::make_unique<Problem>(scene, comm);
  Problem& p = *problem;
  mark_memory(summary, "start", comm);

  // Nodes, and every check that needs them, before anything is allocated per rank.
  PartitionSettings settings = partition_settings_from_options();
  PetscLogEventBegin(events().nodes, 0, 0, 0, 0);
  Nodes nodes = discretize_checked(p.scene, settings, comm, p.rank);
  std::vector<std::vector<std::int64_t>> regions = boundary_regions(p.scene, nodes, p.rank);
  std::vector<BondLaw> laws = calibrate_bodies(p.scene, nodes, p.density);
  p.frame_nodes = frame_node_count(p.scene, nodes);
  stop_point(comm);

  // The partition and this rank's domain: its nodes (owned, then ghosts) and bonds.
  double max_reach = 0;
  for (const BodyGeometry& g : nodes.bodies) max_reach = std::max(max_reach, reach(g));
  const CellList cells(nodes, max_reach);
  warn_touching_bodies(p.scene, nodes, cells, p.rank);
  PetscLogEventEnd(events().nodes, 0, 0, 0, 0);
  mark_memory(summary, "nodes", comm);
  PetscLogEventBegin(events().partition, 0, 0, 0, 0);
  settings.method = resolve_partition_method(settings.method, nodes);  // auto: rcb or cells
  Partition partition = partition_nodes(nodes, cells, p.ranks, comm, settings);
  PetscLogEventEnd(events().partition, 0, 0, 0, 0);
  warn_unused_partition_options(p.rank);
  stop_point(comm);
  mark_memory(summary, "partition", comm);
  Scene initial_cracks = p.scene;  // cracks named by release stages break later
  std::erase_if(initial_cracks.cracks, [&](const Crack& c) { return p.scene.released_later(c.name); });
  PetscLogEventBegin(events().bonds, 0, 0, 0, 0);
  p.domain = build_domain(initial_cracks, nodes, cells, partition, p.rank, [] { return stop_signal() != 0; });
  PetscLogEventEnd(events().bonds, 0, 0, 0, 0);
  stop_point(comm);  // before anything reads a domain the stop left unfinished
  count_edge_cut(partition, p.domain, comm);
  check_body_bonds(p.scene, nodes.bodies, p.domain, comm, p.rank);
  allocate_history(p.domain, laws);
  mark_memory(summary, "domain", comm);

  // What each rank keeps of the global node arrays, which end here: every rank keeps its own
  // nodes (owned and ghosts) in the domain, which is all that the stages, output, checkpoints and
  // crack tips read.
  p.boundaries = std::make_unique<Boundaries>(p.scene, node_boundaries(regions, nodes.size(), p.domain));
  std::optional<LongRangeForces> long_range;
  if (p.scene.long_range) long_range.emplace(make_long_range(p.scene, nodes, p.domain, comm));
  auto pressure = std::make_unique<Pressure>(p.scene, nodes.bodies, p.domain);
  decltype(regions)().swap(regions);
  partition.release_maps();
  p.bodies = std::move(nodes.bodies);
  nodes = Nodes{};
  check_release_stages(p);

  // The state, the force model (lattice bodies, the bond loop's plans) and the node masses.
  p.state = std::make_unique<State>(p.domain, comm);
  mark_memory(summary, "state", comm);
  p.forces = std::make_unique<Forces>(p.scene, p.bodies, p.domain, *p.state, std::move(laws), std::move(long_range), comm);
  node_masses(p);

  // Time steps: the bodies' stable bound (collective, per body, then the smallest), which the
  // tools' penalty lowers; then each stage's. The loads in the order their forces add up.
  std::vector<double> dt_undamped;
  const std::vector<double> dt_body = p.forces->stable_time_steps(p.density, &dt_undamped);
  const double dt_bodies = check_stable_step(p, dt_body, dt_undamped);
  auto tools = std::make_unique<Tools>(p.scene, dt_bodies, *p.state, p.domain, p.inv_density, comm);
  p.stages = plan_stages(p.scene, tools->stable_step(dt_bodies));
  warn_pair_contact(p.scene, p.stages, p.rank);
  if (!tools->empty()) {
    p.tools = tools.get();
    p.loads.push_back(std::move(tools));
  }
  if (!pressure->empty()) p.loads.push_back(std::move(pressure));

  // The state the run starts from (begin() applies the initial conditions again, or a
  // checkpoint's), checked with the boundaries and tools.
  apply_initial_conditions(p);
  check_initial_state(p);

  setup_figures(p, partition, settings.method, summary);
  derived_constants(p, summary);
  p.resolved = emit_scene(p.scene, derived_lines(summary));
  mark_memory(summary, "setup", comm);
  PetscLogEventEnd(events().setup, 0, 0, 0, 0);
  return problem;
}

}  // namespace peri
