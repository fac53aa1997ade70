// Body kind `fiber` (Silling & Bobaru section 6, eq. 31): nodes at equal arc-length steps along a
// polyline (given inline or in a file), or along the many paths of a generated network (example 7.6), measure A ds with the
// cross-section A = pi d^2 / 4; full weights within the horizon; long-range pairs between fibers.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common.hpp"
#include "kinds.hpp"

namespace peri::kinds {
namespace {

using scene_detail::format_number;

const Keys kNetworkKeys = {
    {.name = "box", .required = true, .what = "box {min: [x, y, z], max: [x, y, z]} the fibers fill, m",
     .doc = "the box the fibers cross, `{min: [x, y, z], max: [x, y, z]}` (`bodies.<name>.network.box`)"},
    {.name = "families", .required = true, .what = "list of fiber families {direction: x or y, count}",
     .doc = "non-empty list of fiber families (`bodies.<name>.network.families[i]`)"},
    {.name = "deviation", .unit = "rad", .fallback = "0.15",
     .doc = "standard deviation >= 0 of the Gaussian angles (in the plane and out of it) between a step's "
            "direction and its family's; steps are mirrored back at the box's side faces"},
    {.name = "step", .required = true, .what = "path length between direction draws, m", .unit = "m",
     .doc = "path length between direction draws, > 0; at most 1e6 steps across the box along each family's "
            "direction"},
    {.name = "start_band", .unit = "m", .fallback = "5% of the box's smaller x, y extent",
     .doc = ">= 0: each fiber starts at a uniformly random point within this distance of the box's low face normal "
            "to its family's direction, anywhere across the other two, and walks to the far face"},
    {.name = "seed", .fallback = "1",
     .doc = "integer >= 0; the same seed gives the same paths on every rank (splitmix64 and Box-Muller; on another "
            "platform up to its libm's log and cos)"},
};

const Keys kFamilyKeys = {
    {.name = "direction", .required = true, .what = "x or y", .doc = "`x` or `y`: the direction the family's fibers cross the box"},
    {.name = "count", .required = true, .what = "number of fibers, >= 1", .doc = "number of fibers, an integer in 1 .. 100000"},
};

double distance(const Vec3& p, const Vec3& q) {
  return std::sqrt(std::pow(q[0] - p[0], 2) + std::pow(q[1] - p[1], 2) + std::pow(q[2] - p[2], 2));
}

double path_length(const std::vector<Vec3>& path) {
  double length = 0;
  for (std::size_t k = 1; k < path.size(); ++k) length += distance(path[k - 1], path[k]);
  return length;
}

// Splitmix64: a fully specified generator (the same integers everywhere; the normal deviates also
// go through libm's log and cos, the same on every rank of a run).
struct SplitMix {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  double uniform() { return (static_cast<double>(next() >> 11) + 0.5) * 0x1.0p-53; }  // (0, 1)
  double normal() {  // Box-Muller
    const double u = uniform(), v = uniform();
    return std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * 3.14159265358979323846 * v);
  }
};

// Mirror coordinate x back into [lo, hi].
double mirror_into(double x, double lo, double hi) {
  for (int k = 0; k < 8 && (x < lo || x > hi); ++k) x = x < lo ? 2 * lo - x : 2 * hi - x;
  return std::clamp(x, lo, hi);
}

std::vector<std::vector<Vec3>> network_paths(const FiberNetwork& n) {
  SplitMix rng{static_cast<std::uint64_t>(n.seed) * 0x2545f4914f6cdd1dull + 1};
  std::vector<std::vector<Vec3>> paths;
  for (const FiberFamily& f : n.families) {
    const int a = f.axis, t = 1 - a;  // along, across (in the plane); z out of the plane
    for (long k = 0; k < f.count; ++k) {
      Vec3 p;
      p[a] = n.min[a] + n.start_band * rng.uniform();
      p[t] = n.min[t] + (n.max[t] - n.min[t]) * rng.uniform();
      p[2] = n.min[2] + (n.max[2] - n.min[2]) * rng.uniform();
      std::vector<Vec3> path{p};
      while (path.back()[a] < n.max[a]) {
        const double theta = n.deviation * rng.normal(), phi = n.deviation * rng.normal();
        Vec3 q = path.back();
        q[a] += n.step * std::cos(phi) * std::cos(theta);
        q[t] += n.step * std::cos(phi) * std::sin(theta);
        q[2] += n.step * std::sin(phi);
        q[t] = mirror_into(q[t], n.min[t], n.max[t]);
        q[2] = mirror_into(q[2], n.min[2], n.max[2]);
        if (q[a] > n.max[a]) {  // end on the far face
          const Vec3& o = path.back();
          const double s = (n.max[a] - o[a]) / (q[a] - o[a]);
          for (int c = 0; c < 3; ++c) q[c] = o[c] + s * (q[c] - o[c]);
          q[a] = n.max[a];
        }
        if (q[a] <= path.back()[a]) {  // a step backwards (|theta| > pi/2): draw again
          if (path.size() > 100000) break;
          continue;
        }
        path.push_back(q);
      }
      if (path.size() >= 2) paths.push_back(std::move(path));
    }
  }
  return paths;
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

// A path from a text file (`polyline: file`): one point x, y, z a line (commas or blanks between
// the numbers), `#` lines and blank lines skipped; InputError naming the file and line.
double read_polyline(const Value& v, Body& b) {
  b.polyline = resolve_input_path(v, v.name());
  const std::string key = "bodies." + b.name + ".polyline";
  std::ifstream in(b.polyline, std::ios::binary);
  std::error_code ec;
  if (!in || std::filesystem::is_directory(b.polyline, ec)) {
    const int err = errno;
    v.fail("cannot read the polyline '" + b.polyline + "': " +
           (std::filesystem::is_directory(b.polyline, ec) ? "a directory" : std::strerror(err)));
  }
  auto fail_at = [&](long line, const std::string& what) {
    throw InputError(b.polyline + ":" + std::to_string(line) + ": " + key + ": " + what);
  };
  std::string text;
  long line = 0, previous = 0;
  double length = 0;
  while (std::getline(in, text)) {
    ++line;
    if (line == 1 && text.starts_with(kUtf8Bom)) text.erase(0, kUtf8Bom.size());
    const auto first = text.find_first_not_of(" \t\r");
    if (first == std::string::npos || text[first] == '#') continue;
    std::string t = text.substr(first, text.find_last_not_of(" \t\r") - first + 1);
    std::vector<std::string> cells;
    std::string cell;
    const std::string shown = "'" + (t.size() > 60 ? t.substr(0, 60) + "..." : t) + "'";
    // A comma ends a field that must hold a number: none before it (",0,0", "0,,0") or after the
    // last ("0,0,0,") is an empty field.
    bool filled = false;
    for (char& c : t) {
      if (c == ',') {
        if (!filled) fail_at(line, "an empty field before a comma; expected 3 numbers x, y, z [m], got " + shown);
        filled = false;
        c = ' ';
      } else if (c != ' ' && c != '\t' && c != '\r') {
        filled = true;
      }
    }
    if (!filled) fail_at(line, "an empty field after the last comma; expected 3 numbers x, y, z [m], got " + shown);
    std::istringstream words(t);
    while (words >> cell) cells.push_back(cell);
    if (cells.size() != 3) fail_at(line, "expected 3 numbers x, y, z [m], got " + shown);
    Vec3 p{};
    for (int c = 0; c < 3; ++c) {
      const scene_detail::NumberText r = scene_detail::parse_number(cells[c], p[c]);
      if (r == scene_detail::NumberText::Subnormal)
        fail_at(line, "'" + cells[c] + "' is below the smallest normal double; expected numbers of magnitude 0 or at "
                      "least 2.2e-308 [m], got " + shown);
      if (r != scene_detail::NumberText::Ok)
        fail_at(line, std::string("expected 3 finite numbers x, y, z [m], got ") + shown);
    }
    if (!b.path.empty()) {
      const double d = distance(b.path.back(), p);
      if (!(d > 0)) fail_at(line, "the same point as line " + std::to_string(previous) + "; expected each point "
                                  "different from the one before it");
      length += d;
    }
    b.path.push_back(p);
    previous = line;
  }
  if (b.path.size() < 2)
    v.fail("the polyline '" + b.polyline + "' has " + std::to_string(b.path.size()) +
           " point" + (b.path.size() == 1 ? "" : "s") + "; expected at least 2 lines x, y, z");
  return length;
}

// A fiber: polyline path, diameter, spacing along the path, horizon, segments (eq. 31).
void read(const Map& m, Body& b, const Material&) {
  double length = INFINITY;  // of the one path (a network's fibers cross its box)
  if (auto x = m.get("network")) {
    if (m.given("path")) x->fail("give either path (one fiber) or network (many), not both");
    if (m.given("polyline")) x->fail("give either polyline (one fiber) or network (many), not both");
    b.network = read_network(*x);
  } else if (auto x = m.get("polyline")) {
    if (auto y = m.get("path")) y->fail("give either path or polyline (a file of the path's points), not both");
    length = read_polyline(*x, b);
  } else {
    if (!m.given("path")) m.missing("path", "polyline [[x, y, z], ...] of at least 2 points, m (or polyline, or network)");
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
  b.diameter = m.at("diameter").positive("m");
  const Value spacing = m.at("spacing");
  b.spacing = spacing.positive("m");
  if (b.spacing > length)
    spacing.fail("spacing must not exceed the fiber's length along its path (" + format_number(length) +
                 " m), got " + spacing.got());
  if (auto x = m.get("segment_length")) b.segment_length = x->non_negative("m");
  read_horizon(m, b);
  b.quadrature = Quadrature::Full;
}

void emit(Writer& w, const Body& b) {
  using scene_detail::flow;
  if (b.network) {
    const FiberNetwork& n = *b.network;
    w.key(4, "network", "");
    w.key(6, "box", "{min: " + flow(n.min) + ", max: " + flow(n.max) + "}");
    std::vector<std::string> fams;
    for (const FiberFamily& f : n.families)
      fams.push_back(std::string("{direction: ") + (f.axis == 0 ? "x" : "y") + ", count: " + std::to_string(f.count) + "}");
    w.key(6, "families", "[" + scene_detail::join(fams) + "]");
    w.key(6, "deviation", n.deviation);
    w.key(6, "step", n.step);
    w.key(6, "start_band", n.start_band);
    w.key(6, "seed", std::to_string(n.seed));
  } else if (!b.polyline.empty()) {
    w.key(4, "polyline", scene_detail::yaml_string(b.polyline));
  } else {
    std::vector<std::string> points;
    for (const Vec3& p : b.path) points.push_back(flow(p));
    w.key(4, "path", "[" + scene_detail::join(points) + "]");
  }
  w.key(4, "diameter", b.diameter);
  w.key(4, "spacing", b.spacing);
  w.key(4, "segment_length", b.segment_length);
  emit_horizon(w, b);
}

// Nodes at the centres of n equal arc-length steps ds = L/n along each path (eq. 31's ds), each
// with the measure A ds; no grid, so reference offsets are not snapped.
void discretize(const Body& b, BodyGeometry& g, NodeSink& sink) {
  const double dx = b.spacing;
  g.area = 0.25 * 3.14159265358979323846 * b.diameter * b.diameter;
  g.segment_length = b.segment_length;
  g.quadrature = Quadrature::Full;
  for (const std::vector<Vec3>& path : fiber_paths(b)) {
    const double length = path_length(path);
    // Segment numbers are 32-bit (long_range_table): a segment_length so short that the path
    // holds more than 1e9 of them is refused (it wrapped the numbers, and every node fell in one
    // segment, whose nodes never interact: the long-range forces silently off).
    if (b.segment_length > 0 && !(length / b.segment_length <= 1e9))
      throw InputError(b.where.str() + ": bodies." + b.name + ".segment_length: " + number_text(b.segment_length) +
                       " m cuts a path of " + number_text(length) + " m into " + number_text(length / b.segment_length) +
                       " segments; expected at most 1e9 (a segment_length of at least " +
                       number_text(length * 1e-9) + " m; the node spacing, " + number_text(dx) +
                       " m, puts each node in a segment of its own)");
    const std::int64_t n = count_along(length, dx);
    const double ds = length / static_cast<double>(n);
    g.path_spacing.push_back(ds);
    std::size_t leg = 1;
    double leg_start = 0;
    double leg_length = distance(path[0], path[1]);
    std::vector<Vec3> placed(static_cast<std::size_t>(n));
    for (std::int64_t k = 0; k < n; ++k) {
      const double s = (static_cast<double>(k) + 0.5) * ds;
      while (s > leg_start + leg_length && leg + 1 < path.size()) {
        leg_start += leg_length;
        ++leg;
        leg_length = distance(path[leg - 1], path[leg]);
      }
      const double t = std::clamp((s - leg_start) / leg_length, 0.0, 1.0);
      const Vec3& p = path[leg - 1];
      const Vec3& q = path[leg];
      placed[static_cast<std::size_t>(k)] = {p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]), p[2] + t * (q[2] - p[2])};
    }
    // A path that comes back onto its own line (0, 1 cm, 0.5 cm along x) puts nodes on nodes: a
    // bond of no length, whose stable step is nothing.
    if (const auto [i, j] = first_close_pair(placed, ds, 1e-8 * ds); i < placed.size()) {
      const std::string place = b.polyline.empty() ? b.where.str() + ": bodies." + b.name + ".path"
                                                   : b.polyline + ": bodies." + b.name + ".polyline";
      throw InputError(place + ": the path comes back onto itself: its nodes at arc length " +
                       format_number((static_cast<double>(j) + 0.5) * ds) + " m and " +
                       format_number((static_cast<double>(i) + 0.5) * ds) + " m lie at one point (" +
                       format_number(placed[i][0]) + ", " + format_number(placed[i][1]) + ", " +
                       format_number(placed[i][2]) + "); expected a path that does not run over itself");
    }
    for (const Vec3& x : placed) sink.add(x[0], x[1], x[2], g.area * ds);
    g.path_first.push_back(static_cast<std::int64_t>(sink.size()) - g.first);
  }
  // One spacing for the body (stable-step and motion checks): the finest path's.
  g.spacing = *std::min_element(g.path_spacing.begin(), g.path_spacing.end());
  g.cells = {g.path_first.back(), 1, 1};
}

double node_estimate(const Body& b) {
  double n = 0;
  if (b.network)  // every fiber crosses the box once; its path is longer by its wiggles (bounded by 1.5)
    for (const FiberFamily& f : b.network->families)
      n += 1.5 * f.count * (b.network->max[f.axis] - b.network->min[f.axis]) / b.spacing;
  else
    n = std::max(1.0, std::round(path_length(b.path) / b.spacing));
  return n;
}

}  // namespace

