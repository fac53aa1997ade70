// A body kind defined in this file alone: `disk`, a circular membrane (the nodes of a square grid
// whose cells' centres lie within a radius), registered at run time and run through everything a
// built-in kind is (docs/developer/adding-a-body-kind.md follows this file):
//  - the registry and the scene's documentation (--describe-keys' sections);
//  - the scene: its keys read, required ones demanded, other kinds' keys refused by name, the
//    resolved scene read back to the same text;
//  - the size estimate and the discretization: node count and total measure against the circle;
//  - a dynamic run from a homogeneous equibiaxial stretch: the initial strain energy against
//    the continuum's 2 K e^2 pi R^2 h (less the missing bonds at the edge), the energy balance of
//    the free vibration, and no net momentum.
// Run under MPI at 1 and 2 ranks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "mpi_test.hpp"
#include "peri/core/format.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/scene/describe.hpp"
#include "peri/scene/located_yaml.hpp"
#include "peri/scene/writer.hpp"
#include "peri/stages/simulation.hpp"

namespace peri {
namespace {

constexpr double kPi = 3.14159265358979323846;

// ------------------------------------------------------------------------------------------------
// The kind: a disk of `radius` about `center` (z = center z), thickness h, grid spacing dx; its
// nodes are the cell centres (i + 1/2) dx - R inside the circle, rows along x, each with the
// measure dx^2 h. The nodes do not fill a raster, so the kind has no grid trait (reference
// offsets are not snapped, and rows do not share family patterns).

void read_disk(const scene_detail::Map& m, Body& b, const Material&) {
  b.origin = m.at("center").vec3("m");
  b.radius = m.at("radius").positive("m");
  b.thickness = m.at("thickness").positive("m");
  const scene_detail::Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  if (b.spacing > b.radius) spacing.fail("spacing must not exceed the radius, got " + spacing.got());
  if (auto x = m.get("horizon_factor")) {
    b.horizon_factor = x->number("a number >= 1");
    if (!(b.horizon_factor >= 1)) x->fail("expected >= 1, got " + x->got());
  }
  b.quadrature = Quadrature::Full;
}

void emit_disk(scene_detail::Writer& w, const Body& b) {
  w.key(4, "center", scene_detail::flow(b.origin));
  w.key(4, "radius", b.radius);
  w.key(4, "thickness", b.thickness);
  w.key(4, "spacing", b.spacing);
  w.key(4, "horizon_factor", b.horizon_factor);
}

std::int64_t cells_across(const Body& b) { return 2 * static_cast<std::int64_t>(std::ceil(b.radius / b.spacing)); }

void discretize_disk(const Body& b, BodyGeometry& g, NodeSink& sink) {
  const double dx = b.spacing, r2 = b.radius * b.radius;
  const std::int64_t n = cells_across(b);
  g.thickness = b.thickness;
  g.cell_area = dx * dx;
  for (std::int64_t j = 0; j < n; ++j)
    for (std::int64_t i = 0; i < n; ++i) {
      const double x = (static_cast<double>(i - n / 2) + 0.5) * dx, y = (static_cast<double>(j - n / 2) + 0.5) * dx;
      if (x * x + y * y <= r2) sink.add(b.origin[0] + x, b.origin[1] + y, b.origin[2], g.cell_area * b.thickness);
    }
}

BodyKind disk_kind() {
  BodyKind k;
  k.name = "disk";
  k.summary = "a circular sheet, square-grid nodes within its radius";
  k.traits = {.dimension = 2, .grid = false, .flat = true};
  k.keys = {
      {.name = "center", .required = true, .what = "centre [x, y, z], m", .unit = "m", .doc = "the centre"},
      {.name = "radius", .required = true, .what = "radius, m", .unit = "m", .doc = "R > 0"},
      {.name = "thickness", .required = true, .what = "thickness, m", .unit = "m", .doc = "h > 0"},
      {.name = "spacing", .required = true, .what = "grid spacing, m", .unit = "m", .doc = "dx, at most R"},
      {.name = "horizon_factor", .fallback = "3", .doc = "m of delta = m dx, >= 1"},
  };
  k.read = read_disk;
  k.emit = emit_disk;
  k.measure_keys = [](const Body& b) {
    return "bodies." + b.name + ".spacing " + number_text(b.spacing) + " m, bodies." + b.name + ".thickness " +
           number_text(b.thickness) + " m";
  };
  k.node_estimate = [](const Body& b) { return kPi * b.radius * b.radius / (b.spacing * b.spacing); };
  k.family_estimate = [](const Body& b) { return kPi * std::pow(b.horizon_value() / b.spacing + 0.71, 2); };
  k.discretize = discretize_disk;
  return k;
}

const bool kRegistered = [] {
  register_body_kind(disk_kind());
  return true;
}();

// ------------------------------------------------------------------------------------------------

constexpr double kRadius = 0.02, kSpacing = 5e-4, kThickness = 5e-4, kBulk = 800e6, kStrain = 1e-3;

// A disk stretched equibiaxially by e (about its centre) and let go: a free breathing vibration.
std::string disk_scene(const std::string& body_extra = "", const std::string& safety_factor = "0.7") {
  return R"(
name: disk
materials:
  rubber: {model: membrane, density: 1200, bulk_modulus: 8.0e8}
bodies:
  plate: {kind: disk, material: rubber, center: [0.1, 0.2, 0], radius: 0.02, thickness: 0.0005, spacing: 0.0005)" +
         body_extra + R"(}
initial:
  center: [0.1, 0.2, 0]
  displacement_gradient: [[0.001, 0, 0], [0, 0.001, 0], [0, 0, 0]]
stages:
  - {name: free, duration: 2.0e-5, safety_factor: )" +
         safety_factor + R"(}
output: {frames: 1, series_every: 10}
)";
}

std::string error_of(const std::string& text) {
  try {
    parse_scene(text, "disk.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(BodyKind, IsRegisteredAndDocumented) {
  ASSERT_TRUE(kRegistered);
  ASSERT_NE(find_body_kind("disk"), nullptr);
  EXPECT_EQ(body_kinds().back()->name, "disk");
  EXPECT_THROW(register_body_kind(disk_kind()), Error);  // a name is taken once
  const std::vector<KeySection> sections = scene_key_sections();
  const auto it = std::find_if(sections.begin(), sections.end(),
                               [](const KeySection& s) { return s.path == "bodies.<name>" && s.condition == "kind: disk"; });
  ASSERT_NE(it, sections.end());
  ASSERT_EQ(it->keys.size(), 5u);
  EXPECT_EQ(it->keys[1].name, "radius");
  EXPECT_TRUE(it->keys[1].required);
  const std::vector<KindDoc> kinds = scene_kind_docs();
  EXPECT_EQ(kinds.back().name, "disk");
}

TEST(BodyKind, SceneTakesItsKeysAndRefusesOthers) {
  const Scene scene = parse_scene(disk_scene(), "disk.yaml");
  const Body& b = scene.bodies.at(0);
  EXPECT_EQ(b.kind->name, "disk");
  EXPECT_EQ(b.radius, kRadius);
  EXPECT_EQ(b.origin, (Vec3{0.1, 0.2, 0}));
  // The resolved scene reads back to the same text.
  const std::string resolved = emit_scene(scene);
  EXPECT_NE(resolved.find("kind: disk"), std::string::npos);
  EXPECT_EQ(emit_scene(parse_scene(resolved, "resolved.yaml")), resolved);
  // Another kind's key is refused, naming the kind that takes it; a key no kind takes is unknown.
  EXPECT_NE(error_of(disk_scene(", pressure: 1.0e5")).find("bodies.plate.pressure: not used by a disk body"),
            std::string::npos);
  EXPECT_NE(error_of(disk_scene(", origin: [0, 0, 0]")).find("bodies.plate.origin: not used by a disk body (a circular "
                                                             "sheet, square-grid nodes within its radius); expected "
                                                             "one of: kind, material, center, radius"),
            std::string::npos)
      << error_of(disk_scene(", origin: [0, 0, 0]"));
  EXPECT_NE(error_of(disk_scene(", colour: red")).find("bodies.plate.colour: unknown key"), std::string::npos);
  // Its required keys are demanded; its own checks run.
  std::string no_radius = disk_scene();
  no_radius.replace(no_radius.find(" radius: 0.02,"), 14, "");
  EXPECT_NE(error_of(no_radius).find("bodies.plate: missing required key 'radius' (radius, m)"), std::string::npos)
      << error_of(no_radius);
  EXPECT_NE(error_of(disk_scene(", horizon_factor: 0.5")).find("bodies.plate.horizon_factor: expected >= 1"),
            std::string::npos);
  // Its keys are not another kind's: a membrane refuses radius.
  std::string membrane = disk_scene();
  membrane.replace(membrane.find("kind: disk"), 10, "kind: membrane");
  EXPECT_NE(error_of(membrane).find("bodies.plate.center: not used by a membrane body"), std::string::npos)
      << error_of(membrane);
}

TEST(BodyKind, DiscretizationFillsTheCircle) {
  const Scene scene = parse_scene(disk_scene(), "disk.yaml");
  const Nodes nodes = discretize(scene);
  const BodyGeometry& g = nodes.bodies.at(0);
  EXPECT_EQ(g.count, nodes.size());
  EXPECT_FALSE(g.traits.grid);
  EXPECT_TRUE(g.traits.flat);
  double measure = 0, farthest = 0;
  for (std::int64_t i = 0; i < nodes.size(); ++i) {
    measure += nodes.volume[i];
    farthest = std::max(farthest, std::hypot(nodes.X[3 * i] - 0.1, nodes.X[3 * i + 1] - 0.2));
    EXPECT_EQ(nodes.X[3 * i + 2], 0.0);
  }
  // 5024 cells of (1 mm / 2)^2 have their centre within 20 mm: pi R^2 to the boundary cells' 0.3%.
  EXPECT_NEAR(measure / (kPi * kRadius * kRadius * kThickness), 1.0, 3e-3);
  EXPECT_LE(farthest, kRadius);
  EXPECT_GT(farthest, kRadius - kSpacing);
  const SizeEstimate e = estimate_size(scene);
  EXPECT_NEAR(e.nodes / static_cast<double>(nodes.size()), 1.0, 3e-3);
}

RunSummary free_vibration(const std::string& safety_factor) {
  RunOptions quiet;
  quiet.quiet = true;
  Simulation sim(parse_scene(disk_scene("", safety_factor), "disk"), PETSC_COMM_WORLD, quiet);
  sim.run();
  return sim.summary();
}

TEST(BodyKind, DynamicRunFromAStretch) {
  const RunSummary s = free_vibration("0.7"), fine = free_vibration("0.35");
  // At rest and stretched by e: the strain energy of the continuum, 2 K e^2 per unit volume, less
  // the edge's missing bonds (a band of about delta / 2 = 0.75 mm at half strength: about 4%).
  const double continuum = 2 * kBulk * kStrain * kStrain * kPi * kRadius * kRadius * kThickness;
  const double ratio = s.initial_total_energy / continuum;
  const double order = std::log2(s.energy_balance_error / fine.energy_balance_error);
  if (world_rank() == 0)
    std::printf("disk: %lld nodes, initial strain energy %.5e J = %.4f x continuum; energy balance error %.2e "
                "(safety factor 0.7), %.2e (0.35): order %.2f\n",
                static_cast<long long>(s.nodes), s.initial_total_energy, ratio, s.energy_balance_error,
                fine.energy_balance_error, order);
  EXPECT_GT(ratio, 0.93);
  EXPECT_LT(ratio, 0.99);
  EXPECT_EQ(fine.initial_total_energy, s.initial_total_energy);
  // Free vibration: energy kept to the Verlet scheme's error, second order in dt; strain turned
  // partly into motion; nothing breaks (no critical stretch).
  EXPECT_LT(s.energy_balance_error, 5e-3);
  EXPECT_NEAR(order, 2.0, 0.3);
  EXPECT_GT(s.final_energy.kinetic, 0.1 * s.initial_total_energy);
  EXPECT_EQ(s.final_energy.broken_bonds, 0);
}

}  // namespace
}  // namespace peri
