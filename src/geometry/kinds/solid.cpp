// Body kind `solid`: a box of simple-cubic points at the centres of dx-cubes, measure dx^3 (3D
// PMB solids), or a point cloud read from a CSV file (point_cloud.cpp), each point with its own
// volume, or the vertices of a tetrahedral mesh (mesh_file.cpp), each with a quarter of its
// tetrahedra's volumes; cutouts remove nodes of the box and the cloud.
#include <algorithm>

#include "common.hpp"
#include "kinds.hpp"

namespace peri::kinds {
namespace {

using scene_detail::format_number;
using scene_detail::join;

void read(const Map& m, Body& b, const Material&) {
  if (auto mesh = m.get("mesh")) {
    for (const char* key : {"origin", "size", "grid", "points", "cutouts"})
      if (auto x = m.get(key))
        x->fail(std::string("not with mesh: a mesh solid takes its nodes from the file, not from ") + key);
    if (auto x = m.get("scale")) b.scale = x->positive("");
    if (auto x = m.get("spacing"))
      b.spacing = x->positive("m");
    else
      b.spacing_given = false;
    read_mesh_file(*mesh, b, 3);
    read_horizon(m, b);
    b.quadrature = Quadrature::Full;
    if (auto x = m.get("quadrature"))
      b.quadrature = x->choice<Quadrature>({{"full", Quadrature::Full}, {"taper", Quadrature::Taper}});
    return;
  }
  if (auto x = m.get("scale")) x->fail("only with mesh: scale multiplies a mesh file's coordinates");
  if (!m.given("spacing")) m.missing("spacing", "grid spacing, m");
  if (auto points = m.get("points")) {
    // A point cloud: the file gives the nodes; the box's keys have no meaning.
    for (const char* key : {"origin", "size", "grid"})
      if (auto x = m.get(key))
        x->fail(std::string("not with points: a point-cloud solid takes its nodes from the file, not from ") + key);
    b.spacing = m.at("spacing").positive("m");
    read_horizon(m, b);  // before the file: a point's volume is checked against the horizon's ball
    read_point_cloud(*points, b);
  } else {
    if (!m.given("origin")) m.missing("origin", "lower corner [x, y, z], m; or points or mesh");
    if (!m.given("size")) m.missing("size", "extent [Lx, Ly, Lz] of the box, m; or points or mesh");
    b.origin = m.at("origin").vec3("m");
    const Value size = m.at("size");
    const std::string expected = "a solid size [Lx, Ly, Lz] with all entries > 0 [m]";
    const auto xs = size.numbers(3, 3, expected, "m");
    if (!(xs[0] > 0 && xs[1] > 0 && xs[2] > 0))
      size.fail("expected " + expected + ", got [" +
                join({format_number(xs[0]), format_number(xs[1]), format_number(xs[2])}) + "]");
    b.size = {xs[0], xs[1], xs[2]};
    const Value spacing = m.at("spacing");
    b.spacing = spacing.positive("m");
    const double smallest = std::min({b.size[0], b.size[1], b.size[2]});
    if (b.spacing > smallest)
      spacing.fail("spacing must not exceed the smallest extent of size (" + format_number(smallest) + " m), got " +
                   spacing.got());
    if (auto x = m.get("grid")) {
      b.grid = x->choice<Grid>({{"square", Grid::Square}, {"hexagonal", Grid::Hexagonal}});
      if (b.grid != Grid::Square) x->fail("a solid body supports only grid square, got " + x->got());
    }
    read_horizon(m, b);
  }
  if (auto x = m.get("quadrature"))
    b.quadrature = x->choice<Quadrature>(
        {{"full", Quadrature::Full}, {"partial_area", Quadrature::PartialArea}, {"taper", Quadrature::Taper}});
  read_cutouts(m, b, 3);
}

void emit(Writer& w, const Body& b) {
  if (!b.mesh.empty()) {
    w.key(4, "mesh", scene_detail::yaml_string(b.mesh));
    w.key(4, "scale", b.scale);
    if (b.spacing_given)
      w.key(4, "spacing", b.spacing);
    else
      w.line(4, "# spacing: not given; the mesh's mean edge length " + format_number(b.spacing) + " m");
    emit_horizon(w, b);
    w.key(4, "quadrature", scene_detail::to_text(b.quadrature));
    return;
  }
  if (!b.points.empty()) {
    w.key(4, "points", scene_detail::yaml_string(b.points));
  } else {
    w.key(4, "origin", scene_detail::flow(b.origin));
    w.key(4, "size", scene_detail::flow(b.size));
  }
  w.key(4, "spacing", b.spacing);
  if (b.points.empty()) w.key(4, "grid", scene_detail::to_text(b.grid));
  emit_horizon(w, b);
  w.key(4, "quadrature", scene_detail::to_text(b.quadrature));
  emit_cutouts(w, b);
}

// Cell-centred cubic grid, x fastest, then y, then z; or the point cloud's rows in file order
// (no grid: reference offsets are not snapped and rows get their own family patterns).
void discretize(const Body& b, BodyGeometry& g, NodeSink& all) {
  if (!b.mesh.empty()) {  // the mesh's vertices in ascending tag order, a quarter of their tets' volumes
    const MeshData& m = *b.mesh_data;
    g.traits.grid = false;
    g.irregular = true;
    g.mesh_mean_edge = m.mean_edge;
    for (std::size_t k = 0; k < m.nodes.size(); ++k) all.add(m.nodes[k][0], m.nodes[k][1], m.nodes[k][2], m.measure[k]);
    g.cells = {static_cast<std::int64_t>(m.nodes.size()), 1, 1};
    return;
  }
  CutSink sink(b, all);
  if (!b.points.empty()) {
    g.traits.grid = false;
    g.irregular = true;
    for (const CloudPoint& p : b.cloud) sink.add(p.x[0], p.x[1], p.x[2], p.volume);
    sink.finish();
    return;
  }
  const double dx = b.spacing;
  const std::int64_t nx = count_along(b.size[0], dx), ny = count_along(b.size[1], dx), nz = count_along(b.size[2], dx);
  g.cells = {nx, ny, nz};
  for (std::int64_t k = 0; k < nz; ++k)
    for (std::int64_t j = 0; j < ny; ++j)
      for (std::int64_t i = 0; i < nx; ++i)
        sink.add(b.origin[0] + (i + 0.5) * dx, b.origin[1] + (j + 0.5) * dx, b.origin[2] + (k + 0.5) * dx, dx * dx * dx);
  sink.finish();
}

double node_estimate(const Body& b) {
  if (!b.mesh.empty()) return static_cast<double>(b.mesh_data->nodes.size());
  if (!b.points.empty()) return static_cast<double>(b.cloud.size());
  double n = 1;
  for (int d = 0; d < 3; ++d) n *= std::max(1.0, std::round(b.size[d] / b.spacing));
  return n;
}

}  // namespace

BodyKind solid_kind() {
  BodyKind k;
  k.name = "solid";
  k.summary = "a box of simple-cubic points, a point cloud or a tetrahedral mesh from a file";
  k.traits = {.dimension = 3, .grid = true};
  k.keys = {
      {.name = "origin", .what = "lower corner [x, y, z], m", .unit = "m",
       .fallback = "required unless points or mesh", .doc = "the lower corner [x, y, z]"},
      {.name = "size", .what = "extent [Lx, Ly, Lz] of the box, m", .unit = "m",
       .fallback = "required unless points or mesh",
       .doc = "[Lx, Ly, Lz], all > 0"},
      {.name = "points", .fallback = "- (a box)",
       .doc = "instead of origin and size: a CSV file (relative to the scene file) with the header x,y,z,volume or "
              "x,y,z,volume,material and one point a row [m, m^3]; nodes in file order, volumes > 0, no point twice "
              "(nor two within 1e-8 of the cube root of the median volume), no volume above the horizon's ball "
              "(4/3 pi horizon^3); "
              "with a material column the body takes the rows naming its material; `#` lines and blank lines are "
              "skipped. Or an HDF5 file (.h5, .hdf5) with the 1D datasets x, y, z, volume (numbers) and optionally "
              "material (strings), one point an index"},
      kMeshKey3,
      kScaleKey,
      {.name = "spacing", .what = "grid spacing, m", .unit = "m",
       .fallback = "required unless mesh; with mesh: the mesh's mean edge length",
       .doc = "dx > 0, at most the smallest extent of size; nodes sit at origin + (i + 1/2) dx, measure dx^3. With "
              "points: the points' typical distance, which sets the horizon (horizon_factor x spacing) and the "
              "cube of side dx about each point that partial_area weighs. With mesh: the length the horizon is "
              "measured in"},
      {.name = "grid", .fallback = "square", .doc = "`square` only (simple cubic); not with points or mesh"},
      kHorizonFactorKey,
      kHorizonKey,
      quadrature_key(),
      kCutoutsKey,
  };
  k.nested = {{"cutouts[i]", &kCutoutKeys}};
  k.read = read;
  k.emit = emit;
  k.measure_keys = [](const Body& b) {
    if (!b.mesh.empty()) return "the tetrahedra of bodies." + b.name + ".mesh";
    return b.points.empty() ? key_text(b, "spacing", b.spacing) : "the volumes of bodies." + b.name + ".points";
  };
  k.node_estimate = node_estimate;
  k.family_estimate = [](const Body& b) { return grid_family(b, 3); };
  k.discretize = discretize;
  return k;
}

}  // namespace peri::kinds
