// The resolved scene as YAML (emit_scene): every key with its value or default, which
// parse_scene reads back to the same Scene.
#include <algorithm>
#include <cstdio>

#include "peri/scene/models.hpp"
#include "peri/scene/writer.hpp"
#include "schema.hpp"

namespace peri {

namespace scene_detail {

std::string yaml_string(const std::string& s) {
  static const char* const reserved[] = {"true", "false", "yes",  "no",  "on",  "off",
                                         "y",    "n",     "null", "nan", "inf", "infinity"};
  bool plain =
      !s.empty() && (std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_') && s.back() != ' ';
  for (char c : s) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (!(std::isalnum(u) || c == '_' || c == '-' || c == '.' || c == '/' || c == ' ')) plain = false;
  }
  if (plain) {
    std::string lower = s;
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    for (const char* r : reserved)
      if (lower == r) plain = false;
  }
  if (plain) return s;
  std::string out = "\"";
  for (char c : s) {
    const unsigned char u = static_cast<unsigned char>(c);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (u < 0x20 || u == 0x7f) {
          static const char hex[] = "0123456789abcdef";
          out += "\\x";
          out += hex[u >> 4];
          out += hex[u & 15];
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

namespace {
// "[" + inner + "]" by appending: GCC 12 warns falsely (-Warray-bounds, -Wstringop-overflow) on
// operator+(const char*, std::string&&) once inlined.
std::string enclose(char open, const std::string& inner, char close) {
  std::string out(1, open);
  out += inner;
  out += close;
  return out;
}
}  // namespace

std::string flow(std::initializer_list<double> xs) {
  std::vector<std::string> parts;
  for (double x : xs) parts.push_back(format_number(x));
  return enclose('[', join(parts), ']');
}

std::string flow(const Vec3& v) { return flow({v[0], v[1], v[2]}); }

std::string flow(const std::array<double, 9>& m) {
  return enclose('[', flow({m[0], m[1], m[2]}) + ", " + flow({m[3], m[4], m[5]}) + ", " + flow({m[6], m[7], m[8]}),
                 ']');
}

}  // namespace scene_detail

namespace {

using namespace scene_detail;

void emit_material(Writer& w, const Material& m) {
  w.key(2, yaml_string(m.name), "");
  w.key(4, "model", m.model);
  w.key(4, "density", m.density);
  if (m.marder) {
    w.key(4, "mooney_rivlin_a", m.marder->a);
    w.key(4, "mooney_rivlin_b", m.marder->b);
    w.key(4, "cutoff", m.marder->cutoff);
    w.key(4, "fracture_separation", m.marder->fracture_separation);
    w.key(4, "breaking", m.marder->reversible ? "reversible" : "irreversible");
    const MarderOptions& o = m.marder->options;
    if (o.kelvin_viscosity > 0) w.key(4, "kelvin_viscosity", o.kelvin_viscosity);
    if (o.stiffening_width > 0) {
      w.key(4, "stiffening_onset", o.stiffening_onset);
      w.key(4, "stiffening_width", o.stiffening_width);
    }
    if (o.break_separation > 0) w.key(4, "break_separation", o.break_separation);
    return;
  }
  w.optional(4, "wave_speed", m.wave_speed);
  w.optional(4, "bulk_modulus", m.bulk_modulus);
  w.optional(4, "youngs_modulus", m.youngs_modulus);
  w.optional(4, "micromodulus", m.micromodulus);
  // The shared keys the model takes (its catalog entry), resolved: influence with its default.
  const MaterialModel* model = find_material_model(m.model);
  const auto takes = [&](const char* key) {
    return model && std::find(model->keys.begin(), model->keys.end(), key) != model->keys.end();
  };
  if (takes("influence")) w.key(4, "influence", to_text(m.influence));
  w.optional(4, "critical_stretch", m.critical_stretch);
  w.optional(4, "critical_stretch_at_horizon", m.critical_stretch_at_horizon);
  w.optional(4, "tip_advance", m.tip_advance);
  if (m.tip_advance_tips == TipScope::Body) w.key(4, "tip_advance_tips", std::string("body"));
  if (m.kelvin_viscosity > 0) w.key(4, "kelvin_viscosity", m.kelvin_viscosity);
  if (m.hardening) {
    w.key(4, "hardening",
          "{coefficient: " + format_number(m.hardening->coefficient) +
              ", exponent: " + format_number(m.hardening->exponent) + "}");
  }
}

void emit_body(Writer& w, const Body& b) {
  w.key(2, yaml_string(b.name), "");
  w.key(4, "kind", b.kind->name);
  w.key(4, "material", yaml_string(b.material));
  b.kind->emit(w, b);  // the kind's own keys (its module)
}

void emit_boundary(Writer& w, const Boundary& b) {
  w.key(2, "- name", yaml_string(b.name));
  std::string region = b.region.group.empty() ? "{min: " + flow(b.region.min) + ", max: " + flow(b.region.max) : "{";
  if (!b.region.body.empty()) region += (b.region.group.empty() ? ", body: " : "body: ") + yaml_string(b.region.body);
  if (!b.region.group.empty()) region += ", group: " + yaml_string(b.region.group);
  w.key(4, "region", region + "}");
  w.key(4, "velocity", flow(b.velocity));
  std::vector<std::string> comps;
  for (int d = 0; d < 3; ++d)
    if (b.components[d]) comps.emplace_back(1, "xyz"[d]);
  w.key(4, "components", enclose('[', join(comps), ']'));
  w.key(4, "ramp_time", b.ramp_time);
}

void emit_tool(Writer& w, const Tool& t) {
  w.key(2, "- name", yaml_string(t.name));
  w.key(4, "kind", t.sphere ? "sphere" : "cylinder");
  w.key(4, "radius", t.radius);
  w.key(4, "center", t.sphere ? flow(t.center) : flow({t.center[0], t.center[1]}));
  w.key(4, "velocity", t.sphere ? flow(t.velocity) : flow({t.velocity[0], t.velocity[1]}));
  w.key(4, "friction", t.friction);
  w.key(4, "stiffness", t.stiffness);
  if (t.mass > 0) w.key(4, "mass", t.mass);
}

std::string flow_values(const std::vector<BoundaryValue>& values) {
  std::vector<std::string> items;
  for (const BoundaryValue& b : values) items.push_back(yaml_string(b.boundary) + ": " + flow(b.value));
  return enclose('{', join(items), '}');
}

void emit_stage(Writer& w, const Stage& s) {
  w.key(2, "- name", yaml_string(s.name));
  w.key(4, "kind", to_text(s.kind));
  if (s.kind == StageKind::QuasiStatic) {
    w.key(4, "displacements", flow_values(s.displacements));
    w.key(4, "displacement_gradient", flow(s.displacement_gradient));
    w.key(4, "load_steps", std::to_string(s.load_steps));
    w.key(4, "max_load_steps", std::to_string(s.max_load_steps));
    w.key(4, "max_load_step", s.max_load_step);
    w.key(4, "in_plane", to_text(s.in_plane));
    w.key(4, "jacobian", s.jacobian == Stage::Jacobian::Assembled    ? "assembled"
                         : s.jacobian == Stage::Jacobian::MfOperator ? "mf_operator"
                                                                      : "matrix_free");
    w.key(4, "jacobian_shift", s.jacobian_shift);
    w.key(4, "prescribed", s.prescribed == Stage::Prescribed::Eliminated ? "eliminated" : "scaled_rows");
    w.key(4, "max_break_passes", std::to_string(s.max_break_passes));
    return;
  }
  if (s.kind == StageKind::Release) {
    std::vector<std::string> names;
    for (const std::string& c : s.cracks) names.push_back(yaml_string(c));
    w.key(4, "cracks", enclose('[', join(names), ']'));
    return;
  }
  // With steps given, duration is optional; 0 stands for "not given".
  if (!(s.steps && s.duration == 0.0)) w.key(4, "duration", s.duration);
  if (s.steps) w.key(4, "steps", std::to_string(*s.steps));
  w.optional(4, "dt", s.dt);
  if (!s.dt) w.key(4, "safety_factor", s.safety_factor);  // (unused where dt is given)
  w.key(4, "allow_unstable_dt", to_text(s.allow_unstable_dt));
  w.key(4, "damping", s.damping);
  if (!s.boundary_velocity.empty()) w.key(4, "boundary_velocity", flow_values(s.boundary_velocity));
}

}  // namespace

std::string emit_scene(const Scene& s, const std::vector<std::string>& derived) {
  Writer w;
  w.key(0, "name", yaml_string(s.name));
  w.key(0, "description", yaml_string(s.description));
  w.key(0, "materials", "");
  for (const Material& m : s.materials) emit_material(w, m);
  w.key(0, "bodies", "");
  for (const Body& b : s.bodies) emit_body(w, b);
  if (!s.cracks.empty()) {
    w.key(0, "cracks", "");
    for (const Crack& c : s.cracks) {
      w.key(2, "- name", yaml_string(c.name));
      if (c.is_polygon()) {
        std::string corners;
        for (const Vec3& x : c.polygon) corners += (corners.empty() ? "" : ", ") + flow(x);
        w.key(4, "polygon", "[" + corners + "]");
        continue;
      }
      w.key(4, "from", flow(c.from));
      w.key(4, "to", flow(c.to));
    }
  }
  if (!s.boundaries.empty()) {
    w.key(0, "boundaries", "");
    for (const Boundary& b : s.boundaries) emit_boundary(w, b);
  }
  if (!s.tools.empty()) {
    w.key(0, "tools", "");
    for (const Tool& t : s.tools) emit_tool(w, t);
  }
  if (s.long_range) {
    const LongRange& lr = *s.long_range;
    w.key(0, "long_range", "");
    w.key(2, "length", lr.length);
    w.key(2, "cutoff", lr.cutoff);
    w.key(2, "exclusion", lr.exclusion);
    w.key(2, "pairs", "");
    for (const PairRule& r : lr.pairs) {
      std::string rule = std::string("- {between: ") + to_text(r.between);
      if (r.between == PairKind::Segments)
        rule += ", segments: [" + std::to_string(r.segments[0]) + ", " + std::to_string(r.segments[1]) + "]";
      rule += ", alpha: " + format_number(r.alpha) + ", beta: " + format_number(r.beta);
      if (r.cutoff > 0) rule += ", cutoff: " + format_number(r.cutoff);
      w.line(4, rule + "}");
    }
  }
  const Initial& init = s.initial;
  w.key(0, "initial", "");
  w.key(2, "displacement_gradient", flow(init.displacement_gradient));
  w.key(2, "velocity_gradient", flow(init.velocity_gradient));
  w.key(2, "center", flow(init.center));
  w.key(2, "seed",
        "{amplitude: " + format_number(init.seed_amplitude) +
            ", wavelength: " + flow({init.seed_wavelength_x, init.seed_wavelength_y}) + "}");
  w.key(0, "stages", "");
  for (const Stage& st : s.stages) emit_stage(w, st);
  w.key(0, "stability", "");
  w.key(2, "energy_error", s.stability.energy_error);
  w.key(2, "motion_per_step", s.stability.motion_per_step);
  w.key(0, "output", "");
  w.key(2, "frames", std::to_string(s.output.frames));
  w.key(2, "series_every", std::to_string(s.output.series_every));
  std::vector<std::string> fields;
  for (const std::string& f : s.output.fields) fields.push_back(f);
  w.key(2, "fields", enclose('[', join(fields), ']'));
  w.key(2, "node_stride", std::to_string(s.output.node_stride));
  if (s.output.region)
    w.key(2, "region", "{min: " + flow((*s.output.region)[0]) + ", max: " + flow((*s.output.region)[1]) + "}");
  w.key(2, "precision", s.output.single_precision ? "single" : "double");
  w.key(2, "check_free_space", to_text(s.output.check_free_space));
  w.key(2, "progress_seconds", s.output.progress_seconds);
  w.key(2, "checkpoint_every_steps", std::to_string(s.output.checkpoint_every_steps));
  w.key(2, "checkpoint_every_seconds", s.output.checkpoint_every_seconds);
  for (const std::string& text : derived) {
    // One comment line per line of text, so that the result stays valid YAML.
    std::size_t start = 0;
    for (;;) {
      const std::size_t nl = text.find('\n', start);
      w.line(0, "# " + text.substr(start, nl == std::string::npos ? nl : nl - start));
      if (nl == std::string::npos) break;
      start = nl + 1;
    }
  }
  return std::move(w).str();
}

}  // namespace peri
