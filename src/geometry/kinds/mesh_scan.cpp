#include "mesh_scan.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "peri/core/error.hpp"
#include "peri/scene/located_yaml.hpp"

namespace peri::kinds {
namespace {

namespace fs = std::filesystem;
using scene_detail::format_number;

// A binary STL: an 80-byte header, a 4-byte facet count, 50 bytes per facet (normal, three
// corners as 32-bit floats, 2 attribute bytes).
constexpr std::size_t kStlHeader = 84, kStlFacet = 50;

bool starts_with_word(const std::string& s, const char* word) {
  std::size_t i = 0;
  while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
  return s.compare(i, std::strlen(word), word) == 0;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// One STL corner: finite, below 1e100 m after scale, and unlike the facet's other corners.
struct Corner {
  double x[3];
};
std::string corner_text(const Corner& c) {
  // Appended, not "(" + ...: GCC 12 warns of a false -Wstringop-overflow on operator+(const char*, string&&).
  std::string s = "(";
  s.append(format_number(c.x[0])).append(", ").append(format_number(c.x[1])).append(", ");
  s.append(format_number(c.x[2])).append(")");
  return s;
}
// Throws `fail(what)` for a facet whose corners Gmsh would drop it for.
template <class Fail>
void check_facet(const Corner (&c)[3], double scale, Fail fail) {
  for (const Corner& p : c)
    for (double x : p.x)
      if (!std::isfinite(x) || !(std::fabs(x * scale) < 1e100))
        fail("a corner at " + corner_text(p) + "; expected finite coordinates below 1e100 m (after scale)");
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b)
      if (std::equal(c[a].x, c[a].x + 3, c[b].x))
        fail("degenerate facet: two corners at " + corner_text(c[a]) + "; expected three distinct corners");
}

void scan_binary_stl(std::ifstream& in, const std::string& path, const std::string& key, double scale, std::size_t facets) {
  in.clear();
  in.seekg(static_cast<std::streamoff>(kStlHeader));
  char record[kStlFacet];
  for (std::size_t f = 1; f <= facets; ++f) {
    in.read(record, kStlFacet);
    Corner c[3];
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) {
        float v;
        std::memcpy(&v, record + 12 + 12 * k + 4 * d, 4);  // after the normal
        c[k].x[d] = v;
      }
    check_facet(c, scale, [&](const std::string& what) {
      throw InputError(path + ": facet " + std::to_string(f) + ": " + key + ": " + what);
    });
  }
}

void scan_text_stl(std::ifstream& in, const std::string& path, const std::string& key, double scale, MeshFileScan& s) {
  in.clear();
  in.seekg(0);
  std::string line;
  std::size_t number = 0, facet_line = 0;
  int corners = -1;  // within a facet: its corners so far; -1 outside one
  Corner c[3];
  auto fail = [&](std::size_t at, const std::string& what) {
    throw InputError(path + ":" + std::to_string(at) + ": " + key + ": " + what);
  };
  while (std::getline(in, line)) {
    ++number;
    std::istringstream words(line);
    std::string word;
    if (!(words >> word)) continue;
    word = lower(word);
    if (word == "facet") {
      if (corners >= 0) fail(number, "a facet before the one of line " + std::to_string(facet_line) + " ended");
      corners = 0, facet_line = number;
    } else if (word == "vertex") {
      if (corners < 0 || corners == 3) fail(number, "a vertex outside a facet's three corners");
      std::string t[3];
      words >> t[0] >> t[1] >> t[2];
      for (int d = 0; d < 3; ++d) {
        char* end = nullptr;
        c[corners].x[d] = std::strtod(t[d].c_str(), &end);
        if (t[d].empty() || *end) fail(number, "'" + line + "': expected vertex x y z");
      }
      ++corners;
    } else if (word == "endfacet") {
      if (corners != 3)
        fail(facet_line, "a facet with " + std::to_string(std::max(corners, 0)) + " corners; expected 3");
      ++s.elements;
      check_facet(c, scale, [&](const std::string& what) {
        fail(facet_line, "facet " + std::to_string(s.elements) + ": " + what);
      });
      corners = -1;
    }
  }
  if (corners >= 0) fail(facet_line, "the file ends within this facet");
}

// A text .msh's elements, one call per element: (tag, type, line). Version 2: "$Elements", a
// count, then "tag type ..." lines; version 4: "$Elements", "blocks elements min max", then per
// block "dim entity type count" and `count` lines "tag nodes...".
template <class F>
void each_text_element(std::ifstream& in, int version, F f) {
  in.clear();
  in.seekg(0);
  std::string line;
  std::size_t number = 0;
  bool inside = false;
  while (std::getline(in, line)) {
    ++number;
    if (!inside) {
      inside = starts_with_word(line, "$Elements");
      if (inside) {
        if (!std::getline(in, line)) return;
        ++number;
        if (version == 4) {
          std::size_t blocks = 0;
          std::istringstream(line) >> blocks;
          for (std::size_t b = 0; b < blocks && std::getline(in, line); ++b) {
            ++number;
            int dim = 0, entity = 0, type = 0;
            std::size_t count = 0;
            std::istringstream(line) >> dim >> entity >> type >> count;
            for (std::size_t e = 0; e < count && std::getline(in, line); ++e) {
              ++number;
              std::size_t tag = 0;
              std::istringstream(line) >> tag;
              if (!f(tag, type, number)) return;
            }
          }
          return;
        }
      }
      continue;
    }
    if (starts_with_word(line, "$EndElements")) return;
    std::size_t tag = 0;
    int type = 0;
    std::istringstream(line) >> tag >> type;
    if (!f(tag, type, number)) return;
  }
}

// A text .msh's physical names ("$PhysicalNames", a count, then "dim tag \"name\"" lines): two
// groups of one dimension under one name, of which Gmsh keeps one (the other's nodes would not be
// the region's), refused naming both lines.
void check_physical_names(std::ifstream& in, const std::string& path, const std::string& key) {
  in.clear();
  in.seekg(0);
  std::string line;
  std::size_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (!starts_with_word(line, "$PhysicalNames")) continue;
    std::map<std::pair<int, std::string>, std::size_t> seen;  // (dim, name) -> line
    while (std::getline(in, line)) {
      ++number;
      if (starts_with_word(line, "$EndPhysicalNames")) return;
      const std::size_t open = line.find('"'), close = line.rfind('"');
      if (open == std::string::npos || close <= open) continue;
      int dim = -1;
      std::istringstream(line.substr(0, open)) >> dim;
      const std::string name = line.substr(open + 1, close - open - 1);
      const auto [it, fresh] = seen.emplace(std::make_pair(dim, name), number);
      if (!fresh)
        throw InputError(path + ":" + std::to_string(number) + ": " + key + ": a second physical group of dimension " +
                         std::to_string(dim) + " named '" + name + "' (the first at line " + std::to_string(it->second) +
                         "), whose nodes Gmsh would leave out of the name; expected one group per name and "
                         "dimension (merge them into one)");
    }
    return;
  }
}

