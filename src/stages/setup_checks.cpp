#include "peri/stages/setup_checks.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <utility>
#include <vector>

#include "peri/io/restart.hpp"
#include "peri/models/long_range.hpp"
#include "peri/models/marder.hpp"
#include "peri/models/model.hpp"
#include "peri/stages/problem.hpp"

namespace peri {
namespace {

constexpr double kFamilyWarning = 1e4;    // bonds per node beyond which a horizon is suspect
constexpr double kSmallestStep = 1e-150;  // [s]: 2 / dt^2 (a tool's penalty) stays finite
constexpr double kEnergyRange = 1e280;    // [J]: a body's energy scale sum m c_l^2 in [1/x, x]
constexpr double kLargestStrain = 100;    // initial displacement / body extent
constexpr double kSmallestStretch = 0.01;  // initial bond length / reference length under F = I + H
constexpr double kLargestWallStress = 100;  // sphere: p R / (2 h) / in-plane bulk modulus
// A node's distance from the origin in spacings (its largest coordinate / dx): positions are
// rounded to 2^-53 of their magnitude, so at 1e9 spacings to 1.1e-7 of a spacing (stretches
// below about 1e-6 are round-off; refused), at 1e6 spacings to 1.1e-10 (warned).
constexpr double kFarthestNode = 1e9;
constexpr double kFarNodeWarning = 1e6;
// A point cloud whose points' median volume^(1/3) is beyond this factor of the spacing (either way).
constexpr double kCloudSpacingRatio = 1.5;

std::string num(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

const char* beyond(double x) { return x > 1 ? "beyond the largest double" : "below the smallest normal double"; }

// The keys that give a body's node measure (its kind's).
std::string measure_keys(const Body& b) { return b.kind->measure_keys(b); }

}  // namespace

void stop_point(MPI_Comm comm) {
  int mine = stop_signal(), any = 0;
  MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, comm);
  if (any != 0)
    throw StopRequested("stopped by signal " + std::to_string(any) + " while setting up the run; nothing was written");
}

void warn_large_families(const Scene& scene, const SizeEstimate& e, int rank) {
  if (rank != 0 || !(e.largest_family > kFamilyWarning) || e.largest_family_body < 0) return;
  const Body& b = scene.bodies[static_cast<std::size_t>(e.largest_family_body)];
  std::fprintf(stderr,
               "peridrive: warning: %s: bodies.%s.%s: a horizon of %s m (%s spacings) gives each node about %s "
               "bonds, more than %s: setup, memory and every step grow as nodes x bonds per node (about %s "
               "bonds in all)\n",
               b.where.str().c_str(), b.name.c_str(), b.horizon ? "horizon" : "horizon_factor",
               num(b.horizon_value()).c_str(), num(b.horizon_value() / b.spacing).c_str(),
               num(e.largest_family).c_str(), num(kFamilyWarning).c_str(), num(e.bonds / 2).c_str());
}

void warn_overlapping_boundaries(const Scene& scene, const std::vector<std::vector<std::int64_t>>& bc_nodes, int rank) {
  if (rank != 0) return;
  // Two boundaries that prescribe the same motion in every stage may share nodes freely (clamps
  // meeting at a corner).
  const auto same_motion = [&](const Boundary& p, const Boundary& q) {
    if (p.components != q.components || p.velocity != q.velocity || p.ramp_time != q.ramp_time) return false;
    for (const Stage& st : scene.stages) {
      const auto in = [](const std::vector<BoundaryValue>& values, const std::string& name) {
        for (const BoundaryValue& v : values)
          if (v.boundary == name) return std::optional<Vec3>(v.value);
        return std::optional<Vec3>();
      };
      if (in(st.boundary_velocity, p.name) != in(st.boundary_velocity, q.name) ||
          in(st.displacements, p.name).value_or(Vec3{}) != in(st.displacements, q.name).value_or(Vec3{}))
        return false;
    }
    return true;
  };
  for (std::size_t a = 0; a < bc_nodes.size(); ++a)
    for (std::size_t b = a + 1; b < bc_nodes.size(); ++b) {
      if (same_motion(scene.boundaries[a], scene.boundaries[b])) continue;
      // select_nodes lists a region's nodes in ascending natural order.
      std::int64_t shared = 0;
      for (auto i = bc_nodes[a].begin(), j = bc_nodes[b].begin(); i != bc_nodes[a].end() && j != bc_nodes[b].end();) {
        if (*i < *j) ++i;
        else if (*j < *i) ++j;
        else ++shared, ++i, ++j;
      }
      if (shared == 0) continue;
      const std::string first = scene.boundaries[a].name, later = scene.boundaries[b].name;
      std::fprintf(stderr,
                   "peridrive: warning: %s: boundaries.%s.region and boundaries.%s.region share %lld nodes, which "
                   "they move differently; those follow '%s', the later one (its velocity, components, ramp and "
                   "stage values), not '%s'\n",
                   scene.boundaries[b].where.str().c_str(), first.c_str(), later.c_str(),
                   static_cast<long long>(shared), later.c_str(), first.c_str());
    }
}

void warn_pair_contact(const Scene& scene, const StagePlan& plan, int rank) {
  if (rank != 0 || !scene.long_range) return;
  for (const PairContactStep& c : pair_contact_steps(scene)) {
    const double allowed = c.with_bonds(plan.dt_stable), expected = PairContactStep::kMargin * allowed;
    for (std::size_t s = 0; s < scene.stages.size(); ++s) {
      const Stage& st = scene.stages[s];
      if (st.kind != StageKind::Dynamic || !c.exceeded_by(plan.dt[s], plan.dt_stable)) continue;
      std::fprintf(stderr,
                   "peridrive: warning: %s: long_range.pairs.%d pulls nodes together, and a pair that falls in from "
                   "rest comes to the potential's zero (sigma = %s m), where its stiffness (a node of fiber body '%s' "
                   "against a straight fiber) and the bonds' allow an explicit step of about %s s (the bonds alone: "
                   "%s s); stage '%s' steps %s s, more than %s of it, so the run will likely go unstable once nodes "
                   "meet: expected stages.%zu.dt at most %s s (or a safety_factor at most %s)\n",
                   scene.long_range->pairs[c.rule].where.str().c_str(), c.rule, num(c.sigma).c_str(), c.body.c_str(),
                   num(allowed).c_str(), num(plan.dt_stable).c_str(), st.name.c_str(), num(plan.dt[s]).c_str(),
                   num(PairContactStep::kMargin).c_str(), s, num(expected).c_str(), num(expected / plan.dt_stable).c_str());
      break;  // (one warning per rule: its first stage)
    }
  }
}

void warn_unused_safety_factor(const Scene& scene, int rank) {
  if (rank != 0) return;
  for (std::size_t k = 0; k < scene.stages.size(); ++k) {
    const Stage& st = scene.stages[k];
    if (st.kind != StageKind::Dynamic || !st.dt || !st.safety_factor_where) continue;
    std::fprintf(stderr,
                 "peridrive: warning: %s: stages.%zu.safety_factor: stage '%s' gives dt (%s s), which the stage "
                 "steps with; its safety_factor (%s) is not used\n",
                 st.safety_factor_where->str().c_str(), k, st.name.c_str(), num(*st.dt).c_str(),
                 num(st.safety_factor).c_str());
  }
}

void warn_aliased_seed(const Scene& scene, int rank) {
  const Initial& ic = scene.initial;
  if (rank != 0 || ic.seed_amplitude == 0 || scene.bodies.empty()) return;
  double spacing = INFINITY;  // the finest body's: the seed's shortest resolvable wavelength is twice it
  std::string body;
  for (const Body& b : scene.bodies)
    if (b.spacing < spacing) spacing = b.spacing, body = b.name;
  const std::pair<const char*, double> axes[2] = {{"x", ic.seed_wavelength_x}, {"y", ic.seed_wavelength_y}};
  for (const auto& [axis, wavelength] : axes)
    if (wavelength > 0 && wavelength < 2 * spacing)
      std::fprintf(stderr,
                   "peridrive: warning: %s: initial.seed.wavelength: %s m along %s is below two spacings of body "
                   "'%s' (%s m): the nodes sample the sine aliased (at one spacing, or a multiple of half of one, "
                   "every node of a grid lies on a zero and the seed does nothing); expected a wavelength of at "
                   "least %s m\n",
                   ic.seed_where.str().c_str(), num(wavelength).c_str(), axis, body.c_str(), num(spacing).c_str(),
                   num(2 * spacing).c_str());
}

void warn_cloud_spacing(const Scene& scene, int rank) {
  if (rank != 0) return;
  for (const Body& b : scene.bodies) {
    if (b.points.empty() || b.cloud.empty()) continue;
    std::vector<double> side(b.cloud.size());
    for (std::size_t k = 0; k < side.size(); ++k) side[k] = std::cbrt(b.cloud[k].volume);
    const auto middle = side.begin() + static_cast<std::ptrdiff_t>(side.size() / 2);
    std::nth_element(side.begin(), middle, side.end());
    const double typical = *middle, ratio = typical / b.spacing;
    if (ratio >= 1.0 / kCloudSpacingRatio && ratio <= kCloudSpacingRatio) continue;
    std::fprintf(stderr,
                 "peridrive: warning: %s: bodies.%s.spacing: %s m, but the cube root of the median volume of the "
                 "points of '%s' is %s m (%s spacings): the horizon (%s m) and the micromodulus assume points "
                 "about a spacing apart, each of volume spacing^3, so the body's stiffness is off by about "
                 "the ratio of the volumes (%s); give as spacing the points' typical distance\n",
                 b.where.str().c_str(), b.name.c_str(), num(b.spacing).c_str(), b.points.c_str(), num(typical).c_str(),
                 num(ratio).c_str(), num(b.horizon_value()).c_str(), num(ratio * ratio * ratio).c_str());
  }
}

void warn_touching_bodies(const Scene& scene, const Nodes& nodes, const CellList& cells, int rank) {
  const std::size_t nb = nodes.bodies.size();
  if (rank != 0 || nb < 2) return;
  // Each body's reference box; a pair is searched only where one box, grown by the pair's reach,
  // meets the other, and only over the first body's nodes inside it.
  std::vector<std::array<double, 6>> box(nb, {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY});
  std::vector<std::vector<std::int64_t>> of_body(nb);
  for (std::int64_t i = 0; i < nodes.size(); ++i) {
    const std::size_t b = static_cast<std::size_t>(nodes.body[i]);
    of_body[b].push_back(i);
    for (int c = 0; c < 3; ++c) {
      box[b][c] = std::min(box[b][c], nodes.X[3 * i + c]);
      box[b][3 + c] = std::max(box[b][3 + c], nodes.X[3 * i + c]);
    }
  }
  for (std::size_t a = 0; a < nb; ++a)
    for (std::size_t b = a + 1; b < nb; ++b) {
      const BodyGeometry &ga = nodes.bodies[a], &gb = nodes.bodies[b];
      if (ga.traits.long_range && gb.traits.long_range && scene.long_range) continue;
      // The larger horizon (a lattice's bond reach): two nodes closer than it would have bonded
      // in one body.
      const double r = std::max(ga.horizon > 0 ? ga.horizon : reach(ga), gb.horizon > 0 ? gb.horizon : reach(gb));
      bool apart = false;
      for (int c = 0; c < 3; ++c)
        apart = apart || box[a][c] > box[b][3 + c] + r || box[b][c] > box[a][3 + c] + r;
      if (apart) continue;
      double closest = INFINITY;
      std::int64_t ci = -1, cj = -1;
      for (const std::int64_t i : of_body[a]) {
        const double* xi = &nodes.X[3 * i];
        bool near = true;
        for (int c = 0; c < 3; ++c) near = near && xi[c] >= box[b][c] - r && xi[c] <= box[b][3 + c] + r;
        if (!near) continue;
        cells.for_each_candidate(xi, [&](std::int64_t j) {
          if (static_cast<std::size_t>(nodes.body[j]) != b) return;
          const double* xj = &nodes.X[3 * j];
          const double d = std::hypot(xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]);
          if (d < closest) {
            closest = d;
            ci = i;
            cj = j;
          }
        });
      }
      if (!(closest < r)) continue;
      auto at = [&](std::int64_t i) {  // (appended piece by piece: GCC 12 warns falsely on "(" + ...)
        std::string s = "(";
        for (int k = 0; k < 3; ++k) s += num(nodes.X[3 * i + k]) + (k < 2 ? ", " : ")");
        return s;
      };
      std::fprintf(stderr,
                   "peridrive: warning: bodies '%s' and '%s' come within %s m of each other (nodes at %s and %s), "
                   "inside a horizon (%s m): bodies do not bond to each other, so they meet without a force between "
                   "them; if they are one piece, make them one body (cutouts shape a grid body)\n",
                   scene.bodies[a].name.c_str(), scene.bodies[b].name.c_str(), num(closest).c_str(), at(ci).c_str(),
                   at(cj).c_str(), num(r).c_str());
    }
}

