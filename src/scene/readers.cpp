// The readers of the scene's sections (readers.hpp): one function per map of the schema, each
// value validated where it is read; checks that need several sections last (read_scene).
#include "readers.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

#include "peri/scene/models.hpp"
#include "schema.hpp"

namespace peri::scene_detail {
namespace {

// ------------------------------------------------------------------------------------------------
// Reading the sections

/// Keeps the names of a list's entries unique.
class UniqueNames {
 public:
  explicit UniqueNames(std::string what) : what_(std::move(what)) {}
  const std::string& what() const { return what_; }

  /// `name_value`: the entry's name key if given (the error is reported there), else the entry.
  void add(const std::string& name, const std::optional<Value>& name_value, const Map& entry) {
    const auto it = first_.find(name);
    if (it == first_.end()) {
      first_.emplace(name, entry.path());
      return;
    }
    const std::string msg = "duplicate " + what_ + " name '" + name + "' (also used by " + it->second + ")";
    if (name_value) name_value->fail(msg);
    entry.fail(msg + "; give this entry a name");
  }

 private:
  std::string what_;
  std::map<std::string, std::string> first_;
};

/// Name of a list entry: its `name` key, or "<prefix><index>" when the entry has none (an empty
/// prefix: the name is required).
std::string entry_name(const Map& m, const std::string& prefix, std::size_t index, UniqueNames& names) {
  const std::optional<Value> v = prefix.empty() ? std::optional<Value>(m.at("name")) : m.get("name");
  const std::string name = v ? v->given_name(names.what()) : prefix + std::to_string(index);
  names.add(name, v, m);
  return name;
}

/// Entries of an optional list section (absent or empty value: no entries).
std::vector<Value> optional_list(const Map& top, const std::string& key, const std::string& expected) {
  const std::optional<Value> v = top.get(key);
  return v ? v->list(expected) : std::vector<Value>{};
}

// A critical value (critical_stretch, critical_stretch_at_horizon), as the model checks it.
double critical_value(const Value& v, const MaterialModel& model) {
  const double x = v.number("a number");
  if (model.critical_problem)
    if (const std::string problem = model.critical_problem(x); !problem.empty()) v.fail(problem + ", got " + v.got());
  return x;
}

/// The marder model's keys: its four constants (no peridynamic stiffness, influence, failure
/// stretch or hardening), and the breaking mode.
Material read_marder_material(const Map& m, Material mat) {
  for (const char* key : {"wave_speed", "bulk_modulus", "youngs_modulus", "micromodulus", "influence",
                          "critical_stretch", "critical_stretch_at_horizon", "hardening", "tip_advance",
                          "tip_advance_tips"})
    if (auto x = m.get(key))
      x->fail("not used by the marder model (its stiffness is mooney_rivlin_a, mooney_rivlin_b; its failure "
              "fracture_separation)");
  for (const char* key : {"mooney_rivlin_a", "mooney_rivlin_b", "cutoff", "fracture_separation"})
    if (!m.given(key)) m.missing(key, "required by the marder model");
  MarderParams p;
  p.a = m.at("mooney_rivlin_a").positive("J/kg");
  p.b = m.at("mooney_rivlin_b").number("a number");
  p.cutoff = m.at("cutoff").positive("m");
  p.fracture_separation = m.at("fracture_separation").positive("m");
  if (auto x = m.get("breaking"))
    p.reversible = x->choice<bool>({{"irreversible", false}, {"reversible", true}});
  if (auto x = m.get("kelvin_viscosity")) p.options.kelvin_viscosity = x->non_negative("m^2/s");
  const auto onset = m.get("stiffening_onset"), width = m.get("stiffening_width");
  if (onset && !width) m.missing("stiffening_width", "given with stiffening_onset");
  if (width && !onset) m.missing("stiffening_onset", "given with stiffening_width");
  if (onset) {
    p.options.stiffening_onset = onset->positive("m");
    p.options.stiffening_width = width->positive("m");
  }
  if (auto x = m.get("break_separation")) p.options.break_separation = x->positive("m");
  mat.marder = p;
  return mat;
}

Material read_material(const std::string& name, const Value& v) {
  const Map m(v, &kMaterialKeys, "a map describing the material");
  Material mat;
  mat.name = name;
  mat.where = m.where();
  const Value model = m.at("model");
  const std::optional<std::string> word = model.word();
  const MaterialModel* info = word ? find_material_model(*word) : nullptr;
  if (!info) model.fail("expected one of: " + join(material_model_names()) + "; got " + model.got());
  mat.model = info->name;
  mat.density = m.at("density").positive("kg/m^3");
  if (info->lattice) return read_marder_material(m, std::move(mat));
  for (const char* key : kMarderKeys)
    if (auto x = m.get(key)) x->fail("only the marder model takes this key (model is " + mat.model + ")");
  for (const char* key :
       {"influence", "critical_stretch", "critical_stretch_at_horizon", "hardening", "tip_advance", "tip_advance_tips"})
    if (auto x = m.get(key); x && std::find(info->keys.begin(), info->keys.end(), key) == info->keys.end()) {
      std::vector<std::string> takers;
      for (const std::string& name : material_model_names())
        if (const MaterialModel* other = find_material_model(name);
            std::find(other->keys.begin(), other->keys.end(), key) != other->keys.end())
          takers.push_back(name);
      x->fail(std::string(key) + " is available only for the " + join(takers) + " model" +
              (takers.size() > 1 ? "s" : "") + ", not for " + mat.model);
    }

  int stiffness_given = 0;
  for (const char* key : kStiffnessKeys) stiffness_given += m.given(key) ? 1 : 0;
  if (stiffness_given != 1) {
    m.fail("give exactly one of " +
               join({kStiffnessKeys[0], kStiffnessKeys[1], kStiffnessKeys[2], kStiffnessKeys[3]}) +
               " (found " + std::to_string(stiffness_given) + ")",
           {kStiffnessKeys[0], kStiffnessKeys[1], kStiffnessKeys[2], kStiffnessKeys[3]});
  }
  for (const char* key : kStiffnessKeys)
    if (auto x = m.get(key); x && std::find(info->stiffness.begin(), info->stiffness.end(), key) == info->stiffness.end())
      x->fail("the " + mat.model + " model calibrates from " + join(info->stiffness) + ", not from " + key);
  if (auto x = m.get("wave_speed")) mat.wave_speed = x->positive("m/s");
  if (auto x = m.get("bulk_modulus")) mat.bulk_modulus = x->positive("Pa");
  if (auto x = m.get("youngs_modulus")) mat.youngs_modulus = x->positive("Pa");
  if (auto x = m.get("micromodulus")) mat.micromodulus = x->positive("");

  if (auto x = m.get("influence"))
    mat.influence =
        x->choice<Influence>({{"constant", Influence::Constant}, {"conical", Influence::Conical}});
  if (auto x = m.get("critical_stretch")) mat.critical_stretch = critical_value(*x, *info);
  if (auto x = m.get("critical_stretch_at_horizon")) {
    if (!mat.critical_stretch) x->fail("requires critical_stretch (the critical value at |xi| = 0)");
    mat.critical_stretch_at_horizon = critical_value(*x, *info);
  }
  if (auto x = m.get("tip_advance")) {
    if (!mat.critical_stretch) x->fail("requires critical_stretch (without failure no crack tip advances)");
    mat.tip_advance = x->positive("m");
  }
  if (auto x = m.get("tip_advance_tips")) {
    if (!mat.tip_advance) x->fail("requires tip_advance (the rule whose crack tips it chooses)");
    mat.tip_advance_tips = x->choice<TipScope>({{"family", TipScope::Family}, {"body", TipScope::Body}});
  }
  if (auto x = m.get("kelvin_viscosity")) mat.kelvin_viscosity = x->non_negative("m^2/s");
  if (auto x = m.get("hardening")) {
    const Map h(*x, &kHardeningKeys, "a map {coefficient: c, exponent: n}");
    Hardening hard;
    hard.coefficient = h.at("coefficient").non_negative("");
    // (lambda^n overflows a double at lambda = 2 from n = 1024; 0 * inf made the forces NaN)
    hard.exponent = h.at("exponent").number_if("a number in (1, 100]", [](double n) { return n > 1 && n <= 100; });
    mat.hardening = hard;
  }
  return mat;
}

// A polygon crack's corners: at least three, each different from the one before, within 1e100 m,
// in one plane (to 1e-9 of the polygon's size), convex and simple (one turn direction at every
// corner, once around), enclosing an area. Sets the crack's mean plane for crosses()' filter.
void read_crack_polygon(const Value& list, Crack& c) {
  const std::string expected = "a list of at least 3 corners [[x, y, z], ...] [m] of a convex plane polygon";
  const std::vector<Value> items = list.list(expected);
  if (items.size() < 3) list.fail("expected " + expected + ", got " + list.got());
  for (std::size_t k = 0; k < items.size(); ++k) {
    c.polygon.push_back(items[k].vec3("m"));
    if (k > 0 && c.polygon[k] == c.polygon[k - 1])
      items[k].fail("expected a corner different from the one before it, got " + items[k].got());
  }
  const std::size_t n = c.polygon.size();
  if (n > 2 && c.polygon[n - 1] == c.polygon[0])
    items[n - 1].fail("the same corner as the first; expected each corner once (the polygon closes from its last "
                      "corner to its first by itself)");
  for (std::size_t k = 0; k < n; ++k)
    for (double x : c.polygon[k])
      if (!(std::fabs(x) < 1e100)) items[k].fail("expected a corner within 1e100 m of the origin, got " + items[k].got());
  auto minus = [](const Vec3& a, const Vec3& b) { return Vec3{a[0] - b[0], a[1] - b[1], a[2] - b[2]}; };
  auto cross = [](const Vec3& a, const Vec3& b) {
    return Vec3{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  };
  auto dot = [](const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  // The corners relative to the first, in units of the bounding box's diagonal: O(1) numbers at
  // any scale.
  Vec3 lo = c.polygon[0], hi = c.polygon[0];
  for (const Vec3& x : c.polygon)
    for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], x[d]), hi[d] = std::max(hi[d], x[d]);
  const double size = std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  std::vector<Vec3> p(n);
  for (std::size_t k = 0; k < n; ++k)
    for (int d = 0; d < 3; ++d) p[k][d] = (c.polygon[k][d] - c.polygon[0][d]) / size;
  // Newell's normal (twice the vector area) and the corners' mean.
  Vec3 normal{0, 0, 0}, centre{0, 0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 e = cross(p[i], p[(i + 1) % n]);
    for (int d = 0; d < 3; ++d) normal[d] += e[d], centre[d] += p[i][d] / static_cast<double>(n);
  }
  const std::string crossing = "expected a polygon that encloses an area, its corners in order, got corners on one "
                               "line or edges that cross (" + list.got() + ")";
  const double area2 = std::sqrt(dot(normal, normal));
  if (!(area2 > 1e-12)) list.fail(crossing);
  for (double& x : normal) x /= area2;
  for (std::size_t i = 0; i < n; ++i) {
    const double off = dot(minus(p[i], centre), normal);
    if (!(std::fabs(off) <= 1e-9))
      items[i].fail("expected the corners in one plane (to 1e-9 of the polygon's size), got this corner " +
                    format_number(std::fabs(off) * size) + " m off the corners' mean plane");
  }
  // Convex and simple: it turns one way (about the normal) at every corner, and once around.
  double turning = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 e0 = minus(p[(i + 1) % n], p[i]), e1 = minus(p[(i + 2) % n], p[(i + 1) % n]);
    const double turn = dot(cross(e0, e1), normal);
    if (turn < -1e-9 * std::sqrt(dot(e0, e0) * dot(e1, e1)))
      items[(i + 1) % n].fail("expected a convex polygon with its corners in order, got a turn the other way at "
                              "this corner; give a non-convex cut as several convex polygons");
    turning += std::atan2(turn, dot(e0, e1));
  }
  if (!(std::fabs(turning - 2 * M_PI) < 1e-6)) list.fail(crossing);
  // The mean plane: every corner within 1e-9 size of it (above), so every point of the fan too.
  c.plane_normal = normal;
  c.plane_offset = 0;
  for (int d = 0; d < 3; ++d) c.plane_offset += normal[d] * (c.polygon[0][d] + centre[d] * size);
  c.plane_tolerance = 2e-9 * size;
  // The fan's wedges about the first corner: the corners' angles from the second one, rising
  // (the corners turn about the normal) from 0 to the angle at the first corner, at most pi (and
  // round-off; kept in [-pi/2, 3pi/2)). A corner may turn back by round-off; the bounds stay
  // monotone (a running minimum from the end, a running maximum from the start).
  if (n < kFanSearchCorners) return;
  Vec3 u = p[1];
  const double along = dot(u, normal);
  for (int d = 0; d < 3; ++d) u[d] -= along * normal[d];
  const double length = std::sqrt(dot(u, u));
  for (double& x : u) x /= length;
  c.fan_u = u;
  c.fan_v = cross(normal, u);
  std::vector<double> angle(n);
  for (std::size_t k = 1; k < n; ++k) {
    angle[k] = std::atan2(dot(p[k], c.fan_v), dot(p[k], u));
    if (angle[k] < -M_PI / 2) angle[k] += 2 * M_PI;
  }
  const std::size_t fan = n - 2;
  c.fan_low.resize(fan);
  c.fan_high.resize(fan);
  for (std::size_t k = 0; k < fan; ++k) {
    const double high = std::max(angle[k + 1], angle[k + 2]);
    c.fan_high[k] = k > 0 ? std::max(c.fan_high[k - 1], high) : high;
  }
  for (std::size_t k = fan; k-- > 0;) {
    const double low = std::min(angle[k + 1], angle[k + 2]);
    c.fan_low[k] = k + 1 < fan ? std::min(c.fan_low[k + 1], low) : low;
  }
}

Crack read_crack(const Value& v, std::size_t index, UniqueNames& names) {
  const Map m(v, &kCrackKeys,
              "a map {name, from: [x, y, z], to: [x, y, z]} (a slit) or {name, polygon: [[x, y, z], ...]}");
  Crack c;
  c.name = entry_name(m, "crack", index, names);
  c.where = m.where();
  if (auto polygon = m.get("polygon")) {
    for (const char* key : {"from", "to"})
      if (auto y = m.get(key)) y->fail("not with polygon: a crack is a slit (from, to) or a polygon");
    read_crack_polygon(*polygon, c);
    return c;
  }
  if (!m.given("from")) m.missing("from", "one end [x, y, z], m; or polygon");
  if (!m.given("to")) m.missing("to", "the other end [x, y, z], m; or polygon");
  c.from = m.at("from").vec3("m");
  const Value to = m.at("to");
  c.to = to.vec3("m");
  if (c.to == c.from) to.fail("a crack needs two different end points, got to == from");
  return c;
}

// A point cloud's material column splits the file among the bodies that read it, one body per
// material: every material it names is some such body's, or the rows would be lost unseen.
void check_point_cloud_materials(const std::vector<Body>& bodies) {
  // One file under two names (a link, `a/../b.csv`) is one file.
  auto same_file = [](const std::string& a, const std::string& b) {
    std::error_code ec;
    return a == b || (!a.empty() && !b.empty() && std::filesystem::equivalent(a, b, ec) && !ec);
  };
  for (const Body& b : bodies)
    for (const auto& [material, place] : b.cloud_materials) {
      std::vector<std::string> readers;
      bool taken = false;
      for (const Body& other : bodies)
        if (same_file(other.points, b.points)) {
          readers.push_back(other.name + " (" + other.material + ")");
          taken = taken || other.material == material;
        }
      if (!taken)
        throw InputError(place + ": bodies." + b.name + ".points: material '" +
                         material + "' is no body's: the bodies that read this file are " + join(readers) +
                         "; expected one body with points: this file and material: " + material +
                         " for each material of the file");
    }
}

Region read_region(const Value& v, const std::vector<Body>& bodies) {
  const Map m(v, &kRegionKeys, "a box {min: [x, y, z], max: [x, y, z]} or a mesh's group {body: name, group: name}");
  Region r;
  r.where = m.where();
  const std::optional<Value> group = m.get("group");
  if (!group) {
    if (!m.given("min")) m.missing("min", "lower corner [x, y, z], m; or group");
    if (!m.given("max")) m.missing("max", "upper corner [x, y, z], m; or group");
    r.min = m.at("min").vec3("m");
    const Value max = m.at("max");
    r.max = max.vec3("m");
    for (int d = 0; d < 3; ++d) {
      if (r.min[d] > r.max[d]) {
        max.fail(std::string("expected min <= max in every component, got ") + "xyz"[d] + ": min " +
                 format_number(r.min[d]) + " > max " + format_number(r.max[d]));
      }
    }
  } else {
    for (const char* key : {"min", "max"})
      if (auto y = m.get(key)) y->fail("not with group: the region is the group's nodes");
    if (!m.given("body")) m.missing("body", "the mesh body whose physical group this is");
  }
  const Body* body = nullptr;
  if (auto x = m.get("body")) {
    r.body = x->name();
    const auto it = std::find_if(bodies.begin(), bodies.end(), [&](const Body& b) { return b.name == r.body; });
    if (it == bodies.end()) {
      std::vector<std::string> defined;
      for (const Body& b : bodies) defined.push_back(b.name);
      x->fail("no body named '" + r.body + "'; defined: " + join(defined));
    }
    body = &*it;
  }
  if (group) {  // a physical group of a mesh body's file
    r.group = group->name();
    if (!body->mesh_data)
      group->fail("body '" + r.body + "' is not read from a mesh file; a group names a physical group of a mesh body");
    const MeshData& mesh = *body->mesh_data;
    const MeshGroup* g = mesh.group(r.group);
    if (!g) {
      std::vector<std::string> names;
      for (const MeshGroup& h : mesh.groups) names.push_back("'" + h.name + "'");
      group->fail("the mesh '" + body->mesh + "' has no physical group named '" + r.group + "'; its named groups: " +
                  (names.empty() ? std::string("none") : join(names)));
    }
    if (g->nodes.empty())
      group->fail("physical group '" + r.group + "' of the mesh '" + body->mesh +
                  "' holds no node of the body (none of its nodes belongs to a " +
                  (mesh.tets.empty() ? "triangle" : "tetrahedron") + ")");
  }
  return r;
}

std::array<bool, 3> read_components(const Value& v) {
  const std::string expected = "a non-empty list of distinct letters from x, y, z";
  const std::vector<Value> items = v.list(expected);
  if (items.empty()) v.fail("expected " + expected + ", got " + v.got());
  std::array<bool, 3> on{false, false, false};
  for (const Value& item : items) {
    const int d = item.choice<int>({{"x", 0}, {"y", 1}, {"z", 2}});
    if (on[d]) item.fail("component '" + item.node().Scalar() + "' is given twice; expected " + expected);
    on[d] = true;
  }
  return on;
}

/// A boundary's value (velocity, a stage's displacement or velocity) is prescribed only in the
/// boundary's components: a nonzero value in another did nothing, and is refused.
void check_prescribed(const Value& v, const Boundary& b, const Vec3& value) {
  static const char* const axis[3] = {"x", "y", "z"};
  std::vector<std::string> held;
  for (int d = 0; d < 3; ++d)
    if (b.components[d]) held.push_back(axis[d]);
  for (int d = 0; d < 3; ++d)
    if (!b.components[d] && value[d] != 0)
      v.fail("the " + std::string(axis[d]) + " component " + format_number(value[d]) + " is not prescribed: boundary '" +
             b.name + "' holds components [" + join(held) + "] (boundaries." + b.name +
             ".components); expected 0 there, or the component among them");
}

Boundary read_boundary(const Value& v, UniqueNames& names, const std::vector<Body>& bodies) {
  const Map m(v, &kBoundaryKeys, "a map {name, region, velocity, components, ramp_time}");
  Boundary b;
  b.name = entry_name(m, "", 0, names);
  b.where = m.where();
  b.region = read_region(m.at("region"), bodies);
  if (auto x = m.get("components")) b.components = read_components(*x);
  if (auto x = m.get("velocity")) {
    b.velocity = x->vec3("m/s");
    check_prescribed(*x, b, b.velocity);
  }
  if (auto x = m.get("ramp_time")) b.ramp_time = x->non_negative("s");
  return b;
}

Tool read_tool(const Value& v, UniqueNames& names) {
  const Map m(v, &kToolKeys, "a map {name, kind, radius, center, velocity, friction, stiffness, mass}");
  Tool t;
  t.name = entry_name(m, "", 0, names);
  t.where = m.where();
  t.sphere = m.at("kind").choice<bool>({{"cylinder", false}, {"sphere", true}});
  t.radius = m.at("radius").positive("m");
  if (t.sphere) {
    t.center = m.at("center").vec3("m");
    if (auto x = m.get("velocity")) t.velocity = x->vec3("m/s");
  } else {
    const auto c = m.at("center").vec2("m");
    t.center = {c[0], c[1], 0.0};
    if (auto x = m.get("velocity")) {
      const auto u = x->vec2("m/s");
      t.velocity = {u[0], u[1], 0.0};
    }
  }
  if (auto x = m.get("friction")) t.friction = x->non_negative("");
  // The stable step shrinks by sqrt(1 + stiffness): 1e6 already makes it a thousandth.
  if (auto x = m.get("stiffness"))
    t.stiffness = x->number_if("a number in (0, 1e6]", [](double k) { return k > 0 && k <= 1e6; });
  // Its kinetic energy is booked each step: beyond 1e30 kg (Earth: 6e24) it overflows the energy sums.
  if (auto x = m.get("mass"))
    t.mass = x->number_if("a mass in (0, 1e30] kg", [](double mass) { return mass > 0 && mass <= 1e30; });
  return t;
}

Initial read_initial(const Value& v) {
  const Map m(v, &kInitialKeys, "a map {displacement_gradient, velocity_gradient, center, seed}");
  Initial init;
  if (auto x = m.get("displacement_gradient")) {
    init.displacement_gradient = x->matrix3("");
    init.gradient_where = x->where();
  }
  if (auto x = m.get("velocity_gradient")) init.velocity_gradient = x->matrix3("1/s");
  if (auto x = m.get("center")) init.center = x->vec3("m");
  if (auto x = m.get("seed")) {
    const Map seed(*x, &kSeedKeys, "a map {amplitude: A, wavelength: [Lx, Ly]}");
    init.seed_amplitude = seed.at("amplitude").non_negative("m");
    init.seed_where = seed.at("amplitude").where();
    if (auto w = seed.get("wavelength")) {
      const std::string expected = "a list of 2 non-negative numbers [Lx, Ly] [m]";
      const auto xs = w->numbers(2, 2, expected, "m");
      if (!(xs[0] >= 0 && xs[1] >= 0))
        w->fail("expected " + expected + ", got [" + join({format_number(xs[0]), format_number(xs[1])}) +
                "]");
      init.seed_wavelength_x = xs[0];
      init.seed_wavelength_y = xs[1];
    }
  }
  return init;
}

/// {boundary name: [x, y, z]} with every name an entry of `boundaries`.
std::vector<BoundaryValue> read_boundary_values(const Value& v, const std::vector<Boundary>& boundaries,
                                                std::string_view unit) {
  const Map m(v, nullptr, "a map of boundary name to [x, y, z]");
  std::vector<BoundaryValue> out;
  for (const auto& [name, value] : m.items()) {
    const Boundary* named = nullptr;
    for (const Boundary& b : boundaries)
      if (b.name == name) named = &b;
    if (!named) {
      std::vector<std::string> defined;
      for (const Boundary& b : boundaries) defined.push_back(b.name);
      value.fail("no boundary named '" + name + "'; defined: " + (defined.empty() ? "none" : join(defined)));
    }
    out.push_back({name, value.vec3(unit)});
    check_prescribed(value, *named, out.back().value);
  }
  return out;
}

Stage read_stage(const Value& v, std::size_t index, UniqueNames& names, const std::vector<Boundary>& boundaries,
                 const std::vector<Crack>& cracks) {
  const Map m(v, &kStageKeys, "a map describing the stage");
  Stage s;
  s.name = entry_name(m, "stage", index, names);
  s.where = m.where();
  if (auto x = m.get("kind"))
    s.kind = x->choice<StageKind>({{"dynamic", StageKind::Dynamic},
                                   {"quasistatic", StageKind::QuasiStatic},
                                   {"release", StageKind::Release}});
  for (const auto& [key, kind] : kStageKeyKind)
    if (kind != s.kind)
      if (auto x = m.get(key))
        x->fail(std::string("this key belongs to ") + to_text(kind) + " stages; this stage is " + to_text(s.kind));
  if (s.kind == StageKind::QuasiStatic) {
    if (auto x = m.get("displacements")) s.displacements = read_boundary_values(*x, boundaries, "m");
    if (auto x = m.get("displacement_gradient")) s.displacement_gradient = x->matrix3("");
    if (auto x = m.get("load_steps")) s.load_steps = x->integer(1, 1000000);
    if (auto x = m.get("max_load_steps")) s.max_load_steps = x->integer(1, 100000000);
    if (s.max_load_steps < s.load_steps)
      m.at("max_load_steps").fail("expected an integer >= load_steps (" + std::to_string(s.load_steps) + "), got " +
                                  std::to_string(s.max_load_steps));
    if (auto x = m.get("max_load_step")) {
      s.max_load_step = x->number_if("a number in (0, 1]", [](double f) { return f > 0 && f <= 1; });
      // Increments of at most max_load_step reach the full load in ceil(1 / max_load_step), which
      // max_load_steps (cut-backs included) must allow.
      const double needed = std::ceil(1.0 / s.max_load_step - 1e-9);
      if (needed > static_cast<double>(s.max_load_steps))
        x->fail("increments of at most " + x->got() + " of the load need " + format_number(needed) +
                " increments to reach it, more than max_load_steps (" + std::to_string(s.max_load_steps) +
                "); expected max_load_step at least " + format_number(1.0 / static_cast<double>(s.max_load_steps)) +
                ", or a larger max_load_steps");
    }
    if (auto x = m.get("in_plane")) s.in_plane = x->boolean();
    if (auto x = m.get("jacobian"))
      s.jacobian = x->choice<Stage::Jacobian>({{"assembled", Stage::Jacobian::Assembled},
                                               {"mf_operator", Stage::Jacobian::MfOperator},
                                               {"matrix_free", Stage::Jacobian::MatrixFree}});
    if (auto x = m.get("jacobian_shift"))
      s.jacobian_shift = x->number_if("a number in [0, 1)", [](double f) { return f >= 0 && f < 1; });
    if (auto x = m.get("prescribed"))
      s.prescribed = x->choice<Stage::Prescribed>(
          {{"eliminated", Stage::Prescribed::Eliminated}, {"scaled_rows", Stage::Prescribed::ScaledRows}});
    if (auto x = m.get("max_break_passes")) s.max_break_passes = x->integer(1, 1000000);
    return s;
  }
  if (s.kind == StageKind::Release) {
    const Value list = m.at("cracks");
    const std::string expected = "a non-empty list of crack names";
    const auto items = list.list(expected);
    if (items.empty()) list.fail("expected " + expected + ", got an empty list");
    for (const Value& item : items) {
      const std::string name = item.name();
      bool known = false;
      for (const Crack& c : cracks) known |= c.name == name;
      if (!known) {
        std::vector<std::string> defined;
        for (const Crack& c : cracks) defined.push_back(c.name);
        item.fail("no crack named '" + name + "'; defined: " + (defined.empty() ? "none" : join(defined)));
      }
      if (std::find(s.cracks.begin(), s.cracks.end(), name) != s.cracks.end())
        item.fail("crack '" + name + "' is named twice");
      s.cracks.push_back(name);
    }
    return s;
  }
  if (auto x = m.get("damping")) s.damping = x->non_negative("1/s");
  if (auto x = m.get("boundary_velocity")) s.boundary_velocity = read_boundary_values(*x, boundaries, "m/s");
  if (auto x = m.get("steps")) s.steps = x->integer(1, kMaxStageSteps);
  if (auto x = m.get("duration")) {
    if (s.steps)
      x->fail("give either duration or steps, not both (stage '" + s.name + "' has steps: " +
              std::to_string(*s.steps) + " and duration: " + x->got() + ")");
    s.duration = x->positive("s");
  } else if (!s.steps) {
    m.missing("duration", "simulated time, s; or give steps");
  }
  if (auto x = m.get("dt")) s.dt = x->positive("s");
  if (auto x = m.get("safety_factor")) {
    s.safety_factor = x->number_if("a number in (0, 1]", [](double f) { return f > 0 && f <= 1; });
    s.safety_factor_where = x->where();
  }
  if (auto x = m.get("allow_unstable_dt")) s.allow_unstable_dt = x->boolean();
  return s;
}

Output read_output(const Value& v) {
  const Map m(v, &kOutputKeys,
              "a map {frames, series_every, fields, node_stride, region, precision, check_free_space, "
              "progress_seconds, checkpoint_every_steps, checkpoint_every_seconds}");
  Output out;
  out.where = m.where();
  constexpr long int_max = std::numeric_limits<int>::max();
  if (auto x = m.get("frames")) out.frames = static_cast<int>(x->integer(1, int_max));
  if (auto x = m.get("series_every")) out.series_every = static_cast<int>(x->integer(1, int_max));
  if (auto x = m.get("fields")) {
    if (m.given("velocity")) x->fail("give fields or velocity, not both");
    const std::vector<Value> list = x->list("a list of frame fields");
    if (list.empty()) x->fail("expected at least one of: " + join(frame_field_names()) + ", got an empty list");
    std::vector<std::string> chosen;
    for (const Value& f : list) {
      std::vector<std::pair<std::string, std::string>> options;
      for (const std::string& n : frame_field_names()) options.emplace_back(n, n);
      const std::string name = f.choice(options);
      if (std::find(chosen.begin(), chosen.end(), name) != chosen.end()) f.fail("'" + name + "' is listed twice");
      chosen.push_back(name);
    }
    out.fields.clear();
    for (const std::string& n : frame_field_names())  // in the frames' order
      if (std::find(chosen.begin(), chosen.end(), n) != chosen.end()) out.fields.push_back(n);
  }
  if (auto x = m.get("velocity"))
    if (!x->boolean()) std::erase(out.fields, std::string("velocity"));
  out.write_velocity = out.has_field("velocity");
  if (auto x = m.get("node_stride")) out.node_stride = x->integer(1, std::numeric_limits<int>::max());
  if (auto x = m.get("region")) {
    const Map box(*x, &kBoxKeys, "a box {min: [x, y, z], max: [x, y, z]}");
    const Vec3 lo = box.at("min").vec3("m");
    const Value max = box.at("max");
    const Vec3 hi = max.vec3("m");
    for (int d = 0; d < 3; ++d)
      if (lo[d] > hi[d])
        max.fail(std::string("expected min <= max in every component, got ") + "xyz"[d] + ": min " +
                 format_number(lo[d]) + " > max " + format_number(hi[d]));
    out.region = std::array<Vec3, 2>{lo, hi};
  }
  if (auto x = m.get("precision")) out.single_precision = x->choice<bool>({{"double", false}, {"single", true}});
  if (auto x = m.get("check_free_space")) out.check_free_space = x->boolean();
  if (auto x = m.get("progress_seconds")) out.progress_seconds = x->non_negative("s");
  if (auto x = m.get("checkpoint_every_steps")) out.checkpoint_every_steps = x->integer(0);
  if (auto x = m.get("checkpoint_every_seconds")) out.checkpoint_every_seconds = x->non_negative("s");
  return out;
}

LongRange read_long_range(const Value& v, const std::vector<Body>& bodies) {
  const Map m(v, &kLongRangeKeys, "a map {length, cutoff, exclusion, pairs}");
  LongRange lr;
  lr.where = m.where();
  if (std::none_of(bodies.begin(), bodies.end(), [](const Body& b) { return b.kind->traits.long_range; }))
    v.fail("long-range forces act between fiber nodes (eqs. 32-36); the scene has no body with kind: fiber");
  lr.length = m.at("length").positive("m");
  lr.cutoff = m.at("cutoff").positive("m");
  // Default: the largest fiber horizon (bonded neighbours do not also interact at long range).
  for (const Body& b : bodies)
    if (b.kind->traits.long_range) lr.exclusion = std::max(lr.exclusion, b.horizon_value());
  if (auto x = m.get("exclusion")) {
    lr.exclusion = x->non_negative("m");
    lr.exclusion_where = x->where();
  }
  const Value pairs = m.at("pairs");
  const std::vector<Value> rules = pairs.list("a list of pair rules {between, alpha, beta}");
  if (rules.empty()) pairs.fail("expected at least one pair rule {between, alpha, beta}, got an empty list");
  if (rules.size() > 65000)  // the Verlet list stores a pair's rule in 16 bits
    pairs.fail("expected at most 65000 pair rules, got " + std::to_string(rules.size()));
  for (const Value& r : rules) {
    const Map rm(r, &kPairRuleKeys, "a map {between, segments, alpha, beta, cutoff}");
    PairRule rule;
    rule.where = rm.where();
    rule.between = rm.at("between").choice<PairKind>({{"adjacent_segments", PairKind::AdjacentSegments},
                                                      {"distant_segments", PairKind::DistantSegments},
                                                      {"other_fibers", PairKind::OtherFibers},
                                                      {"segments", PairKind::Segments}});
    if (rule.between == PairKind::Segments) {
      if (!rm.given("segments")) rm.missing("segments", "two different segment indices [i, j] along the fiber");
      const Value seg = rm.at("segments");
      const std::vector<Value> ij = seg.list("a list of two segment indices [i, j]");
      if (ij.size() != 2) seg.fail("expected a list of two segment indices [i, j], got " + seg.got());
      for (int k = 0; k < 2; ++k) {
        const long i = ij[k].integer(0);
        if (i > 1000000000) ij[k].fail("expected a segment index of at most 1e9, got " + ij[k].got());
        rule.segments[k] = static_cast<std::int32_t>(i);
      }
      // Nodes of one segment never interact.
      if (rule.segments[0] == rule.segments[1])
        seg.fail("expected two different segments (nodes of one segment never interact), got [" +
                 std::to_string(rule.segments[0]) + ", " + std::to_string(rule.segments[1]) + "]");
      rule.segments_where = seg.where();
      rule.segments_key = seg.path();
    } else if (auto x = rm.get("segments")) {
      x->fail(std::string("only a rule with between: segments names segments; this rule is between: ") +
              to_text(rule.between));
    }
    rule.alpha = rm.at("alpha").non_negative("J/m^6");
    rule.beta = rm.at("beta").number("a number [J/m^6] (negative: a repulsive 1/y^6 tail)");
    if (auto x = rm.get("cutoff")) rule.cutoff = x->positive("m");
    lr.pairs.push_back(rule);
  }
  return lr;
}

}  // namespace