// The text .msh's "$MeshFormat" line's version (2 or 4) and whether it is binary.
void read_msh_format(std::ifstream& in, const std::string& path, const std::string& key, int& version, bool& binary) {
  in.clear();
  in.seekg(0);
  std::string line;
  std::getline(in, line);  // $MeshFormat
  std::getline(in, line);
  double v = 0;
  int file_type = -1;
  std::istringstream(line) >> v >> file_type;
  version = static_cast<int>(std::floor(v));
  binary = file_type == 1;
  if ((version != 2 && version != 4) || (file_type != 0 && file_type != 1))
    throw InputError(path + ":2: " + key + ": a Gmsh mesh of format '" + line +
                     "'; expected version 2.2 or 4.1 (gmsh FILE -0 -format msh41 -o NEW.msh converts it)");
}

}  // namespace

MeshFileScan scan_mesh_file(const std::string& path, const std::string& key, double scale,
                            const std::vector<int>& accepted) {
  MeshFileScan s;
  std::ifstream in(path, std::ios::binary);
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(path, ec);
  std::string head(kStlHeader, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  // A binary STL is known by its size; its header may start with "solid" as a text STL does.
  if (!ec && head.size() == kStlHeader) {
    std::uint32_t facets = 0;
    std::memcpy(&facets, head.data() + 80, 4);
    if (size == kStlHeader + kStlFacet * static_cast<std::uintmax_t>(facets) && facets > 0) {
      s.stl = s.binary = true;
      s.elements = facets;
      scan_binary_stl(in, path, key, scale, facets);
      return s;
    }
  }
  if (head.compare(0, 11, "$MeshFormat") == 0) {
    int version = 0;
    read_msh_format(in, path, key, version, s.binary);
    if (s.binary) return s;  // (its elements are not counted here)
    check_physical_names(in, path, key);
    each_text_element(in, version, [&](std::size_t tag, int type, std::size_t line) {
      ++s.elements;
      if (!s.unaccepted_tag && std::find(accepted.begin(), accepted.end(), type) == accepted.end())
        s.unaccepted_tag = tag, s.unaccepted_type = type, s.unaccepted_line = line;
      return true;
    });
    return s;
  }
  if (starts_with_word(lower(head), "solid")) {
    s.stl = true;
    scan_text_stl(in, path, key, scale, s);
    return s;
  }
  throw InputError(path + ": " + key +
                   ": neither a Gmsh mesh (a .msh file starts with $MeshFormat) nor an STL (text starting "
                   "with 'solid', or binary of 84 + 50 bytes per facet); Gmsh would read other text as a "
                   "script and run it. Convert the mesh first, e.g. gmsh FILE -0 -format msh41 -o NEW.msh, "
                   "or meshio convert FILE NEW.msh");
}

MissingElement first_element_not_read(const std::string& path, const std::vector<std::size_t>& tags_read) {
  std::ifstream in(path, std::ios::binary);
  int version = 0;
  bool binary = false;
  MissingElement m;
  try {
    read_msh_format(in, path, "", version, binary);
  } catch (const InputError&) {
    return m;
  }
  if (binary) return m;
  each_text_element(in, version, [&](std::size_t tag, int type, std::size_t line) {
    if (std::binary_search(tags_read.begin(), tags_read.end(), tag)) return true;
    m = {tag, type, line};
    return false;
  });
  return m;
}

MeshLink::MeshLink(const std::string& path, bool stl) {
  std::error_code ec;
  fs::path base = fs::temp_directory_path(ec);
  if (ec) base = "/tmp";
  std::string dir_template = (base / "peridrive-mesh-XXXXXX").string();
  if (!mkdtemp(dir_template.data()))
    throw InputError(path + ": cannot make a private folder to open the mesh from (" + dir_template + ": " +
                     std::strerror(errno) + "); set TMPDIR to a writable folder");
  dir_ = dir_template;
  link_ = dir_ + (stl ? "/mesh.stl" : "/mesh.msh");
  fs::create_symlink(fs::absolute(path), link_, ec);
  if (ec) {
    fs::remove_all(dir_, ec);
    throw InputError(path + ": cannot link the mesh into " + dir_ + " to open it: " + ec.message());
  }
}

MeshLink::~MeshLink() {
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

}  // namespace peri::kinds
