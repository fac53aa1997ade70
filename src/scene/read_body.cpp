// The readers of a body (bodies.<name>): its kind's keys (membrane, solid, lattice, fiber with its
// path or network, sphere), the horizon, and the checks that involve its material (readers.hpp).
#include <algorithm>
#include <cmath>

#include "peri/scene/models.hpp"
#include "readers.hpp"
#include "schema.hpp"

namespace peri::scene_detail {
namespace {

// Horizon keys shared by peridynamic bodies: horizon_factor (m spacings) or horizon [m].
void read_horizon(const Map& m, Body& b) {
  if (auto x = m.get("horizon_factor")) {
    b.horizon_factor = x->number("a number >= 1");
    if (!(b.horizon_factor >= 1))
      x->fail("horizon must be at least one spacing (expected >= 1), got " + x->got());
  }
  if (auto x = m.get("horizon")) {
    if (m.given("horizon_factor")) x->fail("give either horizon [m] or horizon_factor, not both");
    const double h = x->number("a number [m]");
    if (!(h >= b.spacing))
      x->fail("horizon must be at least one spacing (expected >= " + format_number(b.spacing) + " m), got " +
              x->got());
    b.horizon = h;
  }
}

FiberNetwork read_network(const Value& v) {
  const Map m(v, &kNetworkKeys, "a map {box, families, deviation, step, start_band, seed}");
  FiberNetwork n;
  n.where = m.where();
  const Map box(m.at("box"), &kBoxKeys, "a box {min: [x, y, z], max: [x, y, z]}");
  n.min = box.at("min").vec3("m");
  const Value max = box.at("max");
  n.max = max.vec3("m");
  for (int d = 0; d < 3; ++d)
    if (!(n.min[d] < n.max[d]))
      max.fail(std::string("expected min < max in every component, got ") + "xyz"[d] + ": min " +
               format_number(n.min[d]) + ", max " + format_number(n.max[d]));
  const Value families = m.at("families");
  const std::vector<Value> list = families.list("a list of fiber families {direction: x or y, count}");
  if (list.empty()) families.fail("expected at least one family {direction: x or y, count}, got an empty list");
  for (const Value& f : list) {
    const Map fm(f, &kFamilyKeys, "a map {direction: x or y, count}");
    FiberFamily fam;
    fam.where = fm.where();
    fam.axis = fm.at("direction").choice<int>({{"x", 0}, {"y", 1}});
    fam.count = fm.at("count").integer(1, 100000);
    n.families.push_back(fam);
  }
  if (auto x = m.get("deviation")) n.deviation = x->non_negative("rad");
  const Value step = m.at("step");
  n.step = step.positive("m");
  for (const FiberFamily& f : n.families)
    if ((n.max[f.axis] - n.min[f.axis]) / n.step > 1e6)
      step.fail("a fiber would take more than 1e6 steps of " + step.got() + " m to cross the box (" +
                format_number(n.max[f.axis] - n.min[f.axis]) + " m along " + (f.axis == 0 ? "x" : "y") +
                "); expected a step of at least 1e-6 of the box's extent");
  n.start_band = 0.05 * std::min(n.max[0] - n.min[0], n.max[1] - n.min[1]);
  if (auto x = m.get("start_band")) n.start_band = x->non_negative("m");
  if (auto x = m.get("seed")) n.seed = x->integer(0);
  return n;
}

// A fiber: polyline path, diameter, spacing along the path, horizon, segments (eq. 31).
void read_fiber(const Map& m, Body& b) {
  for (const char* key : {"origin", "size", "thickness", "grid", "quadrature", "breakable"})
    if (auto x = m.get(key))
      x->fail(std::string("not used by a fiber body (nodes along its path, full weights within the horizon)"));
  double length = INFINITY;  // of the one path (a network's fibers cross its box)
  if (auto x = m.get("network")) {
    if (m.given("path")) x->fail("give either path (one fiber) or network (many), not both");
    b.network = read_network(*x);
  } else {
    if (!m.given("path")) m.missing("path", "polyline [[x, y, z], ...] of at least 2 points, m (or network)");
    const Value path = m.at("path");
    const std::vector<Value> points = path.list("a list of at least 2 points [x, y, z], m");
    if (points.size() < 2) path.fail("expected a list of at least 2 points [x, y, z], m, got " + path.got());
    length = 0;
    for (std::size_t k = 0; k < points.size(); ++k) {
      b.path.push_back(points[k].vec3("m"));
      if (k == 0) continue;
      double d2 = 0;
      for (int c = 0; c < 3; ++c) d2 += std::pow(b.path[k][c] - b.path[k - 1][c], 2);
      if (!(d2 > 0)) points[k].fail("expected a point different from the one before it, got " + points[k].got());
      length += std::sqrt(d2);
    }
  }
  if (!m.given("diameter")) m.missing("diameter", "fiber diameter, m");
  b.diameter = m.at("diameter").positive("m");
  if (!m.given("spacing")) m.missing("spacing", "node spacing along the path, m");
  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  if (b.spacing > length)
    spacing.fail("spacing must not exceed the fiber's length along its path (" + format_number(length) +
                 " m), got " + spacing.got());
  if (auto x = m.get("segment_length")) b.segment_length = x->non_negative("m");
  read_horizon(m, b);
  b.quadrature = Quadrature::Full;
}

// A spherical membrane: center, radius, thickness, spacing, horizon, internal pressure (7.2).
void read_sphere(const Map& m, Body& b) {
  for (const char* key : {"origin", "size", "grid", "quadrature", "breakable", "path", "network", "diameter",
                          "segment_length"})
    if (auto x = m.get(key))
      x->fail("not used by a sphere body (geodesic nodes on the sphere, full weights within the horizon)");
  if (!m.given("center")) m.missing("center", "center of the sphere [x, y, z], m");
  b.origin = m.at("center").vec3("m");
  if (!m.given("radius")) m.missing("radius", "radius of the sphere, m");
  b.radius = m.at("radius").positive("m");
  if (!m.given("thickness")) m.missing("thickness", "membrane thickness, m");
  b.thickness = m.at("thickness").positive("m");
  if (!m.given("spacing")) m.missing("spacing", "node spacing on the sphere, m");
  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  if (b.spacing > b.radius)
    spacing.fail("spacing must not exceed the radius (" + format_number(b.radius) + " m), got " + spacing.got());
  read_horizon(m, b);
  if (auto x = m.get("pressure")) b.pressure = x->non_negative("Pa");
  if (auto x = m.get("pressure_ramp_time")) b.pressure_ramp_time = x->non_negative("s");
  b.quadrature = Quadrature::Full;
}

}  // namespace

Body read_body(const std::string& name, const Value& v, const std::vector<Material>& materials) {
  const Map m(v, &kBodyKeys, "a map describing the body");
  Body b;
  b.name = name;
  b.where = m.where();
  if (auto x = m.get("kind"))
    b.kind = x->choice<BodyKind>({{"membrane", BodyKind::Membrane},
                                  {"solid", BodyKind::Solid},
                                  {"lattice", BodyKind::Lattice},
                                  {"fiber", BodyKind::Fiber},
                                  {"sphere", BodyKind::Shell}});
  const bool membrane = b.kind != BodyKind::Solid;  // membranes and lattices are flat sheets

  const Value material = m.at("material");
  b.material = material.name();
  if (std::none_of(materials.begin(), materials.end(),
                   [&](const Material& mat) { return mat.name == b.material; })) {
    std::vector<std::string> defined;
    for (const Material& mat : materials) defined.push_back(mat.name);
    material.fail("no material named '" + b.material + "'; defined: " + join(defined));
  }
  const Material& mat = *std::find_if(materials.begin(), materials.end(),
                                      [&](const Material& x) { return x.name == b.material; });
  if ((b.kind == BodyKind::Lattice) != find_material_model(mat.model)->lattice)
    material.fail(b.kind == BodyKind::Lattice
                      ? "a lattice body needs a material with model: marder, got '" + b.material + "'"
                      : "material '" + b.material + "' has model: marder, which needs a body with kind: lattice");

  for (const char* key : {"center", "radius", "pressure", "pressure_ramp_time"})
    if (b.kind != BodyKind::Shell && m.given(key))
      m.get(key)->fail("only a sphere body (kind: sphere) takes " + std::string(key));
  if (b.kind == BodyKind::Fiber) {
    read_fiber(m, b);
    return b;
  }
  if (b.kind == BodyKind::Shell) {
    read_sphere(m, b);
    return b;
  }
  for (const char* key : {"path", "network", "diameter", "segment_length"})
    if (auto x = m.get(key)) x->fail("only a fiber body (kind: fiber) takes " + std::string(key));
  if (!m.given("origin")) m.missing("origin", "lower corner [x, y, z], m");
  if (!m.given("size")) m.missing("size", "extent [Lx, Ly] of a membrane or [Lx, Ly, Lz] of a solid, m");
  if (!m.given("spacing")) m.missing("spacing", "grid spacing, m");
  b.origin = m.at("origin").vec3("m");

  const Value size = m.at("size");
  if (membrane) {
    const std::string expected = "a membrane size [Lx, Ly] (or [Lx, Ly, 0]) with Lx, Ly > 0 [m]";
    const auto xs = size.numbers(2, 3, expected, "m");
    if (!(xs[0] > 0 && xs[1] > 0) || (xs.size() == 3 && xs[2] != 0))
      size.fail("expected " + expected + ", got [" + join({format_number(xs[0]), format_number(xs[1])}) +
                (xs.size() == 3 ? ", " + format_number(xs[2]) : "") + "]");
    b.size = {xs[0], xs[1], 0.0};
  } else {
    const std::string expected = "a solid size [Lx, Ly, Lz] with all entries > 0 [m]";
    const auto xs = size.numbers(3, 3, expected, "m");
    if (!(xs[0] > 0 && xs[1] > 0 && xs[2] > 0))
      size.fail("expected " + expected + ", got [" +
                join({format_number(xs[0]), format_number(xs[1]), format_number(xs[2])}) + "]");
    b.size = {xs[0], xs[1], xs[2]};
  }

  if (membrane) {
    if (!m.given("thickness")) m.missing("thickness", "membrane thickness, m");
    b.thickness = m.at("thickness").positive("m");
  } else if (auto x = m.get("thickness")) {
    x->fail("not allowed for a solid body (only membranes have a thickness)");
  }

  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  double smallest = std::numeric_limits<double>::infinity();
  for (double l : b.size)
    if (l > 0) smallest = std::min(smallest, l);
  if (b.spacing > smallest)
    spacing.fail("spacing must not exceed the smallest extent of size (" + format_number(smallest) +
                 " m), got " + spacing.got());

  if (b.kind == BodyKind::Lattice) {
    // Nearest neighbours of a triangular lattice: no grid, horizon or quadrature to choose.
    for (const char* key : {"grid", "horizon_factor", "horizon", "quadrature"})
      if (auto x = m.get(key)) x->fail("not used by a lattice body (triangular lattice, six nearest neighbours)");
    const MarderParams& p = *mat.marder;
    const MaterialModel* model = find_material_model(mat.model);
    const std::string why = model && model->lattice_problem ? model->lattice_problem(p, b.spacing) : "";
    if (!why.empty())
      spacing.fail("lattice spacing " + spacing.got() + " m with material '" + b.material + "' (a = " +
                   format_number(p.a) + ", b = " + format_number(p.b) + ", cutoff = " + format_number(p.cutoff) +
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
  } else if (auto x = m.get("breakable")) {
    x->fail("only a lattice body takes breakable (peridynamic bonds break by their material's critical_stretch)");
  }

  if (auto x = m.get("grid")) {
    b.grid = x->choice<Grid>({{"square", Grid::Square}, {"hexagonal", Grid::Hexagonal}});
    if (!membrane && b.grid != Grid::Square)
      x->fail("a solid body supports only grid square, got " + x->got());
  }

  read_horizon(m, b);

  if (auto x = m.get("quadrature"))
    b.quadrature =
        x->choice<Quadrature>({{"full", Quadrature::Full}, {"partial_area", Quadrature::PartialArea},
                               {"taper", Quadrature::Taper}});
  return b;
}

}  // namespace peri::scene_detail
