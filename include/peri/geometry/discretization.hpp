// Discretization: scene bodies -> nodes (reference position X in 3D, measure, body), in the
// "natural" order: bodies in scene order, then each body's own order (its kind's module in
// src/geometry/kinds/: grids row-major, x fastest). The natural order is independent of the number
// of ranks; everything rank-independent (bond order, output) uses it.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "peri/scene/body_kind.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

/// Geometry facts of one body that later stages need.
struct BodyGeometry {
  int material = 0;          ///< index into Scene::materials
  BodyTraits traits;         ///< its kind's (scene/body_kind.hpp): dimension, grid, flat, ...
  Grid grid = Grid::Square;
  double spacing = 0.0;      ///< dx [m]
  double horizon = 0.0;      ///< delta [m]
  double thickness = 0.0;    ///< h [m] (membranes; 0 for solids)
  double cell_area = 0.0;    ///< in-plane area per node [m^2] (membranes; a mesh's: the mean)
  double mesh_mean_edge = 0.0;  ///< mesh bodies: the mesh's mean edge length [m] (0: no mesh)
  /// Nodes from a file (mesh, point cloud) or on a geodesic sphere: few families alike, so rows
  /// keep no family pattern where the loop can compute their reference geometry (FamilyPatterns'
  /// free rows).
  bool irregular = false;
  double area = 0.0;         ///< cross-section A [m^2] (fibers; their spacing is the arc step ds)
  double segment_length = 0.0;  ///< fibers: length of the segments long-range rules tell apart (0: one)
  /// Fibers: node offsets (from `first`) where each path starts, paths + 1 entries, and each
  /// path's arc step ds (one path unless the body is a network).
  std::vector<std::int64_t> path_first{0};
  std::vector<double> path_spacing;
  /// Spheres: the geodesic triangles (natural ids, counter-clockwise seen from outside) that carry
  /// the internal pressure; center and radius. Mesh membranes: the mesh's triangles (the file's
  /// orientation).
  std::vector<std::array<std::int64_t, 3>> triangles;
  std::array<double, 3> center{0, 0, 0};
  double radius = 0.0;
  Quadrature quadrature = Quadrature::PartialArea;
  std::int64_t first = 0;    ///< first natural node id
  std::int64_t count = 0;    ///< number of nodes
  std::array<std::int64_t, 3> cells{1, 1, 1};  ///< nodes per direction (rows for hex grids)
};

struct Nodes {
  std::vector<double> X;       ///< 3N reference positions [m]
  std::vector<double> volume;  ///< N measures [m^3]: cell area * thickness, or dx^3
  std::vector<int> body;       ///< N body indices
  std::vector<BodyGeometry> bodies;
  std::int64_t size() const { return static_cast<std::int64_t>(volume.size()); }
};

/// The triangles of the mesh membranes among `bodies` (natural ids, the files' orientation), in
/// body order: the surfaces the frames draw (a sphere's triangles carry its pressure only).
std::vector<std::array<std::int64_t, 3>> mesh_triangles(const std::vector<BodyGeometry>& bodies);

/// Where a body kind's discretize appends its nodes: the scene's node arrays, for one body.
class NodeSink {
 public:
  NodeSink(Nodes& nodes, int body) : nodes_(nodes), body_(body) {}
  /// A node at reference position (x, y, z) [m] with measure `measure` [m^3].
  void add(double x, double y, double z, double measure) {
    nodes_.X.insert(nodes_.X.end(), {x, y, z});
    nodes_.volume.push_back(measure);
    nodes_.body.push_back(body_);
  }
  /// Nodes of every body so far.
  std::int64_t size() const { return nodes_.size(); }

 private:
  Nodes& nodes_;
  int body_;
};

/// Rough size of a scene before anything is allocated (nodes, ordered bonds, bytes), and the
/// largest family: bonds per node min(body's nodes - 1, nodes within the horizon) of the body
/// with the most.
struct SizeEstimate {
  double nodes = 0, bonds = 0, bytes = 0;
  double largest_family = 0;
  int largest_family_body = -1;  ///< index into Scene::bodies
};
SizeEstimate estimate_size(const Scene& scene);

/// Frequency of the geodesic sphere of a sphere body: 10 n^2 + 2 nodes, edges about `spacing`
/// (kinds/sphere.cpp).
std::int64_t sphere_frequency(double radius, double spacing);

/// The polylines of a fiber body: its path, or the paths of its network (FiberNetwork)
/// (kinds/fiber.cpp).
std::vector<std::vector<Vec3>> fiber_paths(const Body& b);

/// Generate the nodes of every body. Throws InputError for absurd resolutions (more nodes than
/// fit in 32-bit local indices) naming the body.
Nodes discretize(const Scene& scene);

/// Indices (natural ids) of the nodes inside a region; InputError naming the region if none.
std::vector<std::int64_t> select_nodes(const Nodes& nodes, const Scene& scene,
                                       const Region& region, const std::string& what);

}  // namespace peri