void check_polygon_cracks(const Scene& scene, const Nodes& nodes) {
  for (const Crack& c : scene.cracks) {
    if (!c.is_polygon()) continue;
    Vec3 lo = c.polygon[0], hi = c.polygon[0];
    for (const Vec3& p : c.polygon)
      for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], p[d]), hi[d] = std::max(hi[d], p[d]);
    const double size = std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
      const BodyGeometry& g = nodes.bodies[b];
      if (!g.traits.flat || g.count == 0) continue;
      const double z = nodes.X[3 * g.first + 2];  // a flat sheet's plane
      const bool in_plane = std::all_of(c.polygon.begin(), c.polygon.end(),
                                        [&](const Vec3& p) { return std::fabs(p[2] - z) <= 1e-9 * size; });
      if (in_plane)
        throw InputError(c.where.str() + ": cracks." + c.name + ".polygon: lies in the plane of the flat sheet '" +
                         scene.bodies[b].name + "' (z = " + num(z) + " m), where it would break every bond within "
                         "its area and leave the nodes there loose; expected a polygon across the sheet's plane (a cut "
                         "through the sheet), a slit {from, to}, or a cutout to remove the area");
    }
  }
}

void check_node_positions(const Scene& scene, const Nodes& nodes, int rank) {
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    const BodyGeometry& g = nodes.bodies[b];
    const Body& body = scene.bodies[b];
    double far = 0;
    std::int64_t at = -1;
    for (std::int64_t i = g.first; i < g.first + g.count; ++i)
      for (int d = 0; d < 3; ++d)
        if (!(std::fabs(nodes.X[3 * i + d]) <= far)) far = std::fabs(nodes.X[3 * i + d]), at = i;
    if (at < 0 || !(g.spacing > 0)) continue;
    const double ratio = far / g.spacing;
    if (ratio <= kFarNodeWarning) continue;
    const std::string where = !body.points.empty() || !body.mesh.empty() || !body.polyline.empty()
                                  ? "the file's coordinates"
                              : !body.path.empty() ? "path"
                              : body.network       ? "network"
                                                   : "origin";
    std::ostringstream msg;
    msg << body.where.str() << ": bodies." << body.name << ": a node at (" << num(nodes.X[3 * at]) << ", "
        << num(nodes.X[3 * at + 1]) << ", " << num(nodes.X[3 * at + 2]) << ") m lies ";
    if (std::isfinite(ratio))
      msg << num(ratio) << " spacings (" << num(g.spacing) << " m) from the origin, where a position is rounded to "
          << num(ratio * std::ldexp(1.0, -53)) << (ratio > 0x1p53 ? " spacings" : " of a spacing");
    else
      msg << "more than 1.8e+308 spacings (" << num(g.spacing) << " m) from the origin";
    if (std::isfinite(ratio) && ratio <= kFarthestNode) {
      if (rank == 0)
        std::fprintf(stderr, "peridrive: warning: %s: stretches that small are round-off; moved toward the origin "
                     "(%s), the body keeps positions to 1e-16 of its size\n", msg.str().c_str(), where.c_str());
      continue;
    }
    msg << "; expected every node within " << num(kFarthestNode) << " spacings of the origin: move the body ("
        << where << ") toward it";
    throw InputError(msg.str());
  }
}

