// Tests of scene reading, validation, overrides and emission (peri/scene.hpp).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "peri/scene/scene.hpp"

#ifndef PERI_SOURCE_DIR
#error "PERI_SOURCE_DIR must name the source tree"
#endif

namespace {

using peri::InputError;
using peri::Override;
using peri::Scene;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const std::string kDefaultScenePath = std::string(PERI_SOURCE_DIR) + "/drivers/scenes/slit_membrane.yaml";

// A small valid scene. Line numbers matter to the error tests:
//  1 name   4 model   5 density   6 wave_speed   9 material   10 origin   11 size
//  12 thickness   13 spacing   14 stages   15 duration
const std::string kBase = R"(name: test
materials:
  rubber:
    model: membrane
    density: 1200
    wave_speed: 1000
bodies:
  sheet:
    material: rubber
    origin: [0, 0, 0]
    size: [0.01, 0.01]
    thickness: 0.0005
    spacing: 0.001
stages:
  - duration: 1.0e-5
)";

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// `text` with the first occurrence of `from` replaced by `to` (a test failure if absent).
std::string with(const std::string& from, const std::string& to, std::string text = kBase) {
  const auto pos = text.find(from);
  if (pos == std::string::npos) {
    ADD_FAILURE() << "'" << from << "' not found in the scene text";
    return text;
  }
  return text.replace(pos, from.size(), to);
}

/// The message of the InputError that parsing throws ("<no error>" when none is thrown). Every
/// message must be a single line.
std::string error_of(const std::string& text, const std::vector<Override>& overrides = {}) {
  try {
    peri::parse_scene(text, "scene.yaml", overrides);
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    return msg;
  }
  return "<no error>";
}

/// 1-based number of the first line of `text` that starts with `start` (0 if none).
int line_of(const std::string& text, const std::string& start) {
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n)
    if (line.rfind(start, 0) == 0) return n;
  return 0;
}

bool same_bits(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

template <std::size_t N>
void expect_same_bits(const std::array<double, N>& a, const std::array<double, N>& b,
                      const std::string& what) {
  for (std::size_t i = 0; i < N; ++i)
    EXPECT_TRUE(same_bits(a[i], b[i])) << what << "[" << i << "]: " << a[i] << " vs " << b[i];
}

void expect_same_bits(const std::optional<double>& a, const std::optional<double>& b,
                      const std::string& what) {
  ASSERT_EQ(a.has_value(), b.has_value()) << what;
  if (a) {
    EXPECT_TRUE(same_bits(*a, *b)) << what << ": " << *a << " vs " << *b;
  }
}

void expect_same_bits(double a, double b, const std::string& what) {
  EXPECT_TRUE(same_bits(a, b)) << what << ": " << a << " vs " << b;
}

/// Field-by-field equality (source locations excepted), doubles compared bit for bit.
void expect_same(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.description, b.description);
  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (std::size_t i = 0; i < a.materials.size(); ++i) {
    const auto& x = a.materials[i];
    const auto& y = b.materials[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.model, y.model);
    expect_same_bits(x.density, y.density, "density");
    expect_same_bits(x.wave_speed, y.wave_speed, "wave_speed");
    expect_same_bits(x.bulk_modulus, y.bulk_modulus, "bulk_modulus");
    expect_same_bits(x.youngs_modulus, y.youngs_modulus, "youngs_modulus");
    expect_same_bits(x.micromodulus, y.micromodulus, "micromodulus");
    EXPECT_EQ(x.influence, y.influence);
    expect_same_bits(x.critical_stretch, y.critical_stretch, "critical_stretch");
    expect_same_bits(x.critical_stretch_at_horizon, y.critical_stretch_at_horizon,
                     "critical_stretch_at_horizon");
    ASSERT_EQ(x.hardening.has_value(), y.hardening.has_value());
    if (x.hardening) {
      expect_same_bits(x.hardening->coefficient, y.hardening->coefficient, "coefficient");
      expect_same_bits(x.hardening->exponent, y.hardening->exponent, "exponent");
    }
  }
  ASSERT_EQ(a.bodies.size(), b.bodies.size());
  for (std::size_t i = 0; i < a.bodies.size(); ++i) {
    const auto& x = a.bodies[i];
    const auto& y = b.bodies[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.kind, y.kind);
    EXPECT_EQ(x.material, y.material);
    expect_same_bits(x.origin, y.origin, "origin");
    expect_same_bits(x.size, y.size, "size");
    expect_same_bits(x.thickness, y.thickness, "thickness");
    expect_same_bits(x.spacing, y.spacing, "spacing");
    EXPECT_EQ(x.grid, y.grid);
    expect_same_bits(x.horizon_factor, y.horizon_factor, "horizon_factor");
    expect_same_bits(x.horizon, y.horizon, "horizon");
    EXPECT_EQ(x.quadrature, y.quadrature);
  }
  ASSERT_EQ(a.cracks.size(), b.cracks.size());
  for (std::size_t i = 0; i < a.cracks.size(); ++i) {
    EXPECT_EQ(a.cracks[i].name, b.cracks[i].name);
    expect_same_bits(a.cracks[i].from, b.cracks[i].from, "from");
    expect_same_bits(a.cracks[i].to, b.cracks[i].to, "to");
  }
  ASSERT_EQ(a.boundaries.size(), b.boundaries.size());
  for (std::size_t i = 0; i < a.boundaries.size(); ++i) {
    const auto& x = a.boundaries[i];
    const auto& y = b.boundaries[i];
    EXPECT_EQ(x.name, y.name);
    expect_same_bits(x.region.min, y.region.min, "region.min");
    expect_same_bits(x.region.max, y.region.max, "region.max");
    EXPECT_EQ(x.region.body, y.region.body);
    expect_same_bits(x.velocity, y.velocity, "velocity");
    EXPECT_EQ(x.components, y.components);
    expect_same_bits(x.ramp_time, y.ramp_time, "ramp_time");
  }
  expect_same_bits(a.initial.displacement_gradient, b.initial.displacement_gradient, "displacement_gradient");
  expect_same_bits(a.initial.velocity_gradient, b.initial.velocity_gradient, "velocity_gradient");
  expect_same_bits(a.initial.center, b.initial.center, "center");
  expect_same_bits(a.initial.seed_amplitude, b.initial.seed_amplitude, "seed_amplitude");
  expect_same_bits(a.initial.seed_wavelength_x, b.initial.seed_wavelength_x, "wavelength_x");
  expect_same_bits(a.initial.seed_wavelength_y, b.initial.seed_wavelength_y, "wavelength_y");
  ASSERT_EQ(a.stages.size(), b.stages.size());
  for (std::size_t i = 0; i < a.stages.size(); ++i) {
    const auto& x = a.stages[i];
    const auto& y = b.stages[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.kind, y.kind);
    expect_same_bits(x.duration, y.duration, "duration");
    EXPECT_EQ(x.steps, y.steps);
    expect_same_bits(x.dt, y.dt, "dt");
    expect_same_bits(x.safety_factor, y.safety_factor, "safety_factor");
    EXPECT_EQ(x.allow_unstable_dt, y.allow_unstable_dt);
  }
  EXPECT_EQ(a.output.frames, b.output.frames);
  EXPECT_EQ(a.output.series_every, b.output.series_every);
  EXPECT_EQ(a.output.write_velocity, b.output.write_velocity);
  EXPECT_EQ(a.output.fields, b.output.fields);
  EXPECT_EQ(a.output.node_stride, b.output.node_stride);
  EXPECT_EQ(a.output.region, b.output.region);
  EXPECT_EQ(a.output.single_precision, b.output.single_precision);
  EXPECT_EQ(a.output.check_free_space, b.output.check_free_space);
  expect_same_bits(a.output.progress_seconds, b.output.progress_seconds, "progress_seconds");
  EXPECT_EQ(a.output.checkpoint_every_steps, b.output.checkpoint_every_steps);
  expect_same_bits(a.output.checkpoint_every_seconds, b.output.checkpoint_every_seconds,
                   "checkpoint_every_seconds");
}

/// Emits, re-reads and re-emits; the text and the structs must not change.
void expect_round_trip(const std::string& text) {
  const Scene first = peri::parse_scene(text, "scene.yaml");
  const std::string emitted = peri::emit_scene(first);
  const Scene second = peri::parse_scene(emitted, "emitted.yaml");
  EXPECT_EQ(peri::emit_scene(second), emitted);
  expect_same(first, second);
}

// ------------------------------------------------------------------------------------------------
// Valid scenes

