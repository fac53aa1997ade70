// Body kind `membrane`: a flat rectangular sheet at z = origin z, nodes at the centres of a square
// or hexagonal grid's cells, measure cell area x thickness (Silling & Bobaru section 3); or a
// triangle surface mesh from a file (`mesh`, mesh_file.cpp), flat or curved, nodes at its vertices,
// its triangles carrying a follower pressure as a sphere's do.
#include "common.hpp"
#include "kinds.hpp"

namespace peri::kinds {
namespace {

const Key kQuadratureKey = {
    .name = "quadrature", .fallback = "partial_area; with mesh: full",
    .doc = "the weight of a neighbour inside the horizon: `partial_area` (the exact part of its cell inside the "
           "horizon; second order), `full` (whole cells with xi <= delta) or `taper` (whole cells, the last dx/2 "
           "before delta tapered linearly to 1/2, as LAMMPS PERI does); with mesh `full` or `taper` (a mesh's "
           "nodes have no cells to cut)"};

// A mesh membrane: its nodes from the file, a follower pressure on its triangles.
void read_mesh(const Map& m, Body& b) {
  for (const char* key : {"origin", "size", "grid", "cutouts"})
    if (auto x = m.get(key))
      x->fail(std::string("not with mesh: a mesh membrane takes its nodes from the file, not from ") + key);
  if (auto x = m.get("scale")) b.scale = x->positive("");
  b.thickness = m.at("thickness").positive("m");
  if (auto x = m.get("spacing"))
    b.spacing = x->positive("m");
  else
    b.spacing_given = false;
  read_mesh_file(m.at("mesh"), b, 2);
  read_horizon(m, b);
  b.quadrature = Quadrature::Full;
  if (auto x = m.get("quadrature"))
    b.quadrature = x->choice<Quadrature>({{"full", Quadrature::Full}, {"taper", Quadrature::Taper}});
  if (auto x = m.get("pressure")) b.pressure = x->non_negative("Pa");
  if (auto x = m.get("pressure_ramp_time")) b.pressure_ramp_time = x->non_negative("s");
  if (b.pressure > 0) check_mesh_orientation(b);
}

void read(const Map& m, Body& b, const Material&) {
  if (m.given("mesh")) return read_mesh(m, b);
  for (const char* key : {"scale", "pressure", "pressure_ramp_time"})
    if (auto x = m.get(key))
      x->fail(std::string("only with mesh: ") + key + " belongs to a membrane read from a mesh file");
  if (!m.given("origin")) m.missing("origin", "lower corner [x, y, z], m; or mesh");
  if (!m.given("size")) m.missing("size", "extent [Lx, Ly] of the sheet, m; or mesh");
  if (!m.given("spacing")) m.missing("spacing", "grid spacing, m");
  read_sheet_extent(m, b);
  if (auto x = m.get("grid")) b.grid = x->choice<Grid>({{"square", Grid::Square}, {"hexagonal", Grid::Hexagonal}});
  read_horizon(m, b);
  if (auto x = m.get("quadrature"))
    b.quadrature = x->choice<Quadrature>(
        {{"full", Quadrature::Full}, {"partial_area", Quadrature::PartialArea}, {"taper", Quadrature::Taper}});
  read_cutouts(m, b, 2);
}

void emit_mesh(Writer& w, const Body& b) {
  w.key(4, "mesh", scene_detail::yaml_string(b.mesh));
  w.key(4, "scale", b.scale);
  w.key(4, "thickness", b.thickness);
  if (b.spacing_given)
    w.key(4, "spacing", b.spacing);
  else
    w.line(4, "# spacing: not given; the mesh's mean edge length " + scene_detail::format_number(b.spacing) + " m");
  emit_horizon(w, b);
  w.key(4, "quadrature", scene_detail::to_text(b.quadrature));
  w.key(4, "pressure", b.pressure);
  w.key(4, "pressure_ramp_time", b.pressure_ramp_time);
}

void emit(Writer& w, const Body& b) {
  if (!b.mesh.empty()) return emit_mesh(w, b);
  w.key(4, "origin", scene_detail::flow(b.origin));
  w.key(4, "size", scene_detail::flow({b.size[0], b.size[1]}));
  w.key(4, "thickness", b.thickness);
  w.key(4, "spacing", b.spacing);
  w.key(4, "grid", scene_detail::to_text(b.grid));
  emit_horizon(w, b);
  w.key(4, "quadrature", scene_detail::to_text(b.quadrature));
  emit_cutouts(w, b);
}

// The mesh's vertices, in ascending tag order, with a third of their triangles' areas; no grid
// (reference offsets are not snapped); flat only when every node lies at one z.
void discretize(const Body& b, BodyGeometry& g, NodeSink& sink) {
  if (b.mesh.empty()) return grid_sheet_nodes(b, g, sink);
  const MeshData& m = *b.mesh_data;
  g.traits.grid = false;
  g.irregular = true;
  g.traits.flat = m.planar;
  g.thickness = b.thickness;
  g.cell_area = m.total / static_cast<double>(m.nodes.size());
  g.mesh_mean_edge = m.mean_edge;
  for (std::size_t k = 0; k < m.nodes.size(); ++k)
    sink.add(m.nodes[k][0], m.nodes[k][1], m.nodes[k][2], m.measure[k] * b.thickness);
  for (const auto& t : m.triangles) g.triangles.push_back({g.first + t[0], g.first + t[1], g.first + t[2]});
  g.cells = {static_cast<std::int64_t>(m.nodes.size()), 1, 1};
}

}  // namespace

BodyKind membrane_kind() {
  BodyKind k;
  k.name = "membrane";
  k.summary = "a flat sheet on a square or hexagonal grid";
  k.traits = {.dimension = 2, .grid = true, .flat = true};
  k.keys = {
      {.name = "origin", .what = "lower corner [x, y, z], m", .unit = "m", .fallback = "required unless mesh",
       .doc = "the lower corner [x, y, z]; the sheet lies at z = origin z"},
      {.name = "size", .what = "extent [Lx, Ly] of the sheet, m", .unit = "m", .fallback = "required unless mesh",
       .doc = "[Lx, Ly] (or [Lx, Ly, 0]), Lx, Ly > 0"},
      kMeshKey2,
      kScaleKey,
      {.name = "thickness", .required = true, .what = "membrane thickness, m", .unit = "m",
       .doc = "h > 0; a node's measure is its cell's area times h"},
      {.name = "spacing", .what = "grid spacing, m", .unit = "m",
       .fallback = "required unless mesh; with mesh: the mesh's mean edge length",
       .doc = "dx > 0, at most the smaller extent of size; nodes sit at origin + (i + 1/2) dx. With mesh: the "
              "length the horizon is measured in (horizon_factor x spacing)"},
      {.name = "grid", .fallback = "square",
       .doc = "`square` or `hexagonal` (rows along x, dx apart, rows sqrt(3)/2 dx apart); not with mesh"},
      kHorizonFactorKey,
      kHorizonKey,
      kQuadratureKey,
      {.name = "pressure", .unit = "Pa", .fallback = "0",
       .doc = "with mesh: a follower pressure p >= 0 on the triangles, oriented as in the file (each carries p "
              "times its current area vector (b - a) x (c - a) / 2, a third to each corner whose bonds to the "
              "other two are intact), as a sphere's; the triangles must be oriented alike"},
      {.name = "pressure_ramp_time", .unit = "s", .fallback = "0",
       .doc = "with mesh: the pressure rises linearly from 0 over this time, >= 0"},
      kCutoutsKey,
  };
  k.nested = {{"cutouts[i]", &kCutoutKeys}};
  k.read = read;
  k.emit = emit;
  k.measure_keys = [](const Body& b) {
    if (!b.mesh.empty()) return "the triangles of bodies." + b.name + ".mesh, " + key_text(b, "thickness", b.thickness);
    return key_text(b, "spacing", b.spacing) + ", " + key_text(b, "thickness", b.thickness);
  };
  k.node_estimate = [](const Body& b) {
    return b.mesh.empty() ? grid_sheet_count(b) : static_cast<double>(b.mesh_data->nodes.size());
  };
  k.family_estimate = [](const Body& b) { return grid_family(b, 2); };
  k.discretize = discretize;
  return k;
}

const Key& quadrature_key() { return kQuadratureKey; }

}  // namespace peri::kinds
