// Cutouts of grid bodies (membranes, solids, lattices): regions whose nodes the body drops before
// bonds are built, so that a plate with a hole or a notch needs no mesh. The reader and emitter of
// the `cutouts` key, the shapes' membership test, and the filter a kind's discretize passes its
// nodes through (with the checks that need the nodes: a cutout that removes no node, cutouts
// that remove every node).
#include <algorithm>
#include <cmath>
#include <sstream>

#include "common.hpp"

namespace peri {

bool Cutout::contains(const Vec3& x) const {
  switch (shape) {
    case CutoutShape::Circle: {
      const double dx = x[0] - center[0], dy = x[1] - center[1];
      return dx * dx + dy * dy <= radius * radius;
    }
    case CutoutShape::Box:
      for (int d = 0; d < 3; ++d)
        if (x[d] < min[d] || x[d] > max[d]) return false;
      return true;
    case CutoutShape::Polygon: {
      // Even-odd rule: a ray from x towards +x crosses the boundary an odd number of times.
      bool inside = false;
      const std::size_t n = vertices.size();
      for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
        const auto& a = vertices[i];
        const auto& b = vertices[j];
        if ((a[1] > x[1]) != (b[1] > x[1]) && x[0] < (b[0] - a[0]) * (x[1] - a[1]) / (b[1] - a[1]) + a[0])
          inside = !inside;
      }
      return inside;
    }
    case CutoutShape::Sphere: {
      double r2 = 0;
      for (int d = 0; d < 3; ++d) r2 += (x[d] - center[d]) * (x[d] - center[d]);
      return r2 <= radius * radius;
    }
    case CutoutShape::Cylinder: {
      double r2 = 0;
      for (int d = 0; d < 3; ++d)
        if (d != axis) r2 += (x[d] - center[d]) * (x[d] - center[d]);
      return r2 <= radius * radius;
    }
  }
  return false;
}

namespace kinds {
namespace {

using scene_detail::flow;
using scene_detail::format_number;
using scene_detail::join;

const char* shape_text(CutoutShape s) {
  switch (s) {
    case CutoutShape::Circle: return "circle";
    case CutoutShape::Box: return "box";
    case CutoutShape::Polygon: return "polygon";
    case CutoutShape::Sphere: return "sphere";
    case CutoutShape::Cylinder: return "cylinder";
  }
  return "?";
}

// The keys each shape takes besides kind.
std::vector<std::string> shape_keys(CutoutShape s) {
  switch (s) {
    case CutoutShape::Circle:
    case CutoutShape::Sphere: return {"center", "radius"};
    case CutoutShape::Cylinder: return {"center", "radius", "axis"};
    case CutoutShape::Box: return {"min", "max"};
    case CutoutShape::Polygon: return {"vertices"};
  }
  return {};
}

Cutout read_cutout(const Value& v, int dimension) {
  const Map m(v, &kCutoutKeys, "a cutout {kind: circle | box | polygon | sphere | cylinder, ...}");
  Cutout c;
  c.where = m.where();
  const Value kind = m.at("kind");
  c.shape = kind.choice<CutoutShape>({{"circle", CutoutShape::Circle},
                                      {"box", CutoutShape::Box},
                                      {"polygon", CutoutShape::Polygon},
                                      {"sphere", CutoutShape::Sphere},
                                      {"cylinder", CutoutShape::Cylinder}});
  if (dimension < 3 && (c.shape == CutoutShape::Sphere || c.shape == CutoutShape::Cylinder))
    kind.fail(std::string("a ") + shape_text(c.shape) +
              " cutout cuts solids; a sheet takes circle, box or polygon cutouts, got " + kind.got());
  const std::vector<std::string> keys = shape_keys(c.shape);
  for (const auto& [key, value] : m.items()) {
    if (key == "kind" || !m.given(key) || std::find(keys.begin(), keys.end(), key) != keys.end()) continue;
    std::vector<std::string> own{"kind"};
    own.insert(own.end(), keys.begin(), keys.end());
    value.fail(std::string("not used by a ") + shape_text(c.shape) + " cutout; expected one of: " + join(own));
  }
  for (const std::string& key : keys)
    if (key != "axis" && !m.given(key)) {
      const char* what = key == "center"   ? (c.shape == CutoutShape::Circle ? "centre [x, y], m" : "centre [x, y, z], m")
                         : key == "radius" ? "radius, m"
                         : key == "min"    ? "lower corner [x, y, z], m"
                         : key == "max"    ? "upper corner [x, y, z], m"
                                           : "the polygon's corners [[x, y], ...], m";
      m.missing(key, what);
    }
  switch (c.shape) {
    case CutoutShape::Circle: {
      const auto xy = m.at("center").vec2("m");
      c.center = {xy[0], xy[1], 0.0};
      c.radius = m.at("radius").positive("m");
      break;
    }
    case CutoutShape::Sphere:
    case CutoutShape::Cylinder:
      c.center = m.at("center").vec3("m");
      c.radius = m.at("radius").positive("m");
      if (auto a = m.get("axis")) c.axis = a->choice<int>({{"x", 0}, {"y", 1}, {"z", 2}});
      break;
    case CutoutShape::Box: {
      c.min = m.at("min").vec3("m");
      const Value max = m.at("max");
      c.max = max.vec3("m");
      for (int d = 0; d < 3; ++d)
        if (c.min[d] > c.max[d])
          max.fail(std::string("expected min <= max in every component, got ") + "xyz"[d] + ": min " +
                   format_number(c.min[d]) + " > max " + format_number(c.max[d]));
      break;
    }
    case CutoutShape::Polygon: {
      const Value list = m.at("vertices");
      const std::string expected = "a list of at least 3 corners [[x, y], ...] [m]";
      const std::vector<Value> items = list.list(expected);
      if (items.size() < 3) list.fail("expected " + expected + ", got " + list.got());
      for (std::size_t k = 0; k < items.size(); ++k) {
        c.vertices.push_back(items[k].vec2("m"));
        if (k > 0 && c.vertices[k] == c.vertices[k - 1])
          items[k].fail("expected a corner different from the one before it, got " + items[k].got());
      }
      // A polygon whose corners lie on one line (to round-off) encloses nothing: every corner's
      // offset from the line through the first corner and the one farthest from it, against the
      // bounding box's diagonal. (Not the signed area: a crossing polygon whose lobes cancel
      // encloses them by the even-odd rule.)
      double lo[2] = {HUGE_VAL, HUGE_VAL}, hi[2] = {-HUGE_VAL, -HUGE_VAL}, far = 0, off = 0;
      const auto& o = c.vertices[0];
      std::size_t f = 0;
      for (std::size_t i = 0; i < c.vertices.size(); ++i) {
        const auto& p = c.vertices[i];
        const double d2 = (p[0] - o[0]) * (p[0] - o[0]) + (p[1] - o[1]) * (p[1] - o[1]);
        if (d2 > far) far = d2, f = i;
        for (int d = 0; d < 2; ++d) lo[d] = std::min(lo[d], p[d]), hi[d] = std::max(hi[d], p[d]);
      }
      const auto& q = c.vertices[f];
      for (const auto& p : c.vertices)
        off = std::max(off, std::fabs((q[0] - o[0]) * (p[1] - o[1]) - (p[0] - o[0]) * (q[1] - o[1])));
      const double box = (hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]);
      if (!(off > 1e-12 * box))
        list.fail("expected a polygon that encloses an area (corners not all on one line), got " + list.got());
      break;
    }
  }
  return c;
}

}  // namespace