void check_node_masses(const Scene& scene, const Nodes& nodes, const std::vector<BondLaw>& laws,
                       const std::vector<double>& density) {
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    const BodyGeometry& g = nodes.bodies[b];
    const Body& body = scene.bodies[b];
    const Material& mat = scene.material(body.material);
    double least = INFINITY, most = 0, all = 0;
    for (std::int64_t i = g.first; i < g.first + g.count; ++i) {
      least = std::min(least, nodes.volume[i]);
      most = std::max(most, nodes.volume[i]);
      all += nodes.volume[i];
    }
    if (g.count == 0) continue;
    std::ostringstream msg;
    const double rho = density[b];
    if (!usable(least) || !std::isfinite(most)) {
      const double bad = usable(least) ? most : least;
      msg << body.where.str() << ": bodies." << body.name << ": " << measure_keys(body) << " give nodes a measure of "
          << num(bad) << " m^3, " << beyond(bad)
          << "; expected a geometry whose node measures are finite doubles of at least 2.2e-308";
    } else if (!usable(rho * least) || !std::isfinite(rho * most)) {
      const double bad = usable(rho * least) ? rho * most : rho * least;
      msg << mat.where.str() << ": materials." << mat.name << ".density: " << num(rho) << " kg/m^3 gives the nodes of body '"
          << body.name << "' (measure " << num(bad / rho) << " m^3) a mass of " << num(bad) << " kg, " << beyond(bad)
          << "; expected a density whose node masses are finite doubles of at least 2.2e-308";
    } else {
      const double wave2 = mat.marder ? mat.marder->a
                                      : std::pow(elastic_constants(laws[b], g, rho).c_longitudinal, 2);
      const double mass = rho * all, scale = mass * wave2;  // sum m c_l^2
      if (scale >= 1 / kEnergyRange && scale <= kEnergyRange) continue;
      // The factor farthest from 1 (in decades) is named: the density, the geometry or the stiffness.
      const auto decades = [](double x) { return std::fabs(std::log10(x)); };
      const std::string what = "an energy scale sum m c_l^2 = " + num(scale) + " J (mass " + num(mass) + " kg, c_l^2 " +
                               num(wave2) + " m^2/s^2)";
      if (decades(wave2) > decades(mass))
        msg << mat.where.str() << ": " << stiffness_input(mat) << " gives body '" << body.name << "' " << what;
      else if (decades(rho) >= decades(all))
        msg << mat.where.str() << ": materials." << mat.name << ".density: " << num(rho) << " kg/m^3 gives body '"
            << body.name << "' " << what;
      else
        msg << body.where.str() << ": bodies." << body.name << ": " << measure_keys(body) << " give the body " << what;
      msg << "; expected " << num(1 / kEnergyRange) << " to " << num(kEnergyRange)
          << " J, so that energies, their sums and the balance's floor (1e-20 of it) stay finite doubles";
    }
    throw InputError(msg.str());
  }
}

