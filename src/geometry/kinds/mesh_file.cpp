// Mesh bodies (`mesh: file`): a triangle surface mesh for a membrane, a tetrahedral mesh for a
// solid, read through Gmsh's C API (the library loaded on first use) while the scene is read (on
// every rank alike), so that every problem of the file is an input error before anything is
// built. Nodes at the mesh's vertices, each with a third of its triangles' areas (a quarter of
// its tetrahedra's volumes).
#include <algorithm>
#include <cerrno>
#include <clocale>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <unordered_map>

#include "common.hpp"
#include "gmsh_library.hpp"
#include "mesh_scan.hpp"

namespace peri::kinds {
namespace {

using scene_detail::format_number;
using scene_detail::join;

// Gmsh's API between initialize and finalize, quiet (no terminal output, no configuration files),
// its messages logged. Gmsh sets the process's locale (LC_ALL from the environment, LC_NUMERIC
// "C"): restored when the session ends.
class GmshSession {
 public:
  explicit GmshSession(const GmshLibrary& g) : g_(g) {
    if (const char* l = std::setlocale(LC_ALL, nullptr)) locale_ = l;
    int ierr = 0;
    g_.initialize(0, nullptr, 0, &ierr);
    g_.check(ierr, "Gmsh cannot start");
    g_.option_set_number("General.Terminal", 0, &ierr);
    g_.logger_start(&ierr);
  }
  ~GmshSession() {
    int ierr = 0;
    g_.logger_stop(&ierr);
    g_.finalize(&ierr);
    if (!locale_.empty()) std::setlocale(LC_ALL, locale_.c_str());
  }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;

 private:
  const GmshLibrary& g_;
  std::string locale_;
};

// Runs Gmsh calls; what they throw (GmshLibrary::check throws Gmsh's message as a std::string)
// becomes `fail`'s.
template <class F, class Fail>
void gmsh_call(F f, Fail fail) {
  try {
    f();
  } catch (const InputError&) {
    throw;
  } catch (const std::string& e) {
    fail(e);
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

double norm(const double e[3]) { return std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]); }

std::string point_text(const Vec3& x) {
  return "(" + format_number(x[0]) + ", " + format_number(x[1]) + ", " + format_number(x[2]) + ")";
}

// Gmsh's element types a body of `dimension` takes: its cells (3-node triangles, 4-node
// tetrahedra) and the lower elements that carry physical groups (points, 2-node lines, and the
// triangles of a solid's faces).
constexpr int kPoint = 15, kLine = 1, kTriangle = 2, kTetrahedron = 4;

}  // namespace

const Key kMeshKey2 = {
    .name = "mesh", .fallback = "- (a grid sheet)",
    .doc = "instead of origin and size: a triangle surface mesh (relative to the scene file; a Gmsh .msh, version "
           "2.2 or 4.1, or an STL, known by its bytes), possibly curved. Nodes at its vertices in ascending tag order, each with "
           "a third of its triangles' areas (measure area x thickness); full weights within the horizon; spacing "
           "optional (default: the mesh's mean edge length). Its triangles carry `pressure`, oriented as in the "
           "file (right-hand rule: the pressure pushes along (b - a) x (c - a)). Only 3-node triangles, with "
           "points and 2-node lines for physical groups; nodes no triangle uses are not the body's; no degenerate "
           "triangle, no two nodes at one position. Named physical groups are regions "
           "(`region: {body: <name>, group: <group>}`). A mesh whose nodes lie at one z is flat (as a grid "
           "sheet), within round-off: a spread in z of at most 1e-6 of its size is set to one z, with a warning"};
const Key kMeshKey3 = {
    .name = "mesh", .fallback = "- (a box)",
    .doc = "instead of origin and size: a tetrahedral mesh (relative to the scene file; a Gmsh .msh, version 2.2 "
           "or 4.1). Nodes at its vertices in ascending tag order, each with a quarter of its tetrahedra's "
           "volumes; full weights within the horizon; spacing optional (default: the mesh's mean edge length). "
           "Only 4-node tetrahedra, with points, 2-node lines and 3-node triangles for physical groups; nodes no "
           "tetrahedron uses are not the body's; no degenerate or inverted tetrahedron, no two nodes at one "
           "position. Named physical groups are regions (`region: {body: <name>, group: <group>}`)"};
const Key kScaleKey = {.name = "scale", .fallback = "1",
                       .doc = "with mesh: the factor on the file's coordinates (e.g. 0.001 for a mesh in mm), > 0"};

namespace {

// A triangle mesh not exactly at one z: flat within kFlatMeshTolerance (its z set to the middle of
// the spread, MeshData::flattened), or a plane at a tilt (MeshData::tilted_normal), or curved.
void settle_plane(MeshData& m) {
  // A flat sheet whose z carries round-off (a CAD export, an STL's float32 coordinates) is made
  // flat: otherwise it is a curved sheet, whose crack tips are not tracked and whose in_plane
  // quasi-static stages do not hold it in its plane.
  double low[3] = {INFINITY, INFINITY, INFINITY}, high[3] = {-INFINITY, -INFINITY, -INFINITY}, largest = 0;
  for (const Vec3& x : m.nodes)
    for (int c = 0; c < 3; ++c) {
      low[c] = std::min(low[c], x[c]);
      high[c] = std::max(high[c], x[c]);
      largest = std::max(largest, std::fabs(x[c]));
    }
  const double spread = high[2] - low[2];
  const double size = std::max({high[0] - low[0], high[1] - low[1], largest});
  if (spread <= kFlatMeshTolerance * size) {
    const double z = 0.5 * (low[2] + high[2]);
    for (Vec3& x : m.nodes) x[2] = z;
    m.planar = true;
    m.flattened = spread;
  } else {
    // A plane sheet at a tilt (its normal off z): the normal of its largest triangle, kept when
    // every node lies within the tolerance of that triangle's plane.
    Vec3 normal{0, 0, 0};
    double largest_area2 = 0;
    std::size_t corner = 0;
    for (const auto& t : m.triangles) {
      const Vec3 &a = m.nodes[t[0]], &b = m.nodes[t[1]], &c = m.nodes[t[2]];
      const Vec3 n = {(b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]),
                      (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]),
                      (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])};
      const double area2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
      if (area2 > largest_area2) largest_area2 = area2, normal = n, corner = static_cast<std::size_t>(t[0]);
    }
    const double length = std::sqrt(largest_area2);
    if (length > 0) {
      for (double& c : normal) c /= length;
      const double extent = std::max({size, high[2] - low[2]});
      const Vec3& o = m.nodes[corner];
      const bool plane = std::all_of(m.nodes.begin(), m.nodes.end(), [&](const Vec3& x) {
        return std::fabs((x[0] - o[0]) * normal[0] + (x[1] - o[1]) * normal[1] + (x[2] - o[2]) * normal[2]) <=
               kFlatMeshTolerance * extent;
      });
      if (plane) m.tilted_normal = normal;
    }
  }
}

}  // namespace

