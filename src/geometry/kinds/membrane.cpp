// Body kind `membrane`: a flat rectangular sheet at z = origin z, nodes at the centres of a square
// or hexagonal grid's cells, measure cell area x thickness (Silling & Bobaru section 3).
#include "common.hpp"
#include "kinds.hpp"

namespace peri::kinds {
namespace {

const Key kQuadratureKey = {
    .name = "quadrature", .fallback = "partial_area",
    .doc = "the weight of a neighbour inside the horizon: `partial_area` (the exact part of its cell inside the "
           "horizon; second order), `full` (whole cells with xi <= delta) or `taper` (whole cells, the last dx/2 "
           "before delta tapered linearly to 1/2, as LAMMPS PERI does)"};

void read(const Map& m, Body& b, const Material&) {
  read_sheet_extent(m, b);
  if (auto x = m.get("grid")) b.grid = x->choice<Grid>({{"square", Grid::Square}, {"hexagonal", Grid::Hexagonal}});
  read_horizon(m, b);
  if (auto x = m.get("quadrature"))
    b.quadrature = x->choice<Quadrature>(
        {{"full", Quadrature::Full}, {"partial_area", Quadrature::PartialArea}, {"taper", Quadrature::Taper}});
  read_cutouts(m, b, 2);
}

void emit(Writer& w, const Body& b) {
  w.key(4, "origin", scene_detail::flow(b.origin));
  w.key(4, "size", scene_detail::flow({b.size[0], b.size[1]}));
  w.key(4, "thickness", b.thickness);
  w.key(4, "spacing", b.spacing);
  w.key(4, "grid", scene_detail::to_text(b.grid));
  emit_horizon(w, b);
  w.key(4, "quadrature", scene_detail::to_text(b.quadrature));
  emit_cutouts(w, b);
}

}  // namespace

BodyKind membrane_kind() {
  BodyKind k;
  k.name = "membrane";
  k.summary = "a flat sheet on a square or hexagonal grid";
  k.traits = {.dimension = 2, .grid = true, .flat = true};
  k.keys = {
      {.name = "origin", .required = true, .what = "lower corner [x, y, z], m", .unit = "m",
       .doc = "the lower corner [x, y, z]; the sheet lies at z = origin z"},
      {.name = "size", .required = true, .what = "extent [Lx, Ly] of the sheet, m", .unit = "m",
       .doc = "[Lx, Ly] (or [Lx, Ly, 0]), Lx, Ly > 0"},
      {.name = "thickness", .required = true, .what = "membrane thickness, m", .unit = "m",
       .doc = "h > 0; a node's measure is its cell's area times h"},
      {.name = "spacing", .required = true, .what = "grid spacing, m", .unit = "m",
       .doc = "dx > 0, at most the smaller extent of size; nodes sit at origin + (i + 1/2) dx"},
      {.name = "grid", .fallback = "square",
       .doc = "`square` or `hexagonal` (rows along x, dx apart, rows sqrt(3)/2 dx apart)"},
      kHorizonFactorKey,
      kHorizonKey,
      kQuadratureKey,
      kCutoutsKey,
  };
  k.nested = {{"cutouts[i]", &kCutoutKeys}};
  k.read = read;
  k.emit = emit;
  k.measure_keys = [](const Body& b) {
    return key_text(b, "spacing", b.spacing) + ", " + key_text(b, "thickness", b.thickness);
  };
  k.node_estimate = grid_sheet_count;
  k.family_estimate = [](const Body& b) { return grid_family(b, 2); };
  k.discretize = grid_sheet_nodes;
  return k;
}

const Key& quadrature_key() { return kQuadratureKey; }

}  // namespace peri::kinds