void warn_unused_partition_options(int rank) {
  if (rank != 0) return;
  PetscInt n = 0;
  char** names = nullptr;
  char** values = nullptr;
  if (PetscOptionsLeftGet(nullptr, &n, &names, &values)) return;
  for (PetscInt k = 0; k < n; ++k)
    if (std::strncmp(names[k], "partition_", 10) == 0)
      std::fprintf(stderr,
                   "peridrive: warning: -%s: a partitioner option this run did not read (a misspelling? the "
                   "partitioner's options: -partition_method, -partition_cells_per_part, -partition_line_weight, "
                   "-partition_mat_partitioning_type and, with -partition_method petsc, PETSc's "
                   "-partition_mat_partitioning_*)\n",
                   names[k]);
  PetscOptionsLeftRestore(nullptr, &n, &names, &values);
}

void check_body_bonds(const Scene& scene, const std::vector<BodyGeometry>& bodies, const Domain& d, MPI_Comm comm,
                      int rank) {
  // Per body: ordered bonds, nodes without any, nodes; and the first node without a bond.
  const std::size_t n = scene.bodies.size();
  std::vector<long long> local(3 * n, 0), all(3 * n, 0);
  std::vector<long long> first_local(n, std::numeric_limits<long long>::max()), first(n);
  for (std::int32_t i = 0; i < d.owned; ++i) {
    const auto b = static_cast<std::size_t>(d.body[i]);
    const std::int64_t k = d.bonds.offsets[i + 1] - d.bonds.offsets[i];
    local[b] += k;
    local[n + b] += k == 0;
    ++local[2 * n + b];
    if (k == 0) first_local[b] = std::min<long long>(first_local[b], d.natural[i]);
  }
  MPI_Allreduce(local.data(), all.data(), static_cast<int>(3 * n), MPI_LONG_LONG, MPI_SUM, comm);
  MPI_Allreduce(first_local.data(), first.data(), static_cast<int>(n), MPI_LONG_LONG, MPI_MIN, comm);
  for (std::size_t b = 0; b < n; ++b) {
    const Body& body = scene.bodies[b];
    if (bodies[b].traits.lattice || all[2 * n + b] == 0 || all[n + b] == 0) continue;
    if (all[b] == 0)
      throw InputError(body.where.str() + ": bodies." + body.name + ": none of its " + std::to_string(all[2 * n + b]) +
                       " nodes has a bond: its horizon " + num(body.horizon_value()) +
                       " m reaches no other node; expected a horizon of a few of its nodes' spacings (horizon_factor "
                       "or horizon)");
    // The first node without a bond, and where it is (collective: its owner gives it).
    double X_local[3] = {0, 0, 0}, X[3];
    for (std::int32_t i = 0; i < d.owned; ++i)
      if (d.natural[i] == first[b])
        for (int c = 0; c < 3; ++c) X_local[c] = d.X[3 * static_cast<std::size_t>(i) + c];
    MPI_Allreduce(X_local, X, 3, MPI_DOUBLE, MPI_SUM, comm);
    if (rank == 0)
      std::fprintf(stderr,
                   "peridrive: warning: %s: bodies.%s: %lld of its %lld nodes have no bond (the first at (%s, %s, %s)): "
                   "nothing holds them, and they move only with their initial velocity and the loads on them; "
                   "cutouts, cracks or a mesh may have cut them off by more than the horizon %s m\n",
                   body.where.str().c_str(), body.name.c_str(), all[n + b], all[2 * n + b], num(X[0]).c_str(),
                   num(X[1]).c_str(), num(X[2]).c_str(), num(body.horizon_value()).c_str());
  }
}

