// What the body kinds' modules share: the horizon keys, the grid sheet's keys and nodes, a box
// key table, and the texts of their messages. Private to src/geometry/kinds/.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "peri/core/format.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/scene/body_kind.hpp"
#include "peri/scene/located_yaml.hpp"
#include "peri/scene/writer.hpp"

namespace peri::kinds {

using scene_detail::Key;
using scene_detail::Keys;
using scene_detail::kBoxKeys;
using scene_detail::Map;
using scene_detail::Value;
using scene_detail::Writer;

inline constexpr double kPi = 3.14159265358979323846;

/// The UTF-8 byte order mark some programs (spreadsheets' "CSV UTF-8") write first in a text file:
/// the text readers skip it.
inline constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

// The horizon of a peridynamic body: horizon_factor (m spacings) or horizon [m].
inline const Key kHorizonFactorKey = {.name = "horizon_factor", .fallback = "3",
                                      .doc = "m of delta = m dx, >= 1; not with horizon"};
inline const Key kHorizonKey = {.name = "horizon", .unit = "m", .fallback = "horizon_factor x spacing",
                                .doc = "delta itself, >= spacing; not with horizon_factor"};
void read_horizon(const Map& m, Body& b);
/// horizon and horizon_factor exclude each other: writes the one in effect.
void emit_horizon(Writer& w, const Body& b);

/// Nodes inside a horizon of m spacings on a grid of dimension d (continuum estimate with the
/// boundary cells): pi (m + 0.71)^2 or 4/3 pi (m + 0.71)^3.
double grid_family(const Body& b, int dimension);

/// A flat sheet on a grid (membranes, lattices): origin, size [Lx, Ly], thickness, spacing (the
/// reader has checked that they are given).
void read_sheet_extent(const Map& m, Body& b);
/// Its nodes at the centres of the grid's cells, rows along x: square (dx by dx cells) or
/// hexagonal (rows dx sqrt(3)/2 apart, odd rows shifted by dx/2); measure cell area x h.
void grid_sheet_nodes(const Body& b, BodyGeometry& g, NodeSink& sink);
/// Nodes of a grid sheet before any is made (a hexagonal grid has 2/sqrt(3) more).
double grid_sheet_count(const Body& b);

/// The first point (in order) within `tol` of an earlier one, and that one, hashed on cells of
/// size `cell` >= tol; {n, n} when none (or when a coordinate is beyond 1e15 cells).
std::pair<std::size_t, std::size_t> first_close_pair(const std::vector<Vec3>& x, double cell, double tol);

/// Number of grid cells along a length (at least one).
std::int64_t count_along(double length, double dx);

// Cutouts (cutouts.cpp): regions whose nodes a grid body drops before bonds are built.
inline const Keys kCutoutKeys = {
    {.name = "kind", .required = true, .what = "the cutout's shape: circle, box, polygon, sphere or cylinder",
     .doc = "`circle` (center, radius: the nodes within radius of center in the xy plane; through a solid along "
            "z), `box` (min, max: a closed box), `polygon` (vertices: the nodes inside it in the xy plane, "
            "even-odd rule; through a solid along z), `sphere` (center, radius; solids) or `cylinder` (center, "
            "radius, axis: unbounded along its axis; solids)"},
    {.name = "center", .unit = "m", .fallback = "required (circle, sphere, cylinder)",
     .doc = "circle: [x, y]; sphere: [x, y, z]; cylinder: a point [x, y, z] on its axis"},
    {.name = "radius", .unit = "m", .fallback = "required (circle, sphere, cylinder)",
     .doc = "> 0; nodes at a distance <= radius are removed"},
    {.name = "axis", .fallback = "z", .doc = "cylinder: its axis, `x`, `y` or `z`"},
    {.name = "min", .unit = "m", .fallback = "required (box)", .doc = "box: lower corner [x, y, z]"},
    {.name = "max", .unit = "m", .fallback = "required (box)",
     .doc = "box: upper corner [x, y, z], >= min in every component"},
    {.name = "vertices", .unit = "m", .fallback = "required (polygon)",
     .doc = "polygon: at least 3 corners [[x, y], ...] in order, each different from the one before, enclosing "
            "an area (the last joins the first); a node exactly on an edge may fall either way"},
};
inline const Key kCutoutsKey = {
    .name = "cutouts", .fallback = "none",
    .doc = "list of regions whose nodes are removed before bonds are built (a hole, a notch) "
           "(`bodies.<name>.cutouts[i]`); removed nodes do not exist at all. Each cutout must remove at least "
           "one node and the body must keep one; --dry-run's size estimate ignores them"};
void read_cutouts(const Map& m, Body& b, int dimension);
void emit_cutouts(Writer& w, const Body& b);

/// What a kind's discretize adds its candidate nodes to when the body may have cutouts: passes
/// on those no cutout holds. finish() throws InputError for a cutout that held no candidate
/// (named at its line) and for cutouts that removed every candidate (at the body's line).
class CutSink {
 public:
  CutSink(const Body& b, NodeSink& sink);
  void add(double x, double y, double z, double measure);
  void finish() const;

 private:
  const Body& body_;
  NodeSink& sink_;
  std::int64_t first_;
  std::int64_t candidates_ = 0;
  std::vector<std::int64_t> held_;
};

// Point clouds (point_cloud.cpp).
/// A file named by the scene value v, resolved against the scene file's folder (the working
/// directory for a value set by --set), absolute.
std::string resolve_input_path(const Value& v, const std::string& path);
/// Reads the point cloud v names (CSV; HDF5 for .h5 and .hdf5: the 1D datasets x, y, z, volume
/// and optionally material) into b.points (its resolved path), b.cloud (the rows the body takes,
/// in file order) and b.cloud_materials. InputError naming the file and line (HDF5: point).
void read_point_cloud(const Value& v, Body& b);

// Meshes (mesh_file.cpp).
/// Reads the mesh file v names (Gmsh's .msh, or any format Gmsh opens: STL, ...) through Gmsh's
/// API into b.mesh (its resolved path) and b.mesh_data: its 3-node triangles (dimension 2) or
/// 4-node tetrahedra (dimension 3), coordinates times b.scale, and its named physical groups.
/// Sets b.spacing to the mean edge length unless b.spacing_given. InputError naming the file and
/// the element or node: unreadable file, no such elements, an element type the body cannot take,
/// a degenerate or inverted element, two nodes at one position.
void read_mesh_file(const Value& v, Body& b, int dimension);
/// For a follower pressure: InputError unless every edge two triangles share runs in opposite
/// directions in them (one orientation over the surface), naming the two elements.
void check_mesh_orientation(const Body& b);
/// The mesh keys (mesh, scale) and what they exclude, for the membrane and solid kinds.
extern const Key kMeshKey2, kMeshKey3, kScaleKey;

/// "bodies.<name>.<key> <value> m" for messages.
std::string key_text(const Body& b, const char* key, double value);

}  // namespace peri::kinds