TEST(SceneFile, DefaultSceneParses) {
  const Scene s = peri::load_scene(kDefaultScenePath);
  EXPECT_EQ(s.file, kDefaultScenePath);
  EXPECT_EQ(s.name, "slit-membrane");
  EXPECT_THAT(s.description, HasSubstr("Example 7.1"));

  ASSERT_EQ(s.materials.size(), 1u);
  const peri::Material& rubber = s.materials[0];
  EXPECT_EQ(rubber.name, "rubber");
  EXPECT_EQ(rubber.model, "membrane");
  EXPECT_EQ(rubber.density, 1200.0);
  EXPECT_EQ(rubber.wave_speed, 1000.0);
  EXPECT_FALSE(rubber.bulk_modulus);
  EXPECT_FALSE(rubber.youngs_modulus);
  EXPECT_FALSE(rubber.micromodulus);
  EXPECT_EQ(rubber.influence, peri::Influence::Constant);
  EXPECT_EQ(rubber.critical_stretch, 2.0);
  EXPECT_FALSE(rubber.critical_stretch_at_horizon);
  EXPECT_FALSE(rubber.hardening);
  EXPECT_EQ(rubber.where.file, kDefaultScenePath);
  EXPECT_EQ(rubber.where.line, line_of(read_file(kDefaultScenePath), "    model: membrane"));

  ASSERT_EQ(s.bodies.size(), 1u);
  const peri::Body& sheet = s.bodies[0];
  EXPECT_EQ(sheet.name, "sheet");
  EXPECT_EQ(sheet.kind->name, "membrane");
  EXPECT_EQ(sheet.material, "rubber");
  EXPECT_EQ(sheet.origin, (peri::Vec3{-0.025, -0.025, 0}));
  EXPECT_EQ(sheet.size, (peri::Vec3{0.05, 0.05, 0}));
  EXPECT_EQ(sheet.thickness, 5.0e-4);
  EXPECT_EQ(sheet.spacing, 1.5625e-4);  // demo resolution: 320 x 320 nodes
  EXPECT_EQ(sheet.horizon_factor, 3.0);
  EXPECT_FALSE(sheet.horizon);
  EXPECT_DOUBLE_EQ(sheet.horizon_value(), 3 * 1.5625e-4);
  EXPECT_EQ(sheet.quadrature, peri::Quadrature::PartialArea);

  ASSERT_EQ(s.cracks.size(), 1u);
  EXPECT_EQ(s.cracks[0].name, "slit");
  EXPECT_EQ(s.cracks[0].from, (peri::Vec3{-0.005, 0, 0}));
  EXPECT_EQ(s.cracks[0].to, (peri::Vec3{0.005, 0, 0}));

  ASSERT_EQ(s.boundaries.size(), 2u);
  EXPECT_EQ(s.boundaries[0].name, "top");
  EXPECT_EQ(s.boundaries[0].region.min, (peri::Vec3{-1, 0.0242, -1}));
  EXPECT_EQ(s.boundaries[0].region.max, (peri::Vec3{1, 1, 1}));
  EXPECT_EQ(s.boundaries[0].region.body, "");
  EXPECT_GT(s.boundaries[0].velocity[1], 0.0);  // top edge pulled up
  EXPECT_EQ(s.boundaries[0].velocity[0], 0.0);
  EXPECT_EQ(s.boundaries[1].name, "bottom");
  EXPECT_EQ(s.boundaries[1].velocity[1], -s.boundaries[0].velocity[1]);

  EXPECT_EQ(s.initial.displacement_gradient[4], 0.08);
  EXPECT_EQ(s.initial.displacement_gradient[0], 0.0);
  EXPECT_GT(s.initial.seed_amplitude, 0.0);
  EXPECT_EQ(s.initial.seed_wavelength_x, 0.005);
  EXPECT_EQ(s.initial.seed_wavelength_y, 0.005);

  ASSERT_EQ(s.stages.size(), 1u);
  EXPECT_EQ(s.stages[0].name, "pull");
  EXPECT_GT(s.stages[0].duration, 0.0);
  EXPECT_FALSE(s.stages[0].steps);
  EXPECT_EQ(s.stages[0].safety_factor, 0.35);
  EXPECT_GE(s.output.frames, 1);
  EXPECT_TRUE(s.output.write_velocity);
}

TEST(SceneFile, DefaultsAreFilledIn) {
  const std::string text = kBase + R"(cracks:
  - from: [0, 0, 0]
    to: [0.001, 0, 0]
boundaries:
  - name: clamp
    region: {min: [0, 0, 0], max: [1, 1, 1]}
)";
  const Scene s = peri::parse_scene(text, "scene.yaml");
  EXPECT_EQ(s.file, "scene.yaml");
  EXPECT_EQ(s.description, "");
  const peri::Material& m = s.materials.at(0);
  EXPECT_EQ(m.influence, peri::Influence::Constant);
  EXPECT_FALSE(m.critical_stretch);
  EXPECT_FALSE(m.hardening);
  const peri::Body& b = s.bodies.at(0);
  EXPECT_EQ(b.kind->name, "membrane");
  EXPECT_EQ(b.grid, peri::Grid::Square);
  EXPECT_EQ(b.horizon_factor, 3.0);
  EXPECT_FALSE(b.horizon);
  EXPECT_EQ(b.quadrature, peri::Quadrature::PartialArea);
  EXPECT_EQ(b.size, (peri::Vec3{0.01, 0.01, 0}));
  EXPECT_EQ(s.cracks.at(0).name, "crack0");
  const peri::Boundary& c = s.boundaries.at(0);
  EXPECT_EQ(c.velocity, (peri::Vec3{0, 0, 0}));
  EXPECT_EQ(c.components, (std::array<bool, 3>{true, true, true}));
  EXPECT_EQ(c.ramp_time, 0.0);
  EXPECT_EQ(c.region.body, "");
  for (double x : s.initial.displacement_gradient) EXPECT_EQ(x, 0.0);
  for (double x : s.initial.velocity_gradient) EXPECT_EQ(x, 0.0);
  EXPECT_EQ(s.initial.center, (peri::Vec3{0, 0, 0}));
  EXPECT_EQ(s.initial.seed_amplitude, 0.0);
  EXPECT_EQ(s.initial.seed_wavelength_x, 0.0);
  const peri::Stage& st = s.stages.at(0);
  EXPECT_EQ(st.name, "stage0");
  EXPECT_EQ(st.kind, peri::StageKind::Dynamic);
  EXPECT_EQ(st.duration, 1.0e-5);
  EXPECT_FALSE(st.steps);
  EXPECT_FALSE(st.dt);
  EXPECT_EQ(st.safety_factor, 0.7);
  EXPECT_FALSE(st.allow_unstable_dt);
  EXPECT_EQ(s.output.frames, 20);
  EXPECT_EQ(s.output.series_every, 10);
  EXPECT_TRUE(s.output.write_velocity);
  EXPECT_EQ(s.output.progress_seconds, 2.0);
}

TEST(SceneFile, MapsKeepFileOrder) {
  const std::string text = with("bodies:", R"(  steel:
    model: pmb
    density: 7800
    micromodulus: 1.0e19
  alu:
    model: pmb
    density: 2700
    youngs_modulus: 7.0e10
bodies:
  zeta:
    kind: solid
    material: steel
    origin: [0, 0, 0]
    size: [0.01, 0.01, 0.01]
    spacing: 0.001)");
  const Scene s = peri::parse_scene(text, "scene.yaml");
  ASSERT_EQ(s.materials.size(), 3u);
  EXPECT_EQ(s.materials[0].name, "rubber");
  EXPECT_EQ(s.materials[1].name, "steel");
  EXPECT_EQ(s.materials[2].name, "alu");
  ASSERT_EQ(s.bodies.size(), 2u);
  EXPECT_EQ(s.bodies[0].name, "zeta");
  EXPECT_EQ(s.bodies[0].kind->name, "solid");
  EXPECT_EQ(s.bodies[1].name, "sheet");
  EXPECT_EQ(s.material_index("steel"), 1);
  EXPECT_EQ(s.material_index("alu"), 2);
  EXPECT_EQ(s.material_index("nope"), -1);
  EXPECT_EQ(s.material("alu").youngs_modulus, 7.0e10);
  EXPECT_THROW(s.material("nope"), InputError);
}

TEST(SceneFile, IntegersMayBeWrittenAsIntegralFloats) {
  const Scene s = peri::parse_scene(
      with("  - duration: 1.0e-5", "  - steps: 1e3\noutput: {frames: 40.0, series_every: 5}"), "scene.yaml");
  EXPECT_EQ(s.stages.at(0).steps, 1000);
  EXPECT_EQ(s.stages.at(0).duration, 0.0);
  EXPECT_EQ(s.output.frames, 40);
  EXPECT_EQ(s.output.series_every, 5);
}

TEST(SceneFile, EmptyOptionalValuesCountAsNotGiven) {
  const Scene s = peri::parse_scene(kBase + "cracks:\ninitial:\noutput: ~\n", "scene.yaml");
  EXPECT_TRUE(s.cracks.empty());
  EXPECT_EQ(s.output.frames, 20);
}

TEST(SceneFile, LoadReportsUnreadableFile) {
  try {
    peri::load_scene("/nonexistent/x.yaml");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "cannot read scene file '/nonexistent/x.yaml': No such file or directory");
  }
}

// ------------------------------------------------------------------------------------------------
// Round trip

TEST(SceneRoundTrip, DefaultScene) {
  const std::string text = read_file(kDefaultScenePath);
  ASSERT_FALSE(text.empty());
  expect_round_trip(text);
}

TEST(SceneRoundTrip, EveryFeatureAndAwkwardValues) {
  const std::string text = R"(name: "true"
description: "colon: quote \" backslash \\ tab\t newline\n # hash, unicode é"
materials:
  "rubber_gum-2":
    model: membrane
    density: 0.30000000000000004
    bulk_modulus: 3.3333333333333335e5
    influence: conical
    critical_stretch: 1.1
    critical_stretch_at_horizon: 1.0000000001000002
    hardening: {coefficient: 0, exponent: 4.5}
  "1":
    model: pmb
    density: 6.02214076e23
    micromodulus: 1.0e-300
    critical_stretch: 0.03
bodies:
  sheet:
    material: rubber_gum-2
    origin: [-0.1, 0.2, -0.0]
    size: [0.7, 0.1, 0]
    thickness: 1.0e-3
    spacing: 0.01
    grid: hexagonal
    horizon: 0.0301
    quadrature: full
  block:
    kind: solid
    material: "1"
    origin: [1, 2, 3]
    size: [0.1, 0.2, 0.3]
    spacing: 0.01
    horizon_factor: 4.015
cracks:
  - from: [0, 0, 0]
    to: [0.1, 0, 0]
  - name: "2e3"
    from: [0, 1, 0]
    to: [0.1, 1, 0]
boundaries:
  - name: "null"
    region: {min: [-1, -1, -1], max: [1, 1, 1], body: block}
    velocity: [1.0e-7, 0, 0]
    components: [z, x]
    ramp_time: 1.0e-6
initial:
  displacement_gradient: [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]]
  velocity_gradient: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
  center: [0.5, 0.5, 0]
  seed: {amplitude: 0}
