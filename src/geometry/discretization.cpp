#include "peri/geometry/discretization.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace peri {

SizeEstimate estimate_size(const Scene& scene) {
  SizeEstimate e;
  double dashpot_bytes = 0, free_bytes = 0;
  for (std::size_t bi = 0; bi < scene.bodies.size(); ++bi) {
    const Body& b = scene.bodies[bi];
    const double n = b.kind->node_estimate(b);
    // A horizon that takes in the whole body bonds every node to every other, no more.
    const double family = std::min(b.kind->family_estimate(b), std::max(n - 1, 0.0));
    e.nodes += n;
    e.bonds += n * family;
    // Irregular bodies (meshes, point clouds, geodesic spheres): a float weight per ordered bond,
    // or the bond loop's interleaved neighbour lists (RowBlocks::free_lanes), 4 bytes either way.
    if (!b.mesh.empty() || !b.points.empty() || b.kind->traits.irregular) free_bytes += 4.0 * n * family;
    // Bond dashpots (peridynamic laws; the lattice computes its own): per ordered bond a constant
    // and the neighbour once more, in the pass's vector groups (DashpotLanes: 12 bytes a slot, the
    // groups' slots 1.01-1.04 times the bonds in the scenes), and per node the dashpot force and the
    // velocity they saw and the pass's node records (64 bytes, dashpot_records).
    const Material& m = scene.material(b.material);
    if (m.kelvin_viscosity > 0)
      dashpot_bytes += m.model == "marder" ? 48.0 * n : 12.5 * n * family + 112.0 * n;
    if (family > e.largest_family) {
      e.largest_family = family;
      e.largest_family_body = static_cast<int>(bi);
    }
  }
  // 5 bytes per ordered bond (32-bit neighbour, flag; the reference geometry is shared by family
  // patterns; 9 in irregular bodies) + ~350 bytes per node (state, PETSc, forces, output), as measured at 1M nodes.
  e.bytes = 5.0 * e.bonds + 350.0 * e.nodes + dashpot_bytes + free_bytes;
  return e;
}

Nodes discretize(const Scene& scene) {
  Nodes nodes;
  const SizeEstimate est = estimate_size(scene);
  if (est.nodes > 2.0e9 || est.bonds > 2.0e11) {
    std::ostringstream msg;
    msg << scene.file << ": the scene asks for about " << est.nodes << " nodes and " << est.bonds
        << " bonds (" << est.bytes / 1e9 << " GB); peridrive indexes nodes with 32 bits per rank "
        << "and cannot run it: increase the spacing";
    throw InputError(msg.str());
  }
  nodes.X.reserve(static_cast<std::size_t>(3 * est.nodes));
  for (std::size_t bi = 0; bi < scene.bodies.size(); ++bi) {
    const Body& b = scene.bodies[bi];
    BodyGeometry g;
    g.material = scene.material_index(b.material);
    g.traits = b.kind->traits;
    g.irregular = g.traits.irregular;
    g.grid = b.grid;
    g.spacing = b.spacing;
    g.horizon = b.horizon_value();
    g.quadrature = b.quadrature;
    g.first = nodes.size();
    NodeSink sink(nodes, static_cast<int>(bi));
    b.kind->discretize(b, g, sink);
    g.count = nodes.size() - g.first;
    nodes.bodies.push_back(g);
  }
  return nodes;
}

std::vector<std::int64_t> select_nodes(const Nodes& nodes, const Scene& scene,
                                       const Region& region, const std::string& what) {
  int only_body = -1;
  if (!region.body.empty())
    for (std::size_t b = 0; b < scene.bodies.size(); ++b)
      if (scene.bodies[b].name == region.body) only_body = static_cast<int>(b);
  std::vector<std::int64_t> ids;
  if (!region.group.empty()) {  // a mesh body's physical group (the reader checked it holds a node)
    const BodyGeometry& g = nodes.bodies[only_body];
    for (const std::int64_t k : scene.bodies[only_body].mesh_data->group(region.group)->nodes) ids.push_back(g.first + k);
    return ids;
  }
  for (std::int64_t i = 0; i < nodes.size(); ++i) {
    if (only_body >= 0 && nodes.body[i] != only_body) continue;
    if (region.contains({nodes.X[3 * i], nodes.X[3 * i + 1], nodes.X[3 * i + 2]})) ids.push_back(i);
  }
  if (ids.empty()) {
    std::ostringstream msg;
    msg.precision(6);
    msg << region.where.str() << ": " << what << ": the region [" << region.min[0] << ", "
        << region.min[1] << ", " << region.min[2] << "] .. [" << region.max[0] << ", "
        << region.max[1] << ", " << region.max[2] << "] selects no node"
        << (region.body.empty() ? "" : " of body '" + region.body + "'")
        << "; expected a box containing at least one node";
    throw InputError(msg.str());
  }
  return ids;
}

std::vector<std::array<std::int64_t, 3>> mesh_triangles(const std::vector<BodyGeometry>& bodies) {
  std::vector<std::array<std::int64_t, 3>> triangles;
  for (const BodyGeometry& g : bodies)
    if (g.mesh_mean_edge > 0) triangles.insert(triangles.end(), g.triangles.begin(), g.triangles.end());
  return triangles;
}

}  // namespace peri
