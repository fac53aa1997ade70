// Body kind `lattice`: Marder's triangular lattice of spacing Delta, bonds to the six nearest
// neighbours only (next-nearest ones are sqrt(3) Delta away), a marder material's own law.
#include "common.hpp"
#include "kinds.hpp"
#include "peri/scene/models.hpp"

namespace peri::kinds {
namespace {

using scene_detail::format_number;

void read(const Map& m, Body& b, const Material& mat) {
  read_sheet_extent(m, b);
  const Value spacing = m.at("spacing");
  const MarderParams& p = *mat.marder;
  const MaterialModel* model = find_material_model(mat.model);
  const std::string why = model && model->lattice_problem ? model->lattice_problem(p, b.spacing) : "";
  if (!why.empty())
    spacing.fail("lattice spacing " + spacing.got() + " m with material '" + b.material + "' (a = " + format_number(p.a) +
                 ", b = " + format_number(p.b) + ", cutoff = " + format_number(p.cutoff) +
                 ", fracture_separation = " + format_number(p.fracture_separation) + "): " + why);
  b.grid = Grid::Hexagonal;
  b.quadrature = Quadrature::Full;
  if (auto x = m.get("breakable")) {
    const Map box(*x, &kBoxKeys, "a box {min: [x, y, z], max: [x, y, z]}");
    const Vec3 lo = box.at("min").vec3("m");
    const Value max = box.at("max");
    const Vec3 hi = max.vec3("m");
    for (int d = 0; d < 3; ++d)
      if (lo[d] > hi[d])
        max.fail(std::string("expected min <= max in every component, got ") + "xyz"[d] + ": min " +
                 format_number(lo[d]) + " > max " + format_number(hi[d]));
    b.breakable = std::array<Vec3, 2>{lo, hi};
  }
  read_cutouts(m, b, 2);
}

void emit(Writer& w, const Body& b) {
  w.key(4, "origin", scene_detail::flow(b.origin));
  w.key(4, "size", scene_detail::flow({b.size[0], b.size[1]}));
  w.key(4, "thickness", b.thickness);
  w.key(4, "spacing", b.spacing);
  if (b.breakable)
    w.key(4, "breakable",
          "{min: " + scene_detail::flow((*b.breakable)[0]) + ", max: " + scene_detail::flow((*b.breakable)[1]) + "}");
  emit_cutouts(w, b);
}

// The hexagonal grid of a membrane, with the nearest neighbours' horizon and full weights.
void discretize(const Body& b, BodyGeometry& g, NodeSink& sink) {
  g.grid = Grid::Hexagonal;
  g.quadrature = Quadrature::Full;
  g.horizon = 1.1 * b.spacing;
  grid_sheet_nodes(b, g, sink);
}

}  // namespace

BodyKind lattice_kind() {
  BodyKind k;
  k.name = "lattice";
  k.summary = "a triangular lattice, six nearest neighbours";
  k.traits = {.dimension = 2, .grid = true, .flat = true, .lattice = true};
  k.keys = {
      {.name = "origin", .required = true, .what = "lower corner [x, y, z], m", .unit = "m",
       .doc = "the lower corner [x, y, z]; the lattice lies at z = origin z"},
      {.name = "size", .required = true, .what = "extent [Lx, Ly] of the sheet, m", .unit = "m",
       .doc = "[Lx, Ly] (or [Lx, Ly, 0]), Lx, Ly > 0"},
      {.name = "thickness", .required = true, .what = "sheet thickness, m", .unit = "m",
       .doc = "h > 0; a node's mass is density h (sqrt(3)/2) Delta^2"},
      {.name = "spacing", .required = true, .what = "lattice spacing Delta, m", .unit = "m",
       .doc = "Delta > 0, at most the smaller extent of size: rows along x, Delta apart, rows sqrt(3)/2 Delta "
              "apart; checked against the material's cutoff and fracture_separation"},
      {.name = "breakable", .unit = "m", .fallback = "everywhere",
       .doc = "`{min: [x, y, z], max: [x, y, z]}`: only bonds with both ends inside this box (reference positions) "
              "may break (`bodies.<name>.breakable`)"},
      kCutoutsKey,
  };
  k.nested = {{"breakable", &kBoxKeys}, {"cutouts[i]", &kCutoutKeys}};
  k.read = read;
  k.emit = emit;
  k.measure_keys = [](const Body& b) {
    return key_text(b, "spacing", b.spacing) + ", " + key_text(b, "thickness", b.thickness);
  };
  k.node_estimate = grid_sheet_count;
  k.family_estimate = [](const Body&) { return 6.0; };
  k.discretize = discretize;
  return k;
}

}  // namespace peri::kinds