stages:
  - steps: 100
    dt: 1.0e-9
    allow_unstable_dt: true
  - name: relax
    steps: 12
    safety_factor: 1
output:
  frames: 7
  series_every: 3
  velocity: false
  progress_seconds: 0
  checkpoint_every_steps: 25
  checkpoint_every_seconds: 0.5
)";
  const Scene s = peri::parse_scene(text, "scene.yaml");
  EXPECT_EQ(s.name, "true");
  EXPECT_EQ(s.description, "colon: quote \" backslash \\ tab\t newline\n # hash, unicode é");
  EXPECT_EQ(s.materials.at(0).name, "rubber_gum-2");
  EXPECT_EQ(s.materials.at(1).name, "1");
  EXPECT_EQ(s.boundaries.at(0).name, "null");
  EXPECT_EQ(s.boundaries.at(0).components, (std::array<bool, 3>{true, false, true}));
  EXPECT_EQ(s.cracks.at(0).name, "crack0");
  EXPECT_EQ(s.stages.at(0).name, "stage0");
  EXPECT_EQ(s.stages.at(0).steps, 100);
  EXPECT_EQ(s.bodies.at(0).horizon, 0.0301);
  EXPECT_EQ(s.initial.displacement_gradient[5], 0.6);
  expect_round_trip(text);

  const std::string emitted = peri::emit_scene(s);
  EXPECT_THAT(emitted, HasSubstr("density: 0.30000000000000004\n"));
  EXPECT_THAT(emitted, HasSubstr("micromodulus: 1e-300\n"));
  EXPECT_THAT(emitted, HasSubstr("density: 6.02214076e23\n"));
  EXPECT_THAT(emitted, HasSubstr("velocity: [1e-7, 0, 0]\n"));
  EXPECT_THAT(emitted, HasSubstr("bulk_modulus: 333333.3333333334\n"));
  EXPECT_THAT(emitted, HasSubstr("components: [x, z]\n"));
  EXPECT_THAT(emitted, HasSubstr("    horizon: 0.0301\n"));
  EXPECT_THAT(emitted, Not(HasSubstr("horizon_factor: 3\n")));
}

TEST(SceneRoundTrip, EmitsEveryResolvedKeyInSchemaOrder) {
  const Scene s = peri::parse_scene(kBase, "scene.yaml");
  const std::string expected = R"(name: test
description: ""
materials:
  rubber:
    model: membrane
    density: 1200
    wave_speed: 1000
    influence: constant
bodies:
  sheet:
    kind: membrane
    material: rubber
    origin: [0, 0, 0]
    size: [0.01, 0.01]
    thickness: 0.0005
    spacing: 0.001
    grid: square
    horizon_factor: 3
    quadrature: partial_area
initial:
  displacement_gradient: [[0, 0, 0], [0, 0, 0], [0, 0, 0]]
  velocity_gradient: [[0, 0, 0], [0, 0, 0], [0, 0, 0]]
  center: [0, 0, 0]
  seed: {amplitude: 0, wavelength: [0, 0]}
stages:
  - name: stage0
    kind: dynamic
    duration: 1e-5
    safety_factor: 0.7
    allow_unstable_dt: false
    damping: 0
stability:
  energy_error: 0.05
  motion_per_step: 1
output:
  frames: 20
  series_every: 10
  fields: [position, displacement, velocity, damage, strain_energy_density]
  node_stride: 1
  precision: double
  check_free_space: true
  progress_seconds: 2
  checkpoint_every_steps: 0
  checkpoint_every_seconds: 900
)";
  EXPECT_EQ(peri::emit_scene(s), expected);
}

TEST(SceneRoundTrip, DerivedLinesBecomeComments) {
  const Scene s = peri::parse_scene(kBase, "scene.yaml");
  const std::string text = peri::emit_scene(s, {"dt = 1e-7 s", "two\nlines"});
  EXPECT_THAT(text, HasSubstr("\n# dt = 1e-7 s\n# two\n# lines\n"));
  EXPECT_EQ(text.substr(text.size() - 8), "# lines\n");
  EXPECT_EQ(peri::emit_scene(peri::parse_scene(text, "emitted.yaml")), peri::emit_scene(s));
}

// ------------------------------------------------------------------------------------------------
// Overrides

TEST(SceneOverride, SetsNestedValue) {
  const Scene s = peri::parse_scene(kBase, "scene.yaml",
                                    {{"bodies.sheet.spacing", "5e-4"}, {"materials.rubber.density", "900"}});
  EXPECT_EQ(s.bodies.at(0).spacing, 5e-4);
  EXPECT_EQ(s.materials.at(0).density, 900.0);
}

TEST(SceneOverride, AppliesInOrder) {
  const Scene s = peri::parse_scene(kBase, "scene.yaml",
                                    {{"bodies.sheet.spacing", "5e-4"}, {"bodies.sheet.spacing", "2e-4"}});
  EXPECT_EQ(s.bodies.at(0).spacing, 2e-4);
}

TEST(SceneOverride, ListEntryByIndexAndByName) {
  const Scene def = peri::load_scene(kDefaultScenePath, {{"stages.0.duration", "2e-4"},
                                                         {"boundaries.top.velocity", "[0, 20, 0]"},
                                                         {"boundaries.1.ramp_time", "1e-5"},
                                                         {"stages.pull.dt", "1e-8"},
                                                         {"cracks.slit.to", "[0.01, 0, 0]"}});
  EXPECT_EQ(def.stages.at(0).duration, 2e-4);
  EXPECT_EQ(def.stages.at(0).dt, 1e-8);
  EXPECT_EQ(def.boundaries.at(0).velocity, (peri::Vec3{0, 20, 0}));
  EXPECT_EQ(def.boundaries.at(1).velocity, peri::load_scene(kDefaultScenePath).boundaries.at(1).velocity);
  EXPECT_EQ(def.boundaries.at(1).ramp_time, 1e-5);
  EXPECT_EQ(def.cracks.at(0).to, (peri::Vec3{0.01, 0, 0}));
}

TEST(SceneOverride, UnnamedEntriesByDefaultName) {
  const Scene s = peri::parse_scene(kBase, "scene.yaml", {{"stages.stage0.steps", "50"}});
  EXPECT_EQ(s.stages.at(0).steps, 50);
}

TEST(SceneOverride, CreatesOptionalKeysAndMaps) {
  const Scene s = peri::parse_scene(kBase, "scene.yaml",
                                    {{"bodies.sheet.grid", "hexagonal"},
                                     {"materials.rubber.hardening.coefficient", "10"},
                                     {"materials.rubber.hardening.exponent", "3"},
                                     {"output.frames", "5"},
                                     {"initial.seed", "{amplitude: 1e-6, wavelength: [1, 2]}"},
                                     {"boundaries", "[{name: a, region: {min: [0, 0, 0], max: [1, 1, 1]}}]"},
                                     {"stages.0.allow_unstable_dt", "true"}});
  EXPECT_EQ(s.bodies.at(0).grid, peri::Grid::Hexagonal);
  ASSERT_TRUE(s.materials.at(0).hardening);
  EXPECT_EQ(s.materials.at(0).hardening->coefficient, 10.0);
  EXPECT_EQ(s.materials.at(0).hardening->exponent, 3.0);
  EXPECT_EQ(s.output.frames, 5);
  EXPECT_EQ(s.output.series_every, 10);
  EXPECT_EQ(s.initial.seed_amplitude, 1e-6);
  EXPECT_EQ(s.initial.seed_wavelength_y, 2.0);
  ASSERT_EQ(s.boundaries.size(), 1u);
  EXPECT_EQ(s.boundaries[0].name, "a");
  EXPECT_EQ(s.boundaries[0].where.file, "--set");
  EXPECT_TRUE(s.stages.at(0).allow_unstable_dt);
}

TEST(SceneOverride, BadPaths) {
  EXPECT_EQ(error_of(kBase, {{"stages.3.duration", "1"}}),
            "--set stages.3.duration=1: index 3 is out of range: stages has 1 entries");
  EXPECT_THAT(error_of(read_file(kDefaultScenePath), {{"boundaries.left.velocity", "[1, 0, 0]"}}),
              AllOf(StartsWith("--set boundaries.left.velocity=[1, 0, 0]: "),
                    HasSubstr("no entry named 'left' in boundaries"), HasSubstr("top, bottom")));
  // A key inside a body or material the scene lacks: a misspelt name, said as such with the
  // names there are (not "missing required key" of an entry the override began).
  EXPECT_EQ(error_of(kBase, {{"bodies.shet.spacing", "1"}}),
            "--set bodies.shet.spacing=1: the scene has no body 'shet'; its bodies: sheet (a new body is given "
            "whole: --set bodies.shet={...})");
  EXPECT_THAT(error_of(kBase, {{"materials.rubbr.density", "1"}}),
              StartsWith("--set materials.rubbr.density=1: the scene has no material 'rubbr'; its materials: rubber"));
  EXPECT_THAT(error_of(kBase, {{"name.x", "1"}}),
              AllOf(StartsWith("--set name.x=1: "), HasSubstr("'name'"), HasSubstr("no entry 'x'")));
  EXPECT_THAT(error_of(kBase, {{"bodies..spacing", "1"}}),
              StartsWith("--set bodies..spacing=1: expected a dotted key path"));
  EXPECT_THAT(error_of(kBase, {{"", "1"}}), StartsWith("--set =1: expected a dotted key path"));
  // Values are shown cut after 60 characters, with their length, and control characters escaped:
  // one short line whatever the value.
  const std::string deep = std::string(5000, '[') + std::string(5000, ']');
  EXPECT_EQ(error_of(kBase, {{"bodies.sheet.spacing", deep}}),
            "--set bodies.sheet.spacing=" + std::string(60, '[') + "... (10000 characters): cannot read the value as YAML: " +
                "bad file");
  EXPECT_EQ(error_of(kBase, {{"bodies.sheet.spacing", std::string(500, '1')}}),
            "--set: bodies.sheet.spacing: expected a finite number, got " + std::string(60, '1') + "... (500 characters)");
  EXPECT_EQ(error_of(kBase, {{"bodies.sheet.spacing", "\"a\\tb\\u001b[31m\""}}),
            "--set: bodies.sheet.spacing: expected a positive number [m], got \"a\\x09b\\x1b[31m\"");
  EXPECT_THAT(error_of(kBase, {{"bodies.sheet.origin", "[1, 2"}}),
              StartsWith("--set bodies.sheet.origin=[1, 2: cannot read the value as YAML"));
}

