#include "peri/stages/geometry_warnings.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "peri/core/format.hpp"
#include "peri/stages/problem.hpp"

namespace peri {
namespace {

// Thickness of a sheet or diameter of a fiber, in horizons (or lattice spacings), beyond which it
// is not a membrane or a bar: a length in mm written as m is 1000 times too large and lands far beyond.
constexpr double kThickBody = 10.0;

}  // namespace

void warn_thick_bodies(const Scene& scene, const Nodes& nodes, int rank) {
  if (rank != 0) return;
  for (std::size_t k = 0; k < nodes.bodies.size() && k < scene.bodies.size(); ++k) {
    const BodyGeometry& g = nodes.bodies[k];
    const Body& b = scene.bodies[k];
    const bool fiber = b.diameter > 0;
    const double across = fiber ? b.diameter : g.thickness;
    const double length = std::max(g.horizon, g.spacing);  // (a lattice's reach is its spacing)
    if (!(across > kThickBody * length)) continue;
    const std::string what = fiber
        ? "the fiber model is for bars thin against their horizon (no bending, no contact across the width), "
          "and the diameter scales the fiber's mass and stiffness; a diameter in other units than m?"
        : "the sheet models are for sheets thin against their horizon (no bending, no shear through the "
          "thickness), and the thickness scales the sheet's mass, stiffness and pressure stress; a thickness "
          "in mm? (0.5 mm is 0.0005 m)";
    std::fprintf(stderr, "peridrive: warning: %s: bodies.%s.%s: %s m is %s times the %s (%s m): %s\n",
                 b.where.str().c_str(), b.name.c_str(), fiber ? "diameter" : "thickness",
                 number_text(across).c_str(), number_text(across / length).c_str(),
                 g.horizon >= g.spacing ? "horizon" : "spacing", number_text(length).c_str(), what.c_str());
  }
}

void warn_flattened_meshes(const Scene& scene, int rank) {
  if (rank != 0) return;
  for (const Body& b : scene.bodies) {
    if (!b.mesh_data) continue;
    if (const Vec3& n = b.mesh_data->tilted_normal; n[0] != 0 || n[1] != 0 || n[2] != 0) {
      const auto component = [](double c) { return number_text(std::fabs(c) < 1e-12 ? 0.0 : c); };  // (no round-off)
      std::fprintf(stderr,
                   "peridrive: warning: %s: bodies.%s.mesh: '%s' is a plane sheet with normal (%s, %s, %s), not "
                   "along z: it runs as a curved sheet (no crack tips tracked, quasi-static in_plane stages do "
                   "not hold it in its plane, slits cut it along their xy projection); rotate the mesh into a "
                   "plane z = constant to have it flat\n",
                   b.where.str().c_str(), b.name.c_str(), b.mesh.c_str(), component(n[0]).c_str(),
                   component(n[1]).c_str(), component(n[2]).c_str());
      continue;
    }
    if (!(b.mesh_data->flattened > 0)) continue;
    std::fprintf(stderr,
                 "peridrive: warning: %s: bodies.%s.mesh: the nodes of '%s' lie within %s m in z (at most %s of "
                 "its size): taken as a flat sheet, every z set to %s m (crack tips tracked, in_plane stages hold "
                 "it in its plane)\n",
                 b.where.str().c_str(), b.name.c_str(), b.mesh.c_str(), number_text(b.mesh_data->flattened).c_str(),
                 number_text(kFlatMeshTolerance).c_str(),
                 number_text(b.mesh_data->nodes.empty() ? 0.0 : b.mesh_data->nodes[0][2]).c_str());
  }
}

void warn_slit_far_walls(const std::string& subject, const char* verb, long long count, const std::string& body,
                         double horizon, const char* from, double farthest) {
  std::fprintf(stderr,
               "peridrive: warning: %s %s %lld bonds of the curved sheet '%s' farther than its horizon (%s m) from "
               "%s in space, up to %s m: a slit is taken in the xy plane and cuts every wall above and below it; a "
               "polygon crack cuts one wall (docs/user/precracks.md)\n",
               subject.c_str(), verb, count, body.c_str(), number_text(horizon).c_str(), from,
               number_text(farthest).c_str());
}

void warn_far_slit_walls(const Problem& p) {
  const Domain& d = p.domain;
  std::vector<std::int64_t> far(d.crack_far.begin(), d.crack_far.end());
  std::vector<double> far_most(d.crack_far_most.begin(), d.crack_far_most.end());
  if (!far.empty()) {
    MPI_Allreduce(MPI_IN_PLACE, far.data(), static_cast<int>(far.size()), MPI_INT64_T, MPI_SUM, p.comm);
    MPI_Allreduce(MPI_IN_PLACE, far_most.data(), static_cast<int>(far_most.size()), MPI_DOUBLE, MPI_MAX, p.comm);
  }
  const std::size_t nb = p.bodies.size();
  std::size_t k = 0;
  for (std::size_t c = 0; c < p.scene.cracks.size() && p.rank == 0; ++c) {
    const Crack& crack = p.scene.cracks[c];
    if (p.scene.released_later(crack.name)) continue;
    const std::size_t at = k++;
    for (std::size_t b = 0; b < nb && (at + 1) * nb <= far.size(); ++b) {
      const std::int64_t n = far[at * nb + b] / 2;  // (each bond from both ends)
      if (n == 0) continue;
      warn_slit_far_walls(crack.where.str() + ": cracks: the slit '" + crack.name + "'", "breaks", n,
                          p.scene.bodies[b].name, p.bodies[b].horizon, "the slit", far_most[at]);
    }
  }
}

}  // namespace peri