double check_stable_step(const Problem& p, const std::vector<double>& dt_body, const std::vector<double>& dt_undamped) {
  const Scene& scene = p.scene;
  const std::size_t nb = dt_body.size();
  std::vector<double> dt(nb), dt0(nb);
  MPI_Allreduce(dt_body.data(), dt.data(), static_cast<int>(nb), MPI_DOUBLE, MPI_MIN, p.comm);
  MPI_Allreduce(dt_undamped.data(), dt0.data(), static_cast<int>(nb), MPI_DOUBLE, MPI_MIN, p.comm);
  double dt_stable = std::numeric_limits<double>::infinity();
  for (std::size_t b = 0; b < nb; ++b) {
    dt_stable = std::min(dt_stable, dt[b]);
    if (std::isinf(dt[b]) || dt[b] >= kSmallestStep) continue;  // inf: a body without bonds
    const Body& body = scene.bodies[b];
    const Material& mat = scene.material(body.material);
    std::ostringstream msg;
    // Bond dashpots lower the bound (dashpot_stable_time_step: dt^2 + 2 tau dt = dt0^2, about
    // dt0^2 / (2 tau) for a large tau, tau growing as the viscosity): where the bound without
    // them is of ordinary size, the viscosity is at fault.
    if (mat.kelvin_viscosity > 0 && dt0[b] >= kSmallestStep) {
      msg << mat.where.str() << ": materials." << mat.name << ".kelvin_viscosity: " << num(mat.kelvin_viscosity)
          << " m^2/s lowers the stable time step of body '" << body.name << "' from " << num(dt0[b]) << " s to "
          << num(dt[b]) << " s, below " << num(kSmallestStep)
          << " s; expected a smaller viscosity (the step falls as 1 / viscosity once the dashpots' time exceeds "
          << num(dt0[b]) << " s)";
      throw InputError(msg.str());
    }
    msg << body.where.str() << ": bodies." << body.name << ": the stable time step is " << num(dt[b])
        << " s, below " << num(kSmallestStep) << " s: " << stiffness_input(mat);
    if (!p.forces->marder(b)) msg << " gives a micromodulus c = " << num(p.forces->laws()[b].derived("micromodulus"));
    msg << ", too stiff for the node masses (density " << num(p.density[b])
        << " kg/m^3); expected a stiffness and density whose wave speed crosses a spacing in at least "
        << num(kSmallestStep) << " s";
    throw InputError(msg.str());
  }
  if (std::isfinite(dt_stable)) return dt_stable;
  std::int64_t mine = p.domain.bonds.size(), bonds = 0;
  MPI_Allreduce(&mine, &bonds, 1, MPI_INT64_T, MPI_SUM, p.comm);
  if (bonds == 0) throw InputError(scene.file + ": no node has a bond; the horizon is too small for the spacing");
  throw InputError(scene.file + ": the stable time step is not a finite number although " + std::to_string(bonds / 2) +
                   " bonds exist: the bond stiffness sums overflow; expected stiffness and density of ordinary size");
}

void check_stage(const Scene& scene, std::size_t s, double dt, double dt_stable) {
  const Stage& st = scene.stages[s];
  // Damping alpha: the half-step velocity is (1 - alpha dt / 2) v, which reverses and grows when
  // alpha dt / 2 exceeds 1 (the nodes then fly off instead of coming to rest).
  if (!(0.5 * st.damping * dt <= 1)) {
    std::ostringstream msg;
    msg << st.where.str() << ": stages." << s << ".damping: " << num(st.damping) << " 1/s with time steps of "
        << num(dt) << " s gives alpha dt / 2 = " << num(0.5 * st.damping * dt)
        << "; expected at most 1 (a damping of at most " << num(2 / dt) << " 1/s): beyond it the damped half "
        << "step reverses and amplifies the velocity";
    throw InputError(msg.str());
  }
  if (st.steps) return;  // bounded when read
  const double count = st.duration / dt;
  if (count <= static_cast<double>(kMaxStageSteps)) return;
  std::ostringstream msg;
  msg << st.where.str() << ": stages." << s << ".duration: " << num(st.duration) << " s in steps of " << num(dt)
      << " s (";
  if (st.dt) msg << "stages." << s << ".dt";
  else msg << "safety_factor " << num(st.safety_factor) << " x the stable bound " << num(dt_stable) << " s";
  msg << ") takes " << num(count) << " steps; expected at most " << kMaxStageSteps
      << " steps per stage: a shorter duration, a larger time step or a coarser spacing";
  throw InputError(msg.str());
}