void read_cutouts(const Map& m, Body& b, int dimension) {
  const auto v = m.get("cutouts");
  if (!v) return;
  const std::vector<Value> items = v->list("a list of cutouts [{kind: circle, center: [x, y], radius: r}, ...]");
  for (const Value& item : items) b.cutouts.push_back(read_cutout(item, dimension));
}

void emit_cutouts(Writer& w, const Body& b) {
  if (b.cutouts.empty()) return;
  w.key(4, "cutouts", "");
  for (const Cutout& c : b.cutouts) {
    std::string text = std::string("{kind: ") + shape_text(c.shape);
    switch (c.shape) {
      case CutoutShape::Circle:
        text += ", center: " + flow({c.center[0], c.center[1]}) + ", radius: " + format_number(c.radius);
        break;
      case CutoutShape::Sphere:
        text += ", center: " + flow(c.center) + ", radius: " + format_number(c.radius);
        break;
      case CutoutShape::Cylinder:
        text += ", center: " + flow(c.center) + ", radius: " + format_number(c.radius) + ", axis: " +
                std::string(1, "xyz"[c.axis]);
        break;
      case CutoutShape::Box:
        text += ", min: " + flow(c.min) + ", max: " + flow(c.max);
        break;
      case CutoutShape::Polygon: {
        std::vector<std::string> corners;
        for (const auto& p : c.vertices) corners.push_back(flow({p[0], p[1]}));
        text += ", vertices: [" + join(corners) + "]";
        break;
      }
    }
    w.line(6, "- " + text + "}");
  }
}

CutSink::CutSink(const Body& b, NodeSink& sink) : body_(b), sink_(sink), first_(sink.size()), held_(b.cutouts.size(), 0) {}

void CutSink::add(double x, double y, double z, double measure) {
  ++candidates_;
  const Vec3 p{x, y, z};
  bool cut = false;
  for (std::size_t k = 0; k < body_.cutouts.size(); ++k)
    if (body_.cutouts[k].contains(p)) {
      ++held_[k];
      cut = true;
    }
  if (!cut) sink_.add(x, y, z, measure);
}

void CutSink::finish() const {
  for (std::size_t k = 0; k < held_.size(); ++k)
    if (held_[k] == 0) {
      std::ostringstream msg;
      msg << body_.cutouts[k].where.str() << ": bodies." << body_.name << ".cutouts." << k << ": the "
          << shape_text(body_.cutouts[k].shape) << " cutout removes no node of body '" << body_.name
          << "' (it lies outside the body or between its nodes); expected a region that holds at least one of its "
          << candidates_ << " nodes";
      throw InputError(msg.str());
    }
  if (candidates_ > 0 && sink_.size() == first_) {
    std::ostringstream msg;
    msg << body_.where.str() << ": bodies." << body_.name << ".cutouts: the cutouts remove all " << candidates_
        << " nodes of body '" << body_.name << "'; expected at least one node left";
    throw InputError(msg.str());
  }
}

}  // namespace kinds
}  // namespace peri