BodyKind fiber_kind() {
  BodyKind k;
  k.name = "fiber";
  k.summary = "nodes along a path, full weights within the horizon";
  k.traits = {.dimension = 1, .grid = false, .long_range = true};
  k.keys = {
      {.name = "path", .unit = "m", .fallback = "required unless network",
       .doc = "a polyline [[x, y, z], ...] of at least 2 points, each different from the one before; n = round(L / "
              "spacing) nodes at the centres of n equal arc-length steps ds = L / n, measure A ds"},
      {.name = "polyline", .fallback = "- (path)",
       .doc = "instead of path: a text file (relative to the scene file) of the path's points, one `x, y, z` a "
              "line [m] (commas or blanks between the numbers), at least 2, each different from the one before; "
              "one path a file; `#` lines and blank lines are skipped"},
      {.name = "network",
       .doc = "instead of path: many fibers generated in a box, bonded wherever they pass within the horizon "
              "(cross-links) (`bodies.<name>.network`)"},
      {.name = "diameter", .required = true, .what = "fiber diameter, m", .unit = "m",
       .doc = "d > 0; cross-section A = pi d^2 / 4"},
      {.name = "spacing", .required = true, .what = "node spacing along the path, m", .unit = "m",
       .doc = "> 0, at most the path's length; each path gets round(L / spacing) equal arc steps"},
      {.name = "segment_length", .unit = "m", .fallback = "0 (one segment)",
       .doc = ">= 0; node k lies in segment floor((k + 1/2) ds / segment_length), which long_range rules tell "
              "apart"},
      kHorizonFactorKey,
      kHorizonKey,
  };
  k.nested = {{"network", &kNetworkKeys}, {"network.box", &kBoxKeys}, {"network.families[i]", &kFamilyKeys}};
  k.read = read;
  k.emit = emit;
  k.measure_keys = [](const Body& b) {
    return "bodies." + b.name + ".diameter " + number_text(b.diameter) + " m, " + key_text(b, "spacing", b.spacing);
  };
  k.node_estimate = node_estimate;
  k.family_estimate = [](const Body& b) { return 2.0 * std::floor(b.horizon_value() / b.spacing + 1e-9); };
  k.discretize = discretize;
  return k;
}

}  // namespace peri::kinds

namespace peri {

std::vector<std::vector<Vec3>> fiber_paths(const Body& b) {
  if (b.network) return kinds::network_paths(*b.network);
  return {b.path};
}

}  // namespace peri