void check_initial_state(const Problem& p) {
  const Scene& scene = p.scene;
  const Domain& domain = p.domain;
  const std::size_t nb = scene.bodies.size(), nt = scene.tools.size(), nc = scene.boundaries.size();
  const Initial& ic = scene.initial;
  // Maxima over all ranks: per body, the largest |u0|, |H (X - center)| and |v0| of a node
  // without boundary, and -lo, hi of its reference box (3 each); per tool, the deepest node inside
  // at t = 0; per boundary, the smallest spacing among its nodes' bodies (its negative). Sums: per
  // tool, the nodes inside.
  // Per stage: the largest |H_s (X - center)| of a boundary node (quasi-static stages' gradient).
  const std::size_t ns = scene.stages.size();
  const std::size_t n_max = 9 * nb + nt + nc + ns;
  std::vector<double> most(n_max, -INFINITY), count(nt, 0.0);
  double* u_max = most.data();
  double* affine_max = u_max + nb;
  double* v_max = affine_max + nb;
  double* lo_neg = v_max + nb;
  double* hi = lo_neg + 3 * nb;
  double* depth = hi + 3 * nb;
  double* neg_spacing = depth + nt;
  double* stage_affine = neg_spacing + nc;
  {
    const VecArrayRead u(p.state->displacement()), v(p.state->velocity());
    for (std::int32_t i = 0; i < domain.owned; ++i) {
      const int b = domain.body[i];
      const double* X = &domain.X[3 * static_cast<std::size_t>(i)];
      const double* ui = &u[3 * static_cast<std::size_t>(i)];
      const double* vi = &v[3 * static_cast<std::size_t>(i)];
      double affine[3] = {0, 0, 0};
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) affine[a] += ic.displacement_gradient[3 * a + c] * (X[c] - ic.center[c]);
      u_max[b] = std::max(u_max[b], std::hypot(ui[0], ui[1], ui[2]));
      affine_max[b] = std::max(affine_max[b], std::hypot(affine[0], affine[1], affine[2]));
      const int bc = p.boundaries->of(i);
      if (bc < 0) v_max[b] = std::max(v_max[b], std::hypot(vi[0], vi[1], vi[2]));
      else neg_spacing[bc] = std::max(neg_spacing[bc], -p.bodies[b].spacing);
      for (std::size_t st = 0; st < ns && bc >= 0; ++st) {
        const std::array<double, 9>& H = scene.stages[st].displacement_gradient;
        double a[3] = {0, 0, 0};
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) a[r] += H[3 * r + c] * (X[c] - ic.center[c]);
        stage_affine[st] = std::max(stage_affine[st], std::hypot(a[0], a[1], a[2]));
      }
      for (int c = 0; c < 3; ++c) {
        lo_neg[3 * b + c] = std::max(lo_neg[3 * b + c], -X[c]);
        hi[3 * b + c] = std::max(hi[3 * b + c], X[c]);
      }
      for (std::size_t k = 0; k < nt; ++k) {
        const Tool& t = scene.tools[k];
        double r2 = 0;
        for (int c = 0; c < (t.sphere ? 3 : 2); ++c) r2 += std::pow(X[c] + ui[c] - t.center[c], 2);
        if (!(r2 < t.radius * t.radius)) continue;
        count[k] += 1;
        depth[k] = std::max(depth[k], t.radius - std::sqrt(r2));
      }
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, most.data(), static_cast<int>(n_max), MPI_DOUBLE, MPI_MAX, p.comm);
  MPI_Allreduce(MPI_IN_PLACE, count.data(), static_cast<int>(nt), MPI_DOUBLE, MPI_SUM, p.comm);
  const std::string where = scene.file + ": ";
  // Each body's extent: the diagonal of its reference box.
  std::vector<double> diagonal(nb);
  for (std::size_t b = 0; b < nb; ++b) {
    double extent2 = 0;
    for (int c = 0; c < 3; ++c) extent2 += std::pow(hi[3 * b + c] + lo_neg[3 * b + c], 2);
    diagonal[b] = std::sqrt(extent2);
  }

  // Initial displacements: at most kLargestStrain times the body's extent.
  for (std::size_t b = 0; b < nb; ++b) {
    const double extent = std::max(diagonal[b], p.bodies[b].spacing);
    if (u_max[b] <= kLargestStrain * extent) continue;
    const bool affine = !(affine_max[b] <= kLargestStrain * extent);
    std::ostringstream msg;
    const SourceLoc& at = affine ? scene.initial.gradient_where : scene.initial.seed_where;
    msg << (at.file.empty() ? where : at.str() + ": ") << (affine ? "initial.displacement_gradient" : "initial.seed.amplitude")
        << ": displaces nodes of body '"
        << scene.bodies[b].name << "' by up to " << num(u_max[b]) << " m, more than " << num(kLargestStrain)
        << " times its extent (" << num(extent) << " m); expected an initial stretch of at most " << num(kLargestStrain + 1);
    throw InputError(msg.str());
  }
  // Quasi-static stages' prescribed motion: at most kLargestStrain times the largest body's
  // extent, as the initial displacement (beyond it Newton fails at the first increment, read as a
  // limit point).
  double largest_extent = 0;
  for (std::size_t b = 0; b < nb; ++b) largest_extent = std::max({largest_extent, diagonal[b], p.bodies[b].spacing});
  for (std::size_t st = 0; st < ns; ++st) {
    const Stage& stage = scene.stages[st];
    if (stage.kind != StageKind::QuasiStatic) continue;
    const std::string key = stage.where.str() + ": stages." + std::to_string(st);
    auto refuse = [&](const std::string& what, double by) {
      std::ostringstream msg;
      msg << key << what << ": moves boundary nodes by up to " << num(by) << " m over stage '" << stage.name
          << "', more than " << num(kLargestStrain) << " times the largest body's extent (" << num(largest_extent)
          << " m)";
      throw InputError(msg.str());
    };
    for (const BoundaryValue& bv : stage.displacements) {
      const double by = std::hypot(bv.value[0], bv.value[1], bv.value[2]);
      if (!(by <= kLargestStrain * largest_extent)) refuse(".displacements." + bv.boundary, by);
    }
    if (stage_affine[st] > kLargestStrain * largest_extent) refuse(".displacement_gradient", stage_affine[st]);
  }
  // The initial deformation gradient F = I + H collapses no bond: a bond it shortens to nothing
  // puts two nodes on top of each other (H = -I along a direction flattens the body onto a
  // plane). Per body, the smallest |F xi|^2 / |xi|^2 over the bonds, and where: on failure the bond
  // of the rank that holds the smallest names its direction (the same message on every rank).
  {
    const std::array<double, 9>& H = ic.displacement_gradient;
    std::vector<std::pair<double, int>> least(nb, {INFINITY, p.rank});
    std::vector<std::array<double, 3>> direction(nb, {0, 0, 0});
    // Per body with a law that breaks: its intact bonds, those F breaks at once, and the largest
    // stretch |F xi| / |xi| among the latter (sums, then the maximum).
    std::vector<double> breaking(2 * nb, 0.0), stretch_most(nb, 0.0);
    const BondFamilies& bonds = domain.bonds;
    for (std::int32_t i = 0; i < domain.owned; ++i) {
      const int b = domain.body[i];
      const BondLaw* law = p.forces->marder(static_cast<std::size_t>(b)) ? nullptr : &p.forces->laws()[b];
      if (law && (law->empty() || !law->breaks())) law = nullptr;
      const double* Xi = &domain.X[3 * static_cast<std::size_t>(i)];
      for (std::int64_t e = bonds.offsets[i]; e < bonds.offsets[i + 1]; ++e) {
        const double* Xj = &domain.X[3 * static_cast<std::size_t>(bonds.neighbor[e])];
        const double xi[3] = {Xj[0] - Xi[0], Xj[1] - Xi[1], Xj[2] - Xi[2]};
        double y[3];
        for (int a = 0; a < 3; ++a) y[a] = xi[a] + H[3 * a] * xi[0] + H[3 * a + 1] * xi[1] + H[3 * a + 2] * xi[2];
        const double xi2 = xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2], y2 = y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
        const double stretch2 = y2 / xi2;
        if (law && !bonds.broken[static_cast<std::size_t>(e)]) {
          breaking[2 * b] += 1;
          if (law->broken_at(xi2, y2)) {
            breaking[2 * b + 1] += 1;
            stretch_most[b] = std::max(stretch_most[b], std::sqrt(stretch2));
          }
        }
        if (!(stretch2 < least[b].first)) continue;
        least[b].first = stretch2;
        direction[b] = {xi[0], xi[1], xi[2]};
      }
    }
    MPI_Allreduce(MPI_IN_PLACE, least.data(), static_cast<int>(nb), MPI_DOUBLE_INT, MPI_MINLOC, p.comm);
    for (std::size_t b = 0; b < nb; ++b) {
      if (least[b].first >= kSmallestStretch * kSmallestStretch) continue;  // (a body without bonds keeps inf)
      MPI_Bcast(direction[b].data(), 3, MPI_DOUBLE, least[b].second, p.comm);
      const double length = std::hypot(direction[b][0], direction[b][1], direction[b][2]);
      std::ostringstream msg;
      const SourceLoc& at = scene.initial.gradient_where;
      msg << (at.file.empty() ? where : at.str() + ": ")
          << "initial.displacement_gradient: F = I + displacement_gradient shortens bonds of body '"
          << scene.bodies[b].name << "' along (" << num(direction[b][0] / length) << ", " << num(direction[b][1] / length)
          << ", " << num(direction[b][2] / length) << ") to " << num(std::sqrt(least[b].first))
          << " of their length, collapsing the body; expected every bond's initial stretch |F xi| / |xi| to be at least "
          << num(kSmallestStretch);
      throw InputError(msg.str());
    }
    // Bonds that F stretches beyond the critical stretch break in the first step: all of a body's
    // (a gradient of 3 on the slit membrane's lambda_0 = 2 turned the sheet to dust, reported as
    // "51094 bonds broken") is refused; some of them (long bonds under eq. 29's linear lambda_0,
    // a state on Fig. 3's curves) are named.
    MPI_Allreduce(MPI_IN_PLACE, breaking.data(), static_cast<int>(2 * nb), MPI_DOUBLE, MPI_SUM, p.comm);
    MPI_Allreduce(MPI_IN_PLACE, stretch_most.data(), static_cast<int>(nb), MPI_DOUBLE, MPI_MAX, p.comm);
    for (std::size_t b = 0; b < nb; ++b) {
      // (each bond is two ordered bonds, in its two ends' rows)
      const double intact = 0.5 * breaking[2 * b], broken = 0.5 * breaking[2 * b + 1];
      if (!(broken > 0)) continue;
      const Material& m = scene.material(scene.bodies[b].material);
      const SourceLoc& at = scene.initial.gradient_where;
      std::ostringstream msg;
      const std::string share = num(std::round(1000.0 * broken / intact) / 10.0);
      msg << (at.file.empty() ? where : at.str() + ": ") << "initial.displacement_gradient: stretches "
          << (broken == intact ? "every one" : num(broken) + " (" + share + "%)") << " of the " << num(intact)
          << " intact bonds of body '" << scene.bodies[b].name << "' beyond the critical stretch of materials."
          << scene.bodies[b].material << " (critical_stretch = " << num(m.critical_stretch.value_or(NAN));
      if (m.critical_stretch_at_horizon)
        msg << ", critical_stretch_at_horizon = " << num(*m.critical_stretch_at_horizon);
      msg << "), up to |F xi| / |xi| = " << num(stretch_most[b]) << ": they break in the first step";
      if (broken == intact) {
        msg << ", and the body falls apart; expected an initial stretch below the critical stretch";
        throw InputError(msg.str());
      }
      if (p.rank == 0) std::fprintf(stderr, "peridrive: warning: %s\n", msg.str().c_str());
    }
  }
  // A lattice stretched where it loses stiffness: its homogeneous state is unstable. With b < 0 the
  // Mooney-Rivlin sheet's c_l^2 = a [1 + (b/2)(lambda_across^2 - 1)] falls to 0 (b = -1 at Marder's
  // stretch (1.4, 2) gave NaN wave speeds, and the run went on). Tested on the lattice's own
  // long-wave stiffness, the same on every rank.
  for (std::size_t b = 0; b < nb; ++b) {
    const MarderLaw* law = p.forces->marder(b);
    if (!law) continue;
    const auto [lx, ly] = lattice_initial_stretches(ic.displacement_gradient);
    const WaveSpeeds x = marder_lattice_wave_speeds(*law, lx, ly), y = marder_lattice_wave_speeds(*law, ly, lx, true);
    const char* lost = !(x.longitudinal > 0)   ? "longitudinal stiffness along x (waves along x)"
                       : !(y.longitudinal > 0) ? "longitudinal stiffness along y (waves along y)"
                       : !(x.shear > 0 && y.shear > 0) ? "shear stiffness"
                                                        : nullptr;
    if (!lost) continue;
    const SourceLoc& at = scene.initial.gradient_where;
    std::ostringstream msg;
    msg << (at.file.empty() ? std::string() : at.str() + ": ")
        << "initial.displacement_gradient: stretches lattice body '" << scene.bodies[b].name << "' to (" << num(lx)
        << ", " << num(ly) << ") along (x, y), where its material (a = "
        << num(law->a) << ", b = " << num(law->b) << ") has no " << lost << ": the stretched lattice is unstable";
    // The lattice's six bonds at diag(lx, ly): the longest lies along x or at 60 degrees.
    const double diagonal = std::hypot(0.5 * lx, 0.5 * std::sqrt(3.0) * ly);
    const double longest = law->delta * std::max(lx, diagonal), shortest = law->delta * std::min(lx, diagonal);
    const bool along_y = x.longitudinal > 0;
    const double across = along_y ? lx : ly;
    const WaveSpeeds mr = mooney_rivlin_wave_speeds(law->a, law->b, along_y ? ly : lx, across);
    if (longest >= law->uc)
      msg << " (its bonds are stretched up to " << num(longest) << " m, beyond the fracture separation u_c = "
          << num(law->uc) << " m, where they carry no force)";
    else if (!(mr.longitudinal > 0))
      msg << " (the Mooney-Rivlin sheet's c_l^2 = a [1 + (b/2)(lambda_across^2 - 1)] <= 0: at lambda_across = "
          << num(across) << ", b must exceed " << num(-2.0 / (across * across - 1)) << ")";
    else if (shortest < law->delta + law->us)
      msg << " (its bonds, as short as " << num(shortest) << " m, are on the cutoff branch below Delta + u_s = "
          << num(law->delta + law->us) << " m (eq. 31), where the lattice departs from the Mooney-Rivlin sheet: "
          << "the derived constants lattice_*_speed_*)";
    else
      msg << " (its bonds, up to " << num(longest) << " m long, near the fracture separation u_c = " << num(law->uc)
          << " m, where the lattice departs from the Mooney-Rivlin sheet: the derived constants lattice_*_speed_*)";
    msg << "; expected a stretch and b at which the lattice keeps its stiffness";
    throw InputError(msg.str());
  }
  // Tools start clear of every node: one inside would be thrown out by a penalty force far
  // beyond what the time step resolves.
  for (std::size_t k = 0; k < nt; ++k) {
    if (count[k] == 0) continue;
    const Tool& t = scene.tools[k];
    std::ostringstream msg;
    msg << t.where.str() << ": tools." << k << ".center: tool '" << t.name << "' (" << (t.sphere ? "sphere" : "cylinder")
        << " of radius " << num(t.radius) << " m) holds " << num(count[k]) << " node" << (count[k] > 1 ? "s" : "")
        << " at t = 0, the deepest " << num(depth[k])
        << " m inside; expected a tool that starts clear of the body (move it out by at least that much)";
    throw InputError(msg.str());
  }
  // Motion per step: boundaries, tools and the initial velocity field move nodes by at most the
  // spacing (or stability.motion_per_step spacings, where larger) in one step.
  const double per_step = std::max(1.0, scene.stability.motion_per_step);
  double finest = INFINITY;
  for (const BodyGeometry& g : p.bodies) finest = std::min(finest, g.spacing);
  bool first = true;
  for (std::size_t s = 0; s < scene.stages.size(); ++s) {
    const Stage& st = scene.stages[s];
    if (st.kind != StageKind::Dynamic) {
      first = first && st.kind != StageKind::QuasiStatic;  // which leaves the nodes at rest
      continue;
    }
    const double dt = p.stages.dt[s];
    auto refuse = [&](const std::string& key, double speed, double spacing) {
      std::ostringstream msg;
      msg << key << ": " << num(speed) << " m/s moves nodes " << num(speed * dt) << " m in one step of stage '" << st.name
          << "' (dt = " << num(dt) << " s), more than " << (per_step > 1 ? num(per_step) + " x " : "") << "the spacing "
          << num(spacing) << " m; expected a speed of at most " << num(per_step * spacing / dt) << " m/s";
      throw InputError(msg.str());
    };
    for (std::size_t b = 0; b < nb && first; ++b)
      if (!(v_max[b] * dt <= per_step * p.bodies[b].spacing))
        refuse(where + "initial.velocity_gradient", v_max[b], p.bodies[b].spacing);
    for (std::size_t c = 0; c < nc; ++c) {
      const Boundary& bc = scene.boundaries[c];
      std::string key = bc.where.str() + ": boundaries." + bc.name + ".velocity";
      Vec3 vel = bc.velocity;
      for (const BoundaryValue& bv : st.boundary_velocity)
        if (bv.boundary == bc.name) {
          vel = bv.value;
          key = st.where.str() + ": stages." + std::to_string(s) + ".boundary_velocity." + bc.name;
        }
      for (int d = 0; d < 3; ++d) vel[d] = bc.components[d] ? vel[d] : 0.0;
      const double speed = std::hypot(vel[0], vel[1], vel[2]), spacing = -neg_spacing[c];
      if (!(speed * dt <= per_step * spacing)) refuse(key, speed, spacing);
    }
    for (std::size_t k = 0; k < nt; ++k) {
      const Tool& t = scene.tools[k];
      const double speed = std::hypot(t.velocity[0], t.velocity[1], t.velocity[2]);
      const std::string key = t.where.str() + ": tools." + std::to_string(k) + ".velocity";
      if (!(speed * dt <= per_step * finest)) refuse(key, speed, finest);
      // Whatever motion_per_step allows: a tool that moves more than its radius in one step takes
      // a node at its leading face past its axis (or centre), and the penalty, along the normal
      // from there, pushes the node out of its far side: the tool tunnels through the body.
      if (!(speed * dt <= t.radius)) {
        std::ostringstream msg;
        msg << key << ": " << num(speed) << " m/s moves tool '" << t.name << "' " << num(speed * dt)
            << " m in one step of stage '" << st.name << "' (dt = " << num(dt) << " s), more than its radius "
            << num(t.radius) << " m: nodes at its leading face are taken past its axis and pushed out of its far side, "
               "and the tool tunnels through the body, whatever stability.motion_per_step allows; expected a speed of "
               "at most "
            << num(t.radius / dt) << " m/s";
        throw InputError(msg.str());
      }
    }
    first = false;
  }
  // Internal pressure: a wall stress p R / (2 h) beyond kLargestWallStress in-plane bulk moduli
  // tears any sphere at once (and overflows the forces long before that). R: a sphere's radius;
  // for a mesh membrane, whose curvature the check does not know, half its extent (a tube's
  // hoop stress p R / h is within a few times that).
  for (std::size_t b = 0; b < nb; ++b) {
    const Body& body = scene.bodies[b];
    if (!(body.pressure > 0)) continue;  // (spheres and mesh membranes take a pressure)
    const bool sphere = body.radius > 0;
    const double R = sphere ? body.radius : 0.5 * diagonal[b];
    const double stress = body.pressure * R / (2 * body.thickness);
    const double bulk = elastic_constants(p.forces->laws()[b], p.bodies[b], p.density[b]).bulk;
    if (stress <= kLargestWallStress * bulk) continue;  // (a NaN or inf stress is refused)
    std::ostringstream msg;
    msg << body.where.str() << ": bodies." << body.name << ".pressure: " << num(body.pressure)
        << " Pa gives the wall a stress p R / (2 h) = " << num(stress) << " Pa"
        << (sphere ? "" : " (R = " + num(R) + " m, half the body's extent)") << ", more than "
        << num(kLargestWallStress) << " times its in-plane bulk modulus " << num(bulk) << " Pa; expected at most "
        << num(kLargestWallStress * bulk * 2 * body.thickness / R) << " Pa";
    throw InputError(msg.str());
  }
}

}  // namespace peri