Scene read_scene(const Context& ctx, const YAML::Node& root, const std::string& file) {
  const Map top(Value(ctx, root, ""), &kSceneKeys, "a map");
  Scene s;
  s.file = file;
  s.name = top.at("name").given_name("scene");
  if (auto x = top.get("description")) s.description = x->string();

  const Map materials(top.at("materials"), nullptr, "a map of material name to material");
  if (materials.empty()) top.at("materials").fail("expected at least one material, got an empty map");
  materials.check_key_names("material");
  for (const auto& [name, v] : materials.items()) s.materials.push_back(read_material(name, v));

  const Map bodies(top.at("bodies"), nullptr, "a map of body name to body");
  if (bodies.empty()) top.at("bodies").fail("expected at least one body, got an empty map");
  bodies.check_key_names("body");
  for (const auto& [name, v] : bodies.items()) s.bodies.push_back(read_body(name, v, s.materials));
  check_point_cloud_materials(s.bodies);

  UniqueNames crack_names("crack");
  const auto cracks = optional_list(top, "cracks", "a list of cracks");
  for (std::size_t i = 0; i < cracks.size(); ++i) s.cracks.push_back(read_crack(cracks[i], i, crack_names));
  // A slit cuts the bonds of sheets and fibers; in a volume it cuts nothing.
  const bool only_volumes = std::none_of(s.bodies.begin(), s.bodies.end(),
                                         [](const Body& b) { return b.kind->traits.cut_by_cracks(); });
  for (std::size_t i = 0; i < cracks.size() && only_volumes; ++i) {
    if (s.cracks[i].is_polygon()) continue;
    std::vector<std::string> kinds;
    for (const Body& b : s.bodies)
      if (std::find(kinds.begin(), kinds.end(), b.kind->name) == kinds.end()) kinds.push_back(b.kind->name);
    std::string why = "a slit (from, to) is a straight segment, which cuts the bonds of sheets and fibers; every "
                      "body of this scene is a volume (kind: ";
    why += join(kinds);
    why += "), where a segment cuts no bond; a volume is cut by a polygon: {name, polygon: [[x, y, z], ...]}";
    cracks[i].fail(why);
  }

  UniqueNames boundary_names("boundary");
  for (const Value& v : optional_list(top, "boundaries", "a list of boundaries"))
    s.boundaries.push_back(read_boundary(v, boundary_names, s.bodies));

  UniqueNames tool_names("tool");
  const auto tools = optional_list(top, "tools", "a list of tools");
  for (const Value& v : tools) s.tools.push_back(read_tool(v, tool_names));
  // A tool's series.csv columns (<name>_x, _y, _z, _vx, _vy, _vz, _force_x, _force_y, _force_z)
  // repeat no other column: a tool named tip0 would give a second tip0_x beside the crack tip
  // track's, and tools 'a' and 'a_force' would share a_force_x; a reader would take the wrong one.
  {
    std::map<std::string, std::string> owner;  // column -> whose
    for (std::size_t k = 0; k < s.tools.size(); ++k) {
      const std::string& name = s.tools[k].name;
      if (name.size() > 3 && name.compare(0, 3, "tip") == 0 &&
          std::all_of(name.begin() + 3, name.end(), [](char c) { return c >= '0' && c <= '9'; }))
        tools[k].fail("tool '" + name + "': its series.csv columns " + name + "_x, " + name +
                      "_y would repeat those of crack tip track " + name.substr(3) + "; expected another name");
      for (const char* c : {"_x", "_y", "_z", "_vx", "_vy", "_vz", "_force_x", "_force_y", "_force_z"}) {
        const auto [at, added] = owner.emplace(name + c, name);
        if (!added)
          tools[k].fail("tool '" + name + "': its series.csv column " + at->first + " would repeat tool '" + at->second +
                        "''s; expected another name");
      }
    }
  }

  if (auto x = top.get("long_range")) s.long_range = read_long_range(*x, s.bodies);

  if (auto x = top.get("initial")) s.initial = read_initial(*x);

  const Value stages_value = top.at("stages");
  const auto stages = stages_value.list("a list of stages");
  if (stages.empty()) stages_value.fail("expected at least one stage, got an empty list");
  UniqueNames stage_names("stage");
  for (std::size_t i = 0; i < stages.size(); ++i)
    s.stages.push_back(read_stage(stages[i], i, stage_names, s.boundaries, s.cracks));
  std::map<std::string, std::string> released;  // crack -> stage releasing it
  for (std::size_t i = 0; i < s.stages.size(); ++i)
    for (const std::string& c : s.stages[i].cracks)
      if (!released.emplace(c, s.stages[i].name).second)
        stages[i].fail("crack '" + c + "' is already released by stage '" + released[c] + "'");
  bool dynamic = false;
  for (const Stage& st : s.stages) dynamic |= st.kind == StageKind::Dynamic;
  if (!dynamic) stages_value.fail("expected at least one stage of kind dynamic");
  for (std::size_t i = 0; i < s.stages.size() && s.long_range; ++i)
    if (s.stages[i].kind == StageKind::QuasiStatic)
      stages[i].fail("a quasistatic stage in a scene with long_range; long-range forces act in dynamic stages "
                     "only (the quasi-static tangent holds the bonds alone)");

  if (auto x = top.get("stability")) {
    const Map m(*x, &kStabilityKeys, "a map {energy_error, motion_per_step}");
    if (auto e = m.get("energy_error")) s.stability.energy_error = e->non_negative("");
    if (auto e = m.get("motion_per_step")) s.stability.motion_per_step = e->non_negative("");
  }

  if (auto x = top.get("output")) s.output = read_output(*x);
  return s;
}

}  // namespace peri::scene_detail