// A tool's series.csv columns repeat neither a crack tip track's (a tool named tip2) nor another
// tool's (tools 'a' and 'a_force' both giving a_force_x); 'tip' alone and 'tips' are fine.
TEST(SceneTools, SeriesColumnsAreUnique) {
  const std::string cylinder = "{kind: cylinder, radius: 0.001, center: [-0.03, 0]}";
  auto tools = [&](const std::string& a, const std::string& b) {
    return std::vector<Override>{{"tools", "[{name: " + a + ", " + cylinder.substr(1, cylinder.size() - 2) + "}, {name: " +
                                               b + ", kind: cylinder, radius: 0.001, center: [0.03, 0]}]"}};
  };
  EXPECT_EQ(error_of(kBase, tools("tip2", "b")),
            "--set: tools.0: tool 'tip2': its series.csv columns tip2_x, tip2_y would repeat those of crack tip track 2; "
            "expected another name");
  EXPECT_EQ(error_of(kBase, tools("a", "a_force")),
            "--set: tools.1: tool 'a_force': its series.csv column a_force_x would repeat tool 'a''s; expected another "
            "name");
  EXPECT_EQ(error_of(kBase, tools("tip", "tips")), "<no error>");
}

TEST(SceneOverride, ValidationErrorsOfOverriddenValuesReadSet) {
  EXPECT_EQ(error_of(kBase, {{"bodies.sheet.spacing", "-1"}}),
            "--set: bodies.sheet.spacing: expected a positive number [m], got -1");
  EXPECT_THAT(error_of(kBase, {{"materials.rubber.hardening.coefficient", "1"}}),
              StartsWith("--set: materials.rubber.hardening: missing required key 'exponent'"));
  EXPECT_THAT(error_of(kBase, {{"bodies.sheet", "{material: rubber}"}}),
              StartsWith("--set: bodies.sheet: missing required key 'thickness'"));
  EXPECT_THAT(error_of(kBase, {{"bodies.sheet", "{material: rubber, thickness: 0.001}"}}),
              StartsWith("--set: bodies.sheet: missing required key 'origin' (lower corner [x, y, z], m; or mesh)"));
  EXPECT_THAT(error_of(kBase, {{"materials.rubber.youngs_modulus", "1e9"}}),
              StartsWith("--set: materials.rubber: give exactly one of"));
  EXPECT_THAT(error_of(kBase, {{"stages.0.steps", "2.5"}}),
              StartsWith("--set: stages.0.steps: expected an integer >= 1 and <= 1000000000, got 2.5"));
  // A problem in the file is still reported at its line when other keys are overridden.
  EXPECT_THAT(error_of(with("density: 1200", "density: -1"), {{"bodies.sheet.spacing", "1e-4"}}),
              StartsWith("scene.yaml:5: materials.rubber.density: "));
}

// ------------------------------------------------------------------------------------------------
// Errors: keys