void read_mesh_file(const Value& v, Body& b, int dimension) {
  namespace fs = std::filesystem;
  b.mesh = resolve_input_path(v, v.name());
  const std::string& path = b.mesh;
  const std::string key = "bodies." + b.name + ".mesh";
  const char* cells = dimension == 2 ? "triangles" : "tetrahedra";
  {
    std::ifstream probe(path, std::ios::binary);
    std::error_code ec;
    if (!probe || fs::is_directory(path, ec)) {
      const int err = errno;
      v.fail("cannot read the mesh '" + path + "': " + (fs::is_directory(path, ec) ? "a directory" : std::strerror(err)));
    }
  }
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".geo" || ext == ".geo_unrolled")
    v.fail("'" + path + "' is a Gmsh script, not a mesh (opening it would run it); mesh it first (gmsh -" +
           std::to_string(dimension) + " -format msh41 " + fs::path(path).filename().string() + ") and name the .msh");
  auto at_element = [&](std::size_t tag, const std::string& what) {
    throw InputError(path + ": element " + std::to_string(tag) + ": " + key + ": " + what);
  };
  std::string opened;  // the path Gmsh opens (a link to the file): named as the file in Gmsh's messages
  auto gmsh_failed = [&](std::string what) {
    for (std::size_t at; !opened.empty() && (at = what.find(opened)) != std::string::npos;) what.replace(at, opened.size(), path);
    v.fail("Gmsh cannot read the mesh '" + path + "': " + what);
  };
  // The file's own bytes first: Gmsh runs what it takes for a script (mesh_scan.hpp).
  const std::vector<int> accepted = dimension == 2 ? std::vector<int>{kPoint, kLine, kTriangle}
                                                   : std::vector<int>{kPoint, kLine, kTriangle, kTetrahedron};
  const MeshFileScan scan = scan_mesh_file(path, key, b.scale, accepted);

  auto data = std::make_shared<MeshData>();
  MeshData& m = *data;
  std::vector<std::size_t> node_tags;
  std::vector<double> coords;
  std::vector<int> types;
  std::vector<std::vector<std::size_t>> element_tags, element_nodes;
  struct Group {
    std::string name;
    std::vector<std::size_t> tags;
  };
  std::vector<Group> groups;
  {
    const GmshLibrary* lib = nullptr;
    gmsh_call([&] { lib = &GmshLibrary::get(); }, gmsh_failed);
    const GmshLibrary& g = *lib;
    const GmshSession session(g);
    const MeshLink link(path, scan.stl);
    opened = link.path();
    int ierr = 0;
    gmsh_call([&] { g.open(link.path().c_str(), &ierr), g.check(ierr, "cannot open it"); }, gmsh_failed);
    gmsh_call(
        [&] {
          {
            GmshArray<std::size_t> tags(g);
            GmshArray<double> xyz(g), parametric(g);
            g.get_nodes(&tags.data, &tags.size, &xyz.data, &xyz.size, &parametric.data, &parametric.size, -1, -1, 0,
                        0, &ierr);
            g.check(ierr, "cannot list its nodes");
            node_tags.assign(tags.begin(), tags.end());
            coords.assign(xyz.begin(), xyz.end());
          }
          {
            GmshArray<int> element_types(g);
            std::size_t** etags = nullptr;
            std::size_t** enodes = nullptr;
            GmshArray<std::size_t> etags_n(g), enodes_n(g);
            std::size_t etags_nn = 0, enodes_nn = 0;
            g.get_elements(&element_types.data, &element_types.size, &etags, &etags_n.data, &etags_nn, &enodes,
                           &enodes_n.data, &enodes_nn, -1, -1, &ierr);
            for (std::size_t k = 0; k < etags_nn; ++k) {
              element_tags.emplace_back(etags[k], etags[k] + etags_n.data[k]);
              g.free(etags[k]);
            }
            for (std::size_t k = 0; k < enodes_nn; ++k) {
              element_nodes.emplace_back(enodes[k], enodes[k] + enodes_n.data[k]);
              g.free(enodes[k]);
            }
            g.free(etags), g.free(enodes);
            g.check(ierr, "cannot list its elements");
            types.assign(element_types.begin(), element_types.end());
          }
          // An element type the body cannot take: the one of the highest dimension is named.
          int worst = -1, worst_dim = -1;
          std::string worst_name;
          for (std::size_t k = 0; k < types.size(); ++k) {
            const int t = types[k];
            const bool taken = t == kPoint || t == kLine || t == kTriangle || (dimension == 3 && t == kTetrahedron);
            if (taken || element_tags[k].empty()) continue;
            char* name = nullptr;
            int dim = 0, order = 0, nodes = 0, primary = 0;
            GmshArray<double> local(g);
            g.get_element_properties(t, &name, &dim, &order, &nodes, &local.data, &local.size, &primary, &ierr);
            const std::string type_name = g.take(name);
            g.check(ierr, "cannot describe an element type");
            if (dim > worst_dim) worst = static_cast<int>(k), worst_dim = dim, worst_name = type_name;
          }
          if (worst >= 0) {
            std::string why = dimension == 2 ? "a membrane's mesh takes 3-node triangles (and points and 2-node lines "
                                               "for physical groups)"
                                             : "a solid's mesh takes 4-node tetrahedra (and points, 2-node lines and "
                                               "3-node triangles for physical groups)";
            if (dimension == 2 && types[worst] == kTetrahedron) why += "; for a volume mesh use kind: solid";
            at_element(element_tags[worst].front(),
                       "unsupported element type '" + worst_name + "' (Gmsh type " + std::to_string(types[worst]) +
                           ", " + std::to_string(element_tags[worst].size()) + " of them, this the first); " + why);
          }
          // An element Gmsh dropped without a word (a second-order triangle among first-order
          // ones of one entity): named from the file.
          auto type_name = [&](int t) {
            char* name = nullptr;
            int dim = 0, order = 0, nodes = 0, primary = 0;
            GmshArray<double> local(g);
            g.get_element_properties(t, &name, &dim, &order, &nodes, &local.data, &local.size, &primary, &ierr);
            const std::string text = g.take(name);
            return ierr ? std::string("unknown") : text;
          };
          if (scan.unaccepted_tag)
            throw InputError(path + ":" + std::to_string(scan.unaccepted_line) + ": element " +
                             std::to_string(scan.unaccepted_tag) + ": " + key + ": unsupported element type '" +
                             type_name(scan.unaccepted_type) + "' (Gmsh type " + std::to_string(scan.unaccepted_type) +
                             ", which Gmsh drops where it shares an entity with " + cells + "); " +
                             (dimension == 2 ? "a membrane's mesh takes 3-node triangles (and points and 2-node "
                                               "lines for physical groups)"
                                             : "a solid's mesh takes 4-node tetrahedra (and points, 2-node lines "
                                               "and 3-node triangles for physical groups)"));
          std::size_t read = 0;
          for (const auto& tags : element_tags) read += tags.size();
          if (scan.stl && read != scan.elements)
            throw InputError(path + ": " + key + ": Gmsh kept " + std::to_string(read) + " of the file's " +
                             std::to_string(scan.elements) +
                             " facets (it drops facets whose corners coincide within its tolerance); expected "
                             "every facet a triangle of three distinct corners");
          if (!scan.stl && !scan.binary && read < scan.elements) {
            std::vector<std::size_t> tags_read;
            tags_read.reserve(read);
            for (const auto& tags : element_tags) tags_read.insert(tags_read.end(), tags.begin(), tags.end());
            std::sort(tags_read.begin(), tags_read.end());
            const MissingElement lost = first_element_not_read(path, tags_read);
            if (lost.tag)
              throw InputError(path + ":" + std::to_string(lost.line) + ": element " + std::to_string(lost.tag) + ": " +
                               key + ": Gmsh did not read this element (type '" + type_name(lost.type) +
                               "', Gmsh type " + std::to_string(lost.type) + "); expected every element of the file read");
          }
          GmshArray<int> physical(g);  // (dim, tag) pairs
          g.get_physical_groups(&physical.data, &physical.size, -1, &ierr);
          g.check(ierr, "cannot list its physical groups");
          for (std::size_t k = 0; k + 1 < physical.size; k += 2) {
            const int dim = physical.data[k], tag = physical.data[k + 1];
            char* name_text = nullptr;
            g.get_physical_name(dim, tag, &name_text, &ierr);
            const std::string name = g.take(name_text);
            g.check(ierr, "cannot name a physical group");
            if (name.empty()) continue;  // a group without a name cannot be named by a region
            GmshArray<std::size_t> tags(g);
            GmshArray<double> xyz(g);
            g.get_nodes_for_physical_group(dim, tag, &tags.data, &tags.size, &xyz.data, &xyz.size, &ierr);
            g.check(ierr, "cannot list a physical group's nodes");
            auto it = std::find_if(groups.begin(), groups.end(), [&](const Group& gr) { return gr.name == name; });
            if (it == groups.end()) it = groups.insert(groups.end(), Group{name, {}});
            it->tags.insert(it->tags.end(), tags.begin(), tags.end());
          }
        },
        gmsh_failed);
  }
  // The body's cells: their tags and corners' node tags.
  const int cell_type = dimension == 2 ? kTriangle : kTetrahedron;
  const std::size_t corners = dimension == 2 ? 3 : 4;
  std::vector<std::size_t> cell_tags, cell_nodes;
  for (std::size_t k = 0; k < types.size(); ++k)
    if (types[k] == cell_type) {
      cell_tags.insert(cell_tags.end(), element_tags[k].begin(), element_tags[k].end());
      cell_nodes.insert(cell_nodes.end(), element_nodes[k].begin(), element_nodes[k].end());
    }
  if (cell_tags.empty())
    v.fail("the mesh '" + path + "' has no " + cells + " (" +
           (dimension == 2 ? "expected a triangle surface mesh, e.g. gmsh -2" : "expected a tetrahedral mesh, e.g. gmsh -3") +
           "; Gmsh saves only the elements of physical groups when a file defines any: add the " +
           (dimension == 2 ? "surfaces" : "volumes") + " to one, or set Mesh.SaveAll = 1)");
  // The nodes: those the cells use, ascending by tag.
  std::unordered_map<std::size_t, std::size_t> position;  // tag -> index into node_tags
  position.reserve(node_tags.size());
  for (std::size_t i = 0; i < node_tags.size(); ++i) position.emplace(node_tags[i], i);
  std::vector<std::size_t> used(cell_nodes);
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  std::unordered_map<std::size_t, std::int64_t> index;  // tag -> body node
  index.reserve(used.size());
  m.tags = used;
  m.nodes.reserve(used.size());
  for (std::size_t tag : used) {
    const auto it = position.find(tag);
    if (it == position.end()) throw InputError(path + ": node " + std::to_string(tag) + ": " + key + ": an element uses it but the file gives no position");
    const double* x = &coords[3 * it->second];
    const Vec3 p{x[0] * b.scale, x[1] * b.scale, x[2] * b.scale};
    // (NaN corners would otherwise be reported as a degenerate element, huge ones too.)
    if (!std::all_of(p.begin(), p.end(), [](double c) { return std::isfinite(c) && std::fabs(c) < 1e100; }))
      throw InputError(path + ": node " + std::to_string(tag) + ": " + key + ": at " + point_text(p) +
                       "; expected finite coordinates below 1e100 m (after scale)");
    index.emplace(tag, static_cast<std::int64_t>(m.nodes.size()));
    m.nodes.push_back(p);
  }
  // A body below 1e-30 m across (a scale off by many orders): its areas' products would underflow
  // and read as degenerate elements.
  {
    Vec3 lo = m.nodes[0], hi = m.nodes[0];
    for (const Vec3& x : m.nodes)
      for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], x[d]), hi[d] = std::max(hi[d], x[d]);
    const double span = std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    if (span < 1e-30)
      v.fail("the mesh '" + path + "' spans " + format_number(span) + " m after scale " + format_number(b.scale) +
             "; expected a body at least 1e-30 m across (is scale the file's unit in metres?)");
  }
  // The cells: corners as body nodes; areas and volumes; each edge once.
  const std::size_t n_cells = cell_tags.size();
  m.measure.assign(m.nodes.size(), 0.0);
  m.element_tags = cell_tags;
  std::vector<std::pair<std::int64_t, std::int64_t>> edges;
  edges.reserve(n_cells * (dimension == 2 ? 3 : 6));
  for (std::size_t e = 0; e < n_cells; ++e) {
    std::array<std::int64_t, 4> c{};
    for (std::size_t k = 0; k < corners; ++k) c[k] = index.at(cell_nodes[corners * e + k]);
    const Vec3& a = m.nodes[c[0]];
    double longest = 0;
    for (std::size_t p = 0; p < corners; ++p)
      for (std::size_t q = p + 1; q < corners; ++q) {
        const Vec3 &x = m.nodes[c[p]], &y = m.nodes[c[q]];
        const double d[3] = {y[0] - x[0], y[1] - x[1], y[2] - x[2]};
        longest = std::max(longest, norm(d));
        edges.emplace_back(std::min(c[p], c[q]), std::max(c[p], c[q]));
      }
    const double e1[3] = {m.nodes[c[1]][0] - a[0], m.nodes[c[1]][1] - a[1], m.nodes[c[1]][2] - a[2]};
    const double e2[3] = {m.nodes[c[2]][0] - a[0], m.nodes[c[2]][1] - a[1], m.nodes[c[2]][2] - a[2]};
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    std::string corner_tags;
    for (std::size_t k = 0; k < corners; ++k) corner_tags += (k ? ", " : "") + std::to_string(cell_nodes[corners * e + k]);
    if (dimension == 2) {
      const double area = 0.5 * norm(n);
      // A triangle whose area is below 1e-10 of its longest edge squared: collinear corners.
      if (!(area > 1e-10 * longest * longest))
        at_element(cell_tags[e], "degenerate triangle (zero area) with nodes " + corner_tags +
                                     "; expected three corners not on one line");
      for (std::size_t k = 0; k < 3; ++k) m.measure[c[k]] += area / 3.0;
      m.total += area;
      m.triangles.push_back({c[0], c[1], c[2]});
    } else {
      const Vec3& d = m.nodes[c[3]];
      const double e3[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
      const double volume = (n[0] * e3[0] + n[1] * e3[1] + n[2] * e3[2]) / 6.0;
      if (!(std::fabs(volume) > 1e-10 * longest * longest * longest))
        at_element(cell_tags[e], "degenerate tetrahedron (zero volume) with nodes " + corner_tags +
                                     "; expected four corners not in one plane");
      if (volume < 0)
        at_element(cell_tags[e], "inverted tetrahedron (negative volume " + format_number(volume) + " m^3) with nodes " +
                                     corner_tags + "; expected Gmsh's order, (b - a) x (c - a) . (d - a) > 0");
      for (std::size_t k = 0; k < 4; ++k) m.measure[c[k]] += volume / 4.0;
      m.total += volume;
      m.tets.push_back(c);
    }
  }
  // One cell given twice (the same corners in any order) would count its area or volume twice.
  {
    std::vector<std::pair<std::array<std::int64_t, 4>, std::size_t>> sorted(n_cells);
    for (std::size_t e = 0; e < n_cells; ++e) {
      std::array<std::int64_t, 4> c{};
      if (dimension == 2) std::copy(m.triangles[e].begin(), m.triangles[e].end(), c.begin());
      else c = m.tets[e];
      std::sort(c.begin(), c.begin() + static_cast<std::ptrdiff_t>(corners));
      sorted[e] = {c, e};
    }
    std::sort(sorted.begin(), sorted.end());
    for (std::size_t q = 1; q < n_cells; ++q)
      if (sorted[q].first == sorted[q - 1].first) {
        const std::size_t first = std::min(sorted[q].second, sorted[q - 1].second);
        const std::size_t again = std::max(sorted[q].second, sorted[q - 1].second);
        at_element(cell_tags[again], "the same nodes as element " + std::to_string(cell_tags[first]) + "; expected each " +
                                         (dimension == 2 ? "triangle" : "tetrahedron") + " once");
      }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  double sum = 0;
  for (const auto& [p, q] : edges) {
    const double d[3] = {m.nodes[q][0] - m.nodes[p][0], m.nodes[q][1] - m.nodes[p][1], m.nodes[q][2] - m.nodes[p][2]};
    sum += norm(d);
  }
  m.mean_edge = sum / static_cast<double>(edges.size());
  // Two nodes closer than 1e-8 mean edges: one point given twice (hashed on cells of an edge).
  if (const auto [i, j] = first_close_pair(m.nodes, m.mean_edge, 1e-8 * m.mean_edge); i < m.nodes.size())
    throw InputError(path + ": node " + std::to_string(m.tags[i]) + ": " + key + ": at " + point_text(m.nodes[i]) +
                     ", the position of node " + std::to_string(m.tags[j]) +
                     " too (within 1e-8 mean edge lengths); expected each point once (merge the duplicate nodes, "
                     "e.g. Gmsh's Coherence Mesh)");
  m.planar = std::all_of(m.nodes.begin(), m.nodes.end(), [&](const Vec3& x) { return x[2] == m.nodes[0][2]; });
  if (dimension == 2 && !m.planar) settle_plane(m);
  for (const Group& g : groups) {
    MeshGroup out{g.name, {}};
    for (std::size_t tag : g.tags)
      if (const auto it = index.find(tag); it != index.end()) out.nodes.push_back(it->second);
    std::sort(out.nodes.begin(), out.nodes.end());
    out.nodes.erase(std::unique(out.nodes.begin(), out.nodes.end()), out.nodes.end());
    m.groups.push_back(std::move(out));
  }
  if (!b.spacing_given) b.spacing = m.mean_edge;
  b.mesh_data = std::move(data);
}

void check_mesh_orientation(const Body& b) {
  const MeshData& m = *b.mesh_data;
  std::map<std::pair<std::int64_t, std::int64_t>, std::size_t> directed;  // edge a -> b: its triangle
  for (std::size_t e = 0; e < m.triangles.size(); ++e)
    for (int k = 0; k < 3; ++k) {
      const std::pair<std::int64_t, std::int64_t> edge{m.triangles[e][k], m.triangles[e][(k + 1) % 3]};
      const auto [it, fresh] = directed.emplace(edge, e);
      if (!fresh)
        throw InputError(b.mesh + ": element " + std::to_string(m.element_tags[e]) + ": bodies." + b.name +
                         ".mesh: runs along the edge from node " + std::to_string(m.tags[edge.first]) + " to node " +
                         std::to_string(m.tags[edge.second]) + " in the same direction as element " +
                         std::to_string(m.element_tags[it->second]) +
                         ": the triangles are not oriented alike, which the pressure (along (b - a) x (c - a)) "
                         "needs; expected a consistently oriented surface (Gmsh: ReorientMesh, or "
                         "`Reverse Surface`)");
    }
}

}  // namespace peri::kinds