TEST(SceneErrors, UnknownKey) {
  EXPECT_EQ(error_of(with("density: 1200", "densty: 1200")),
            "scene.yaml:5: materials.rubber.densty: unknown key; expected one of: model, density, "
            "wave_speed, bulk_modulus, youngs_modulus, micromodulus, influence, critical_stretch, "
            "critical_stretch_at_horizon, tip_advance, tip_advance_tips, hardening, mooney_rivlin_a, mooney_rivlin_b, cutoff, "
      "fracture_separation, "
            "breaking, kelvin_viscosity, stiffening_onset, stiffening_width, break_separation");
  EXPECT_THAT(error_of(kBase + "outptu: {frames: 2}\n"),
              AllOf(StartsWith("scene.yaml:16: outptu: unknown key; expected one of: name, "),
                    HasSubstr("stages, stability, output")));
  EXPECT_THAT(error_of(with("spacing: 0.001", "spacing: 0.001\n    horizon_facter: 2")),
              StartsWith("scene.yaml:14: bodies.sheet.horizon_facter: unknown key; expected one of: kind,"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - duration: 1.0e-5\n    sfety: 1")),
              StartsWith("scene.yaml:16: stages.0.sfety: unknown key"));
}

TEST(SceneErrors, MissingKey) {
  EXPECT_EQ(error_of(with("    density: 1200\n", "")),
            "scene.yaml:4: materials.rubber: missing required key 'density' (mass density, kg/m^3)");
  EXPECT_THAT(error_of(with("stages:\n  - duration: 1.0e-5\n", "")),
              StartsWith("scene.yaml:1: top level: missing required key 'stages'"));
  EXPECT_THAT(error_of(with("    thickness: 0.0005\n", "")),
              StartsWith("scene.yaml:9: bodies.sheet: missing required key 'thickness'"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - dt: 1.0e-9")),
              StartsWith("scene.yaml:15: stages.0: missing required key 'duration'"));
  EXPECT_THAT(error_of(kBase + "boundaries:\n  - region: {min: [0, 0, 0], max: [1, 1, 1]}\n"),
              StartsWith("scene.yaml:17: boundaries.0: missing required key 'name'"));
  EXPECT_THAT(error_of(kBase + "boundaries:\n  - name: a\n    region: {min: [0, 0, 0]}\n"),
              StartsWith("scene.yaml:18: boundaries.0.region: missing required key 'max'"));
}

TEST(SceneErrors, DuplicateKey) {
  EXPECT_EQ(error_of(with("density: 1200", "density: 1200\n    density: 1300")),
            "scene.yaml:6: materials.rubber.density: duplicate key (first given at line 5)");
}

TEST(SceneErrors, WrongType) {
  EXPECT_EQ(error_of(with("density: 1200", "density: [1, 2]")),
            "scene.yaml:5: materials.rubber.density: expected a positive number [kg/m^3], got a "
            "list of 2");
  EXPECT_EQ(error_of(with("density: 1200", "density: \"1200\"")),
            "scene.yaml:5: materials.rubber.density: expected a positive number [kg/m^3], got "
            "\"1200\"");
  EXPECT_EQ(error_of(with("density: 1200", "density: abc")),
            "scene.yaml:5: materials.rubber.density: expected a positive number [kg/m^3], got abc");
  EXPECT_EQ(error_of(with("density: 1200", "density:")),
            "scene.yaml:5: materials.rubber.density: expected a positive number [kg/m^3], got "
            "nothing (empty value)");
  EXPECT_EQ(error_of(with("name: test", "name: {a: 1}")),
            "scene.yaml:1: name: expected a non-empty string, got a map");
  EXPECT_EQ(error_of(with("name: test", "name: ''")),
            "scene.yaml:1: name: expected a non-empty string, got \"\"");
  EXPECT_THAT(error_of(with("origin: [0, 0, 0]", "origin: [0, 0]")),
              StartsWith("scene.yaml:10: bodies.sheet.origin: expected a list of 3 numbers [x, y, "
                         "z] [m], got a list of 2"));
  EXPECT_THAT(error_of(with("origin: [0, 0, 0]", "origin: 5")),
              StartsWith("scene.yaml:10: bodies.sheet.origin: expected a list of 3 numbers"));
  EXPECT_THAT(error_of(with("origin: [0, 0, 0]", "origin: [0, x, 0]")),
              StartsWith("scene.yaml:10: bodies.sheet.origin.1: expected a number [m], got x"));
  EXPECT_THAT(error_of(with("materials:\n  rubber:\n    model: membrane\n    density: 1200\n"
                            "    wave_speed: 1000\n",
                            "materials: [rubber]\n")),
              StartsWith("scene.yaml:2: materials: expected a map of material name to material, "
                         "got a list of 1"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  duration: 1.0e-5")),
              StartsWith("scene.yaml:15: stages: expected a list of stages, got a map"));
  EXPECT_THAT(error_of(kBase + "output: {velocity: yes}\n"),
              StartsWith("scene.yaml:16: output.velocity: expected true or false, got yes"));
  EXPECT_THAT(error_of(with("model: membrane", "model: rubbery")),
              StartsWith("scene.yaml:4: materials.rubber.model: expected one of: membrane, pmb, marder; "
                         "got rubbery"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - 3")),
              StartsWith("scene.yaml:15: stages.0: expected a map describing the stage, got 3"));
}

// ------------------------------------------------------------------------------------------------
// Errors: values

TEST(SceneErrors, NonFiniteNumbers) {
  EXPECT_EQ(error_of(with("density: 1200", "density: .nan")),
            "scene.yaml:5: materials.rubber.density: expected a finite number, got .nan");
  EXPECT_THAT(error_of(with("spacing: 0.001", "spacing: .inf")),
              StartsWith("scene.yaml:13: bodies.sheet.spacing: expected a finite number, got .inf"));
  EXPECT_THAT(error_of(with("origin: [0, 0, 0]", "origin: [0, -.Inf, 0]")),
              StartsWith("scene.yaml:10: bodies.sheet.origin.1: expected a finite number"));
  EXPECT_THAT(error_of(with("density: 1200", "density: 1e999")),
              StartsWith("scene.yaml:5: materials.rubber.density: expected a finite number"));
}

TEST(SceneErrors, NegativeDensity) {
  EXPECT_EQ(error_of(with("density: 1200", "density: -1200")),
            "scene.yaml:5: materials.rubber.density: expected a positive number [kg/m^3], got -1200");
  EXPECT_THAT(
      error_of(with("wave_speed: 1000", "wave_speed: 0")),
      StartsWith("scene.yaml:6: materials.rubber.wave_speed: expected a positive number [m/s], got 0"));
}

TEST(SceneErrors, Thickness) {
  EXPECT_EQ(error_of(with("thickness: 0.0005", "thickness: 0")),
            "scene.yaml:12: bodies.sheet.thickness: expected a positive number [m], got 0");
  EXPECT_EQ(error_of(with("thickness: 0.0005", "thickness: -5e-4")),
            "scene.yaml:12: bodies.sheet.thickness: expected a positive number [m], got -5e-4");
}

TEST(SceneErrors, Spacing) {
  EXPECT_EQ(error_of(with("spacing: 0.001", "spacing: 0")),
            "scene.yaml:13: bodies.sheet.spacing: expected a positive number [m], got 0");
  EXPECT_EQ(error_of(with("spacing: 0.001", "spacing: -0.001")),
            "scene.yaml:13: bodies.sheet.spacing: expected a positive number [m], got -0.001");
  EXPECT_THAT(error_of(with("spacing: 0.001", "spacing: 0.02")),
              StartsWith("scene.yaml:13: bodies.sheet.spacing: spacing must not exceed the smallest "
                         "extent of size (0.01 m), got 0.02"));
}

TEST(SceneErrors, Horizon) {
  EXPECT_EQ(error_of(with("spacing: 0.001", "spacing: 0.001\n    horizon_factor: 0.5")),
            "scene.yaml:14: bodies.sheet.horizon_factor: horizon must be at least one spacing "
            "(expected >= 1), got 0.5");
  EXPECT_EQ(error_of(with("spacing: 0.001", "spacing: 0.001\n    horizon: 0.0005")),
            "scene.yaml:14: bodies.sheet.horizon: horizon must be at least one spacing (expected "
            ">= 0.001 m), got 0.0005");
  EXPECT_THAT(error_of(with("spacing: 0.001", "spacing: 0.001\n    horizon_factor: 3\n    horizon: 0.003")),
              StartsWith("scene.yaml:15: bodies.sheet.horizon: give either horizon [m] or "
                         "horizon_factor, not both"));
  const Scene s =
      peri::parse_scene(with("spacing: 0.001", "spacing: 0.001\n    horizon: 0.001"), "scene.yaml");
  EXPECT_EQ(s.bodies.at(0).horizon_value(), 0.001);
}

TEST(SceneErrors, CriticalStretch) {
  EXPECT_EQ(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: 0.9")),
            "scene.yaml:7: materials.rubber.critical_stretch: the membrane model needs a critical "
            "stretch lambda_0 > 1, got 0.9");
  EXPECT_THAT(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: 1")),
              HasSubstr("scene.yaml:7: materials.rubber.critical_stretch: the membrane model needs a "
                        "critical stretch lambda_0 > 1, got 1"));
  const std::string pmb = with("model: membrane", "model: pmb");
  EXPECT_EQ(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: -0.1", pmb)),
            "scene.yaml:7: materials.rubber.critical_stretch: the pmb model needs a critical bond "
            "strain s_0 > 0, got -0.1");
  EXPECT_THAT(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: 0", pmb)),
              HasSubstr("scene.yaml:7: materials.rubber.critical_stretch: the pmb model needs"));
  const Scene s = peri::parse_scene(
      with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: 0.1", pmb), "scene.yaml");
  EXPECT_EQ(s.materials.at(0).critical_stretch, 0.1);
  EXPECT_THAT(
      error_of(with("wave_speed: 1000",
                    "wave_speed: 1000\n    critical_stretch: 2\n    critical_stretch_at_horizon: 0.5")),
      HasSubstr("scene.yaml:8: materials.rubber.critical_stretch_at_horizon: the membrane model "
                "needs a critical stretch lambda_0 > 1, got 0.5"));
  EXPECT_THAT(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch_at_horizon: 2")),
              StartsWith("scene.yaml:7: materials.rubber.critical_stretch_at_horizon: requires "
                         "critical_stretch"));
}

TEST(SceneErrors, Hardening) {
  EXPECT_THAT(
      error_of(with("wave_speed: 1000", "wave_speed: 1000\n    hardening: {coefficient: 1, exponent: 1}")),
      StartsWith("scene.yaml:7: materials.rubber.hardening.exponent: expected a number in (1, 100], got 1"));
  EXPECT_THAT(
      error_of(with("wave_speed: 1000", "wave_speed: 1000\n    hardening: {coefficient: 1, exponent: 2}",
                    with("model: membrane", "model: pmb"))),
      StartsWith("scene.yaml:7: materials.rubber.hardening: hardening is available only for "
                 "the membrane model"));
}

TEST(SceneErrors, Stiffness) {
  EXPECT_EQ(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    bulk_modulus: 1e9")),
            "scene.yaml:4: materials.rubber: give exactly one of wave_speed, bulk_modulus, "
            "youngs_modulus, micromodulus (found 2)");
  EXPECT_EQ(error_of(with("    wave_speed: 1000\n", "")),
            "scene.yaml:4: materials.rubber: give exactly one of wave_speed, bulk_modulus, "
            "youngs_modulus, micromodulus (found 0)");
}

TEST(SceneErrors, UnknownMaterial) {
  EXPECT_EQ(error_of(with("material: rubber", "material: rubbr")),
            "scene.yaml:9: bodies.sheet.material: no material named 'rubbr'; defined: rubber");
}

TEST(SceneErrors, SolidBodies) {
  const std::string solid = with("material: rubber", "kind: solid\n    material: rubber");
  // A key of other kinds is refused first, with the keys this kind takes.
  EXPECT_EQ(error_of(solid),
            "scene.yaml:13: bodies.sheet.thickness: not used by a solid body (a box of simple-cubic points, a point "
            "cloud or a tetrahedral mesh from a file); expected one of: kind, material, origin, size, points, mesh, "
            "scale, spacing, grid, horizon_factor, horizon, quadrature, cutouts");
  EXPECT_THAT(error_of(with("    thickness: 0.0005\n", "", solid)),
              StartsWith("scene.yaml:12: bodies.sheet.size: expected a solid size [Lx, Ly, Lz]"));
  const std::string box = with("size: [0.01, 0.01]", "size: [0.01, 0.01, 0.01]", solid);
  const std::string ok = with("    thickness: 0.0005\n", "", box);
  EXPECT_EQ(peri::parse_scene(ok, "scene.yaml").bodies.at(0).size, (peri::Vec3{0.01, 0.01, 0.01}));
  EXPECT_THAT(error_of(with("spacing: 0.001", "spacing: 0.001\n    grid: hexagonal", ok)),
              StartsWith("scene.yaml:14: bodies.sheet.grid: a solid body supports only grid square"));
  EXPECT_THAT(error_of(with("size: [0.01, 0.01]", "size: [0.01, 0.01, 0.01]")),
              StartsWith("scene.yaml:11: bodies.sheet.size: expected a membrane size [Lx, Ly]"));
  EXPECT_THAT(error_of(with("size: [0.01, 0.01]", "size: [0.01, 0]")),
              StartsWith("scene.yaml:11: bodies.sheet.size: expected a membrane size"));
}

TEST(SceneErrors, Boundaries) {
  const std::string two = kBase + R"(boundaries:
  - name: top
    region: {min: [0, 0, 0], max: [1, 1, 1]}
  - name: top
    region: {min: [0, 0, 0], max: [1, 1, 1], body: sheet}
)";
  EXPECT_EQ(error_of(two),
            "scene.yaml:19: boundaries.1.name: duplicate boundary name 'top' (also used by "
            "boundaries.0)");
  EXPECT_EQ(error_of(with("body: sheet", "body: shet", with("name: top", "name: bottom", two))),
            "scene.yaml:20: boundaries.1.region.body: no body named 'shet'; defined: sheet");
  EXPECT_THAT(error_of(with("max: [1, 1, 1]}", "max: [1, -1, 1]}", two)),
              StartsWith("scene.yaml:18: boundaries.0.region.max: expected min <= max in every "
                         "component, got y: min 0 > max -1"));
  const std::string one = kBase + "boundaries:\n  - name: a\n    region: {min: [0, 0, 0], max: [1, 1, 1]}\n";
  EXPECT_THAT(error_of(one + "    components: [x, x]\n"),
              StartsWith("scene.yaml:19: boundaries.0.components.1: component 'x' is given twice"));
  EXPECT_THAT(error_of(one + "    components: [x, w]\n"),
              StartsWith("scene.yaml:19: boundaries.0.components.1: expected one of: x, y, z; got w"));
  EXPECT_THAT(error_of(one + "    components: []\n"),
              StartsWith("scene.yaml:19: boundaries.0.components: expected a non-empty list of "
                         "distinct letters from x, y, z"));
  EXPECT_THAT(
      error_of(one + "    ramp_time: -1\n"),
      StartsWith("scene.yaml:19: boundaries.0.ramp_time: expected a non-negative number [s], got -1"));
}

TEST(SceneErrors, Cracks) {
  const std::string cracks = kBase + R"(cracks:
  - from: [0, 0, 0]
    to: [0, 0, 0]
)";
  EXPECT_THAT(error_of(cracks),
              StartsWith("scene.yaml:18: cracks.0.to: a crack needs two different end points"));
  const std::string dup = kBase + R"(cracks:
  - from: [0, 0, 0]
    to: [1, 0, 0]
  - name: crack0
    from: [0, 1, 0]
    to: [1, 1, 0]
)";
  EXPECT_EQ(error_of(dup),
            "scene.yaml:19: cracks.1.name: duplicate crack name 'crack0' (also used by cracks.0)");
}

TEST(SceneErrors, Stages) {
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - steps: 2.5")),
              StartsWith("scene.yaml:15: stages.0.steps: expected an integer >= 1 and <= 1000000000, got 2.5"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - steps: 0")),
              StartsWith("scene.yaml:15: stages.0.steps: expected an integer >= 1 and <= 1000000000, got 0"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - duration: 1.0e-5\n    safety_factor: 1.5")),
              StartsWith("scene.yaml:16: stages.0.safety_factor: expected a number in (0, 1], got 1.5"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - duration: 1.0e-5\n    kind: static")),
              StartsWith("scene.yaml:16: stages.0.kind: expected one of: dynamic, quasistatic, release; got static"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - duration: 1.0e-5\n  - {name: stage0, duration: 1}")),
              StartsWith("scene.yaml:16: stages.1.name: duplicate stage name 'stage0'"));
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  []")),
              StartsWith("scene.yaml:15: stages: expected at least one stage, got an empty list"));
}

TEST(SceneErrors, Output) {
  EXPECT_THAT(error_of(kBase + "output:\n  frames: 0\n"),
              StartsWith("scene.yaml:17: output.frames: expected an integer >= 1"));
  EXPECT_THAT(error_of(kBase + "output:\n  series_every: 2.5\n"),
              StartsWith("scene.yaml:17: output.series_every: expected an integer >= 1"));
  EXPECT_THAT(error_of(kBase + "output:\n  checkpoint_every_steps: -3\n"),
              StartsWith("scene.yaml:17: output.checkpoint_every_steps: expected an integer >= 0, got -3"));
  EXPECT_THAT(error_of(kBase + "output:\n  checkpoint_every_seconds: .inf\n"),
              StartsWith("scene.yaml:17: output.checkpoint_every_seconds: expected a finite number, got .inf"));
  EXPECT_THAT(error_of(kBase + "output:\n  progress_seconds: -1\n"),
              StartsWith("scene.yaml:17: output.progress_seconds: expected a non-negative number [s]"));
}

TEST(SceneErrors, Initial) {
  EXPECT_THAT(error_of(kBase + "initial:\n  displacement_gradient: [[0, 0, 0], [0, 0, 0]]\n"),
              StartsWith("scene.yaml:17: initial.displacement_gradient: expected a 3x3 matrix"));
  EXPECT_THAT(error_of(kBase + "initial:\n  velocity_gradient: [[0, 0, 0], [0, 0], [0, 0, 0]]\n"),
              StartsWith("scene.yaml:17: initial.velocity_gradient.1: expected a row of 3 numbers"));
  EXPECT_THAT(error_of(kBase + "initial:\n  seed: {wavelength: [1, 1]}\n"),
              StartsWith("scene.yaml:17: initial.seed: missing required key 'amplitude'"));
  EXPECT_THAT(error_of(kBase + "initial:\n  seed: {amplitude: -1}\n"),
              StartsWith("scene.yaml:17: initial.seed.amplitude: expected a non-negative number [m]"));
}

// ------------------------------------------------------------------------------------------------
// Errors: the document

TEST(SceneErrors, YamlSyntaxError) {
  EXPECT_THAT(error_of(with("origin: [0, 0, 0]", "origin: [0, 0, 0")),
              StartsWith("scene.yaml:11: YAML syntax error: "));
  EXPECT_THAT(error_of("name: a\n  bad: 1\n"), StartsWith("scene.yaml:2: YAML syntax error: "));
}

TEST(SceneErrors, EmptyOrNotAMap) {
  EXPECT_THAT(error_of(""), StartsWith("scene.yaml:1: the scene is empty"));
  EXPECT_THAT(error_of("# only a comment\n"), StartsWith("scene.yaml:1: the scene is empty"));
  EXPECT_THAT(error_of("- a\n- b\n"), AllOf(StartsWith("scene.yaml:1: expected a YAML map at the top level"),
                                            HasSubstr("got a list of 2")));
  EXPECT_THAT(error_of("just text\n"), StartsWith("scene.yaml:1: expected a YAML map at the top level"));
  EXPECT_THAT(error_of(kBase + "---\nname: b\n"),
              StartsWith("scene.yaml:17: expected a single YAML document, found 2"));
}

// Frames that scale: their fields (in the frames' order), a node selection, single precision.
TEST(SceneOutput, FieldsNodesAndPrecision) {
  const peri::Scene s = peri::parse_scene(kBase, "scene.yaml", {{"output", "{fields: [damage, position], node_stride: 4, "
                                                                          "region: {min: [0, 0, 0], max: [1, 1, 1]}, precision: single}"}});
  EXPECT_EQ(s.output.fields, (std::vector<std::string>{"position", "damage"}));
  EXPECT_FALSE(s.output.write_velocity);
  EXPECT_EQ(s.output.node_stride, 4);
  ASSERT_TRUE(s.output.region);
  EXPECT_TRUE(s.output.single_precision);
  EXPECT_TRUE(s.output.selects_nodes());
  // The resolved scene reads back to the same output.
  const peri::Scene again = peri::parse_scene(peri::emit_scene(s), "resolved.yaml");
  EXPECT_EQ(again.output.fields, s.output.fields);
  EXPECT_EQ(again.output.region, s.output.region);
  EXPECT_EQ(again.output.single_precision, true);
  // velocity: false, the key of earlier scenes, drops velocity from the default fields.
  EXPECT_EQ(peri::parse_scene(kBase, "scene.yaml", {{"output", "{velocity: false}"}}).output.fields,
            (std::vector<std::string>{"position", "displacement", "damage", "strain_energy_density"}));
  EXPECT_THAT(error_of(kBase, {{"output", "{fields: [damage, stress]}"}}),
              HasSubstr("output.fields.1: expected one of: position, displacement, velocity, damage, "
                        "strain_energy_density; got stress"));
  EXPECT_THAT(error_of(kBase, {{"output", "{fields: [damage, damage]}"}}), HasSubstr("'damage' is listed twice"));
  EXPECT_THAT(error_of(kBase, {{"output", "{fields: []}"}}), HasSubstr("output.fields: expected at least one of"));
  EXPECT_THAT(error_of(kBase, {{"output", "{fields: [damage], velocity: true}"}}),
              HasSubstr("output.fields: give fields or velocity, not both"));
  EXPECT_THAT(error_of(kBase, {{"output", "{node_stride: 0}"}}), HasSubstr("output.node_stride"));
  EXPECT_THAT(error_of(kBase, {{"output", "{region: {min: [0, 0, 1], max: [1, 1, 0]}}"}}),
              HasSubstr("output.region.max: expected min <= max in every component, got z"));
  EXPECT_THAT(error_of(kBase, {{"output", "{precision: half}"}}), HasSubstr("expected one of: double, single"));
}

}  // namespace

// Quasi-static and release stages

const std::string kStaged = R"(name: staged
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2}
bodies:
  sheet: {material: rubber, origin: [0, 0, 0], size: [0.01, 0.01], thickness: 0.0005, spacing: 0.001}
cracks:
  - {name: slit, from: [0.004, 0.005, 0], to: [0.006, 0.005, 0]}
boundaries:
  - {name: top, region: {min: [0, 0.0095, 0], max: [0.01, 0.01, 0]}, components: [y]}
  - {name: bottom, region: {min: [0, 0, 0], max: [0.01, 0.0005, 0]}, components: [y]}
stages:
  - {name: preload, kind: quasistatic, displacements: {top: [0, 0.002, 0]}, load_steps: 4}
  - {name: cut, kind: release, cracks: [slit]}
  - {name: run, duration: 1.0e-5, damping: 100, boundary_velocity: {top: [0, 1, 0]}}
)";

TEST(SceneStages, QuasiStaticReleaseAndDynamicKeys) {
  const Scene s = peri::parse_scene(kStaged, "scene.yaml");
  ASSERT_EQ(s.stages.size(), 3u);
  EXPECT_EQ(s.stages[0].kind, peri::StageKind::QuasiStatic);
  ASSERT_EQ(s.stages[0].displacements.size(), 1u);
  EXPECT_EQ(s.stages[0].displacements[0].boundary, "top");
  EXPECT_DOUBLE_EQ(s.stages[0].displacements[0].value[1], 0.002);
  EXPECT_EQ(s.stages[0].load_steps, 4);
  EXPECT_TRUE(s.stages[0].in_plane);
  EXPECT_EQ(s.stages[1].kind, peri::StageKind::Release);
  EXPECT_EQ(s.stages[1].cracks, std::vector<std::string>{"slit"});
  EXPECT_TRUE(s.released_later("slit"));
  EXPECT_DOUBLE_EQ(s.stages[2].damping, 100.0);
  ASSERT_EQ(s.stages[2].boundary_velocity.size(), 1u);
  EXPECT_DOUBLE_EQ(s.stages[2].boundary_velocity[0].value[1], 1.0);
  // Round trip of the resolved form.
  const std::string once = peri::emit_scene(s);
  EXPECT_EQ(peri::emit_scene(peri::parse_scene(once, "resolved.yaml")), once);
}

TEST(SceneStages, Errors) {
  const auto staged = [](const std::string& from, const std::string& to) {
    std::string t = kStaged;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return error_of(t.replace(at, from.size(), to));
  };
  EXPECT_THAT(staged("displacements: {top:", "displacements: {tpo:"),
              StartsWith("scene.yaml:12: stages.0.displacements.tpo: no boundary named 'tpo'; defined: top, bottom"));
  EXPECT_THAT(staged("cracks: [slit]", "cracks: [slot]"),
              StartsWith("scene.yaml:13: stages.1.cracks.0: no crack named 'slot'; defined: slit"));
  EXPECT_THAT(staged("cracks: [slit]", "cracks: []"),
              StartsWith("scene.yaml:13: stages.1.cracks: expected a non-empty list of crack names"));
  EXPECT_THAT(staged("load_steps: 4", "load_steps: 4, duration: 1"),
              StartsWith("scene.yaml:12: stages.0.duration: this key belongs to dynamic stages; this stage is quasistatic"));
  EXPECT_THAT(staged("damping: 100", "damping: -1"),
              StartsWith("scene.yaml:14: stages.2.damping: expected a non-negative number [1/s], got -1"));
  EXPECT_THAT(staged("damping: 100", "damping: 100, cracks: [slit]"),
              StartsWith("scene.yaml:14: stages.2.cracks: this key belongs to release stages; this stage is dynamic"));
  EXPECT_THAT(staged("load_steps: 4", "load_steps: 4, max_load_step: 0"),
              StartsWith("scene.yaml:12: stages.0.max_load_step: expected a number in (0, 1]"));
  EXPECT_THAT(staged("load_steps: 4", "load_steps: 4, max_load_steps: 2"),
              StartsWith("scene.yaml:12: stages.0.max_load_steps: expected an integer >= load_steps (4), got 2"));
  EXPECT_THAT(staged("  - {name: run, duration: 1.0e-5, damping: 100, boundary_velocity: {top: [0, 1, 0]}}\n", ""),
              StartsWith("scene.yaml:12: stages: expected at least one stage of kind dynamic"));
  EXPECT_THAT(staged("  - {name: cut, kind: release, cracks: [slit]}\n",
                     "  - {name: cut, kind: release, cracks: [slit]}\n  - {name: again, kind: release, cracks: [slit]}\n"),
              HasSubstr("crack 'slit' is already released by stage 'cut'"));
  EXPECT_THAT(error_of(kStaged + "stability: {energy_error: -0.1}\n"),
              StartsWith("scene.yaml:15: stability.energy_error: expected a non-negative number, got -0.1"));
}

// Every name a scene gives (scene, material, body, crack, boundary, tool, stage), in the file and
// through --set: hostile names refused with the rule and the name on one line, at the line that
// gives it (or "--set"); names at the rule's edges accepted as written.
struct NameKind {
  std::string what;
  std::function<std::string(const std::string&)> file;                // scene text naming it `q` (YAML)
  std::function<std::vector<Override>(const std::string&)> set;       // overrides naming it `q`
  std::function<std::string(const Scene&)> name;                      // the name parsed
};

std::vector<NameKind> name_kinds() {
  const std::string sheet = "{material: rubber, origin: [0, 0, 0], size: [0.01, 0.01], thickness: 0.0005, spacing: 0.001}";
  return {
      {"scene", [](const std::string& q) { return with("name: test", "name: " + q); },
       [](const std::string& q) { return std::vector<Override>{{"name", q}}; },
       [](const Scene& s) { return s.name; }},
      {"material",
       [](const std::string& q) { return with("  rubber:\n", "  " + q + ":\n", with("material: rubber", "material: " + q)); },
       [](const std::string& q) {
         return std::vector<Override>{{"materials", "{" + q + ": {model: membrane, density: 1200, wave_speed: 1000}}"},
                                      {"bodies.sheet.material", q}};
       },
       [](const Scene& s) { return s.materials.at(0).name; }},
      {"body", [](const std::string& q) { return with("  sheet:\n", "  " + q + ":\n"); },
       [sheet](const std::string& q) { return std::vector<Override>{{"bodies", "{" + q + ": " + sheet + "}"}}; },
       [](const Scene& s) { return s.bodies.at(0).name; }},
      {"crack", [](const std::string& q) { return kBase + "cracks:\n  - {name: " + q + ", from: [0, 0, 0], to: [0.001, 0, 0]}\n"; },
       [](const std::string& q) {
         return std::vector<Override>{{"cracks", "[{name: " + q + ", from: [0, 0, 0], to: [0.001, 0, 0]}]"}};
       },
       [](const Scene& s) { return s.cracks.at(0).name; }},
      {"boundary",
       [](const std::string& q) { return kBase + "boundaries:\n  - {name: " + q + ", region: {min: [0, 0, 0], max: [1, 1, 1]}}\n"; },
       [](const std::string& q) {
         return std::vector<Override>{{"boundaries", "[{name: " + q + ", region: {min: [0, 0, 0], max: [1, 1, 1]}}]"}};
       },
       [](const Scene& s) { return s.boundaries.at(0).name; }},
      {"tool",
       [](const std::string& q) { return kBase + "tools:\n  - {name: " + q + ", kind: cylinder, radius: 0.001, center: [0.5, 0.5]}\n"; },
       [](const std::string& q) {
         return std::vector<Override>{{"tools", "[{name: " + q + ", kind: cylinder, radius: 0.001, center: [0.5, 0.5]}]"}};
       },
       [](const Scene& s) { return s.tools.at(0).name; }},
      {"stage", [](const std::string& q) { return with("  - duration: 1.0e-5", "  - name: " + q + "\n    duration: 1.0e-5"); },
       [](const std::string& q) { return std::vector<Override>{{"stages.0.name", q}}; },
       [](const Scene& s) { return s.stages.at(0).name; }},
  };
}

/// 1-based line of `text` holding `part` (0 if absent).
int line_holding(const std::string& text, const std::string& part) {
  const auto at = text.find(part);
  return at == std::string::npos ? 0 : 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
}

TEST(SceneNames, HostileNamesRefused) {
  // YAML double-quoted scalars: the name as written in the file and in --set values.
  const std::vector<std::string> hostile = {
      R"("a\"b")", R"("a\tb")", R"("a\\b")", R"("a,b")",  R"("a\nb")",     R"("a/b")",  R"("../../x")",
      R"("..")",   R"(".hidden")", R"("-x")", R"("a b")",  R"("a.b")",      R"("a\0b")", R"("\u00e9t\u00e9")",
      "\"" + std::string(65, 'a') + "\"", "\"" + std::string(1000, 'n') + "\"", R"("")"};
  const std::string rule = " name (1 to 64 characters of A-Z a-z 0-9 _ - not starting with -)";
  for (const NameKind& k : name_kinds()) {
    const bool key = k.what == "material" || k.what == "body";
    for (const std::string& q : hostile) {
      const std::string want = q != "\"\"" ? "expected a " + k.what + rule
                               : key       ? "expected a name as map key, got \"\""
                                           : "expected a non-empty string, got \"\"";
      const std::string text = k.file(q);
      const std::string at = "scene.yaml:" + std::to_string(line_holding(text, q + (key ? ":" : ""))) + ": ";
      const std::string in_file = error_of(text);
      EXPECT_THAT(in_file, AllOf(StartsWith(at), HasSubstr(want))) << k.what << " " << q.substr(0, 20);
      const std::string in_set = error_of(kBase, k.set(q));
      EXPECT_THAT(in_set, AllOf(StartsWith("--set: "), HasSubstr(want))) << k.what << " " << q.substr(0, 20);
      if (q.size() > 100) EXPECT_LT(in_file.size(), 300u) << "a long name is cut in the message";
    }
  }
  EXPECT_EQ(error_of(with("name: test", R"(name: "a\tb/\u00e9")")),
            "scene.yaml:1: name: expected a scene" + rule + ", got \"a\\x09b/\\xc3\\xa9\"");
  EXPECT_EQ(error_of(kBase, {{"bodies.x/y", "{material: rubber}"}}),
            "--set: bodies: expected a body" + rule + " as key, got \"x/y\"");
  EXPECT_EQ(error_of(kBase, {{"name", std::string(70, 'z')}}),
            "--set: name: expected a scene" + rule + ", got \"" + std::string(40, 'z') + "\" (70 characters)");
}

TEST(SceneNames, EdgesOfTheRuleAccepted) {
  for (const NameKind& k : name_kinds()) {
    for (const std::string& name : {std::string("a"), std::string("Z"), std::string("0"), std::string("_"),
                                    std::string("a-b_C9-"), std::string("true"), std::string(64, 'x')}) {
      const std::string q = "\"" + name + "\"";
      try {
        EXPECT_EQ(k.name(peri::parse_scene(k.file(q), "scene.yaml")), name) << k.what;
        EXPECT_EQ(k.name(peri::parse_scene(kBase, "scene.yaml", k.set(q))), name) << k.what;
      } catch (const InputError& e) {
        ADD_FAILURE() << k.what << " " << name << ": " << e.what();
      }
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Extreme values refused where they are read (the derived ones at setup: bad_values.sh)

TEST(SceneLimits, SubnormalAndUnderflowingNumbers) {
  const std::string expected = "expected 0 or a number of magnitude at least 2.2e-308 (the smallest normal double), got ";
  EXPECT_EQ(error_of(with("density: 1200", "density: 1e-310")), "scene.yaml:5: materials.rubber.density: " + expected + "1e-310");
  EXPECT_EQ(error_of(with("density: 1200", "density: 4.9e-324")), "scene.yaml:5: materials.rubber.density: " + expected + "4.9e-324");
  EXPECT_EQ(error_of(with("density: 1200", "density: 1e-400")), "scene.yaml:5: materials.rubber.density: " + expected + "1e-400");
  EXPECT_EQ(error_of(with("origin: [0, 0, 0]", "origin: [0, -2e-320, 0]")),
            "scene.yaml:10: bodies.sheet.origin.1: " + expected + "-2e-320");
  EXPECT_EQ(error_of(kBase, {{"stages.0.dt", "1e-309"}}), "--set: stages.0.dt: " + expected + "1e-309");
  // The smallest normal double itself, and 0 where 0 is allowed, are read.
  EXPECT_EQ(peri::parse_scene(with("density: 1200", "density: 2.2250738585072014e-308"), "scene.yaml").materials[0].density,
            2.2250738585072014e-308);
  EXPECT_EQ(peri::parse_scene(with("origin: [0, 0, 0]", "origin: [0, -0.0, 0]"), "scene.yaml").bodies[0].origin[1], 0.0);
}

TEST(SceneLimits, StepsAreBoundedAndExcludeDuration) {
  EXPECT_THAT(error_of(with("  - duration: 1.0e-5", "  - steps: 1000000001")),
              StartsWith("scene.yaml:15: stages.0.steps: expected an integer >= 1 and <= 1000000000, got 1000000001"));
  EXPECT_EQ(peri::parse_scene(with("  - duration: 1.0e-5", "  - steps: 1e9"), "scene.yaml").stages[0].steps, 1000000000);
  // Both in the file (either order): refused at the duration, naming the stage and both values.
  EXPECT_EQ(error_of(with("  - duration: 1.0e-5", "  - duration: 1.0e-5\n    steps: 20")),
            "scene.yaml:15: stages.0.duration: give either duration or steps, not both (stage 'stage0' has steps: 20 "
            "and duration: 1.0e-5)");
  EXPECT_EQ(error_of(with("  - duration: 1.0e-5", "  - {name: pull, steps: 20, duration: 2e-5}")),
            "scene.yaml:15: stages.0.duration: give either duration or steps, not both (stage 'pull' has steps: 20 "
            "and duration: 2e-5)");
  // An override of one replaces the other the file gave, and is read back from the resolved text.
  const Scene by_steps = peri::parse_scene(kBase, "scene.yaml", {{"stages.0.steps", "20"}});
  EXPECT_EQ(by_steps.stages[0].steps, 20);
  EXPECT_EQ(by_steps.stages[0].duration, 0.0);
  EXPECT_EQ(peri::parse_scene(peri::emit_scene(by_steps), "resolved.yaml").stages[0].steps, 20);
  const Scene by_duration =
      peri::parse_scene(with("  - duration: 1.0e-5", "  - steps: 20"), "scene.yaml", {{"stages.0.duration", "3e-5"}});
  EXPECT_FALSE(by_duration.stages[0].steps);
  EXPECT_EQ(by_duration.stages[0].duration, 3e-5);
  // Both by overrides: refused (the later one names the earlier).
  EXPECT_EQ(error_of(kBase, {{"stages.0.steps", "20"}, {"stages.0.duration", "3e-5"}}),
            "--set: stages.0.duration: give either duration or steps, not both (stage 'stage0' has steps: 20 and "
            "duration: 3e-5)");
  // An emptied key does not remove the other.
  EXPECT_EQ(peri::parse_scene(kBase, "scene.yaml", {{"stages.0.steps", "~"}}).stages[0].duration, 1.0e-5);
}

TEST(SceneLimits, CriticalStretchAboveTheResolutionOfBondLengths) {
  const std::string pmb = with("model: membrane", "model: pmb");
  EXPECT_EQ(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: 1.00000000001")),
            "scene.yaml:7: materials.rubber.critical_stretch: expected a critical stretch lambda_0 >= 1 + 1e-10 (a "
            "smaller failure strain is below the resolution of reference bond lengths and breaks bonds at rest), got "
            "1.00000000001");
  EXPECT_THAT(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: 1e-300", pmb)),
              StartsWith("scene.yaml:7: materials.rubber.critical_stretch: expected a critical bond strain s_0 >= 1e-10"));
  EXPECT_THAT(error_of(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: 0.1\n    critical_stretch_at_horizon: 1e-11", pmb)),
              StartsWith("scene.yaml:8: materials.rubber.critical_stretch_at_horizon: expected a critical bond strain s_0 >= 1e-10"));
  EXPECT_EQ(peri::parse_scene(with("wave_speed: 1000", "wave_speed: 1000\n    critical_stretch: 1e-10", pmb), "scene.yaml")
                .materials[0].critical_stretch, 1e-10);
}

TEST(SceneLimits, ToolStiffness) {
  const std::string tools = kBase + "tools:\n  - {name: rod, kind: cylinder, radius: 0.001, center: [-0.002, 0.005], stiffness: 1e300}\n";
  EXPECT_EQ(error_of(tools), "scene.yaml:17: tools.0.stiffness: expected a number in (0, 1e6], got 1e300");
  EXPECT_EQ(error_of(tools, {{"tools.rod.stiffness", "0"}}), "--set: tools.0.stiffness: expected a number in (0, 1e6], got 0");
  EXPECT_EQ(peri::parse_scene(tools, "scene.yaml", {{"tools.rod.stiffness", "1e6"}}).tools[0].stiffness, 1e6);
}

TEST(SceneLimits, ValuesAreCountedBeforeTheDocumentIsKept) {
  // 100,000 cracks of 11 values each: refused at the line where the count passes 1,000,000,
  // naming the top-level key being read.
  std::string text = kBase + "cracks:\n";
  for (int k = 0; k < 100000; ++k) text += "  - {from: [0, 0, 0], to: [" + std::to_string(k + 1) + ", 0, 0]}\n";
  const std::string msg = error_of(text);
  EXPECT_EQ(msg, "scene.yaml:90922: cracks: the scene holds more than 1000000 YAML values (numbers, strings, lists, maps) "
                 "by this line; expected at most 1000000 (about 90000 cracks written as {from: [x, y, z], to: [x, y, z]})");
  // 90,000 are read.
  text = kBase + "cracks:\n";
  for (int k = 0; k < 90000; ++k) text += "  - {from: [0, 0, 0], to: [" + std::to_string(k + 1) + ", 0, 0]}\n";
  EXPECT_EQ(peri::parse_scene(text, "scene.yaml").cracks.size(), 90000u);
}

TEST(SceneLimits, AliasesCountAsTheValuesTheyStandFor) {
  // A polygon of 1000 corners (a crack of 4003 values: its map, the key, the list, 1000 lists of
  // 3) given once with an anchor, then 400 cracks that are aliases of it: 1.6 million values once
  // expanded, in a text of 20 kB. Refused at the alias where the count passes 1,000,000 (an alias
  // counted as one value let 3000 such cracks through, 48 million values, 3 GB).
  std::string polygon = "[";
  for (int k = 0; k < 1000; ++k) polygon += (k ? ", [" : "[") + std::to_string(k) + ", 0, " + std::to_string(k % 7) + "]";
  polygon += "]";
  std::string text = kBase + "cracks:\n  - &p {polygon: " + polygon + "}\n";
  for (int k = 0; k < 400; ++k) text += "  - *p\n";
  // kBase's 15 lines and 37 values, "cracks:" (2 values: the key and the list), the anchored
  // crack on line 17, then alias n on line 17 + n.
  const int aliases = (1000000 - (37 + 2 + 4003)) / 4003 + 1;
  const int line = 17 + aliases;
  EXPECT_EQ(error_of(text), "scene.yaml:" + std::to_string(line) +
                                ": cracks: the scene holds more than 1000000 YAML values (numbers, strings, lists, maps) "
                                "by this line; expected at most 1000000 (about 90000 cracks written as {from: [x, y, "
                                "z], to: [x, y, z]})");
}

TEST(SceneLimits, OverrideWithTextAfterItsValue) {
  // yaml-cpp reads the first value and drops the rest; the scene file refuses the same text.
  EXPECT_EQ(error_of(kBase, {{"bodies.sheet.origin", "[0, 0, 0] [1, 1, 1]"}}),
            "--set bodies.sheet.origin=[0, 0, 0] [1, 1, 1]: text after the value; expected one YAML value (a value "
            "that starts with a quote or a bracket ends where it closes: to give the whole text as a string, wrap it "
            "in quotes of the other kind)");
  EXPECT_THAT(error_of(kBase, {{"description", "\"abc\" junk"}}),
              StartsWith("--set description=\"abc\" junk: text after the value"));
  EXPECT_EQ(peri::parse_scene(kBase, "scene.yaml", {{"description", "'\"abc\" junk'"}}).description, "\"abc\" junk");
  EXPECT_EQ(peri::parse_scene(kBase, "scene.yaml", {{"description", "abc junk"}}).description, "abc junk");
}

TEST(SceneLimits, TextThatIsNotUtf8) {
  // Invalid bytes (a lone lead byte, an overlong form, a surrogate) in the file or a --set value.
  EXPECT_EQ(error_of(kBase + "description: \"ok\xc3\x28\"\n"),
            "scene.yaml:16: the byte 0xC3 at offset " + std::to_string(kBase.size() + 16) +
                " is not UTF-8 text; expected a scene in UTF-8");
  EXPECT_THAT(error_of(kBase + "description: \"\xc0\xaf\"\n"), StartsWith("scene.yaml:16: the byte 0xC0"));
  EXPECT_THAT(error_of(kBase + "description: \"\xed\xa0\x80\"\n"), StartsWith("scene.yaml:16: the byte 0xED"));
  EXPECT_THAT(error_of("\xff\xfe" + kBase), HasSubstr("(the file starts with a UTF-16 byte order mark: save it as UTF-8)"));
  EXPECT_EQ(error_of(kBase, {{"description", "ok\xc3\x28"}}),
            "--set description=ok\xc3\x28: the value is not UTF-8 text; expected UTF-8");
  // Well-formed UTF-8 of 2, 3 and 4 bytes is read.
  EXPECT_EQ(peri::parse_scene(kBase + "description: \"\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80\"\n", "scene.yaml").description,
            "\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");
}

TEST(SceneLimits, ReadingStopsWhenAsked) {
  // The stop check is asked before each 64 KiB of text: a long scene is abandoned mid-way.
  std::string text = kBase + "cracks:\n";
  for (int k = 0; k < 20000; ++k) text += "  - {from: [0, 0, 0], to: [" + std::to_string(k + 1) + ", 0, 0]}\n";
  int asked = 0;
  try {
    peri::parse_scene(text, "scene.yaml", {}, [&] { return ++asked == 3; });
    ADD_FAILURE() << "the reading went on after the stop request";
  } catch (const peri::StopRequested& e) {
    EXPECT_EQ(std::string(e.what()), "stopped while reading the scene");
  }
  EXPECT_EQ(asked, 3);
  // Never asked to stop: the same text is read whole.
  EXPECT_EQ(peri::parse_scene(text, "scene.yaml", {}, [] { return false; }).cracks.size(), 20000u);
}
