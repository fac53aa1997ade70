// Point clouds of solids (`points: file`): a CSV file with the header x,y,z,volume or
// x,y,z,volume,material, one point a row. Read while the scene is read, so that every problem of
// the file is an input error before anything is built: "<file>:<line>: bodies.<name>.points: ...".
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>

#include "common.hpp"

namespace peri::kinds {
namespace {

using scene_detail::format_number;
using scene_detail::join;

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(trim(cell));
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

// The text of a cell in a message: quoted, cut after 40 characters.
std::string shown(const std::string& s) { return "'" + (s.size() > 40 ? s.substr(0, 40) + "..." : s) + "'"; }

}  // namespace

std::string resolve_input_path(const Value& v, const std::string& path) {
  namespace fs = std::filesystem;
  const SourceLoc where = v.where();
  // Relative to the scene file's folder; a value set by --set (or a scene without a file) is
  // relative to the working directory.
  fs::path base = where.line > 0 ? fs::path(where.file).parent_path() : fs::path();
  std::error_code ec;
  fs::path full = fs::absolute(base / fs::path(path), ec);
  if (ec) full = base / fs::path(path);
  return full.lexically_normal().string();
}

void read_point_cloud(const Value& v, Body& b) {
  auto& materials = b.cloud_materials;
  const std::string given = v.name();
  b.points = resolve_input_path(v, given);
  const std::string key = "bodies." + b.name + ".points";
  std::ifstream in(b.points, std::ios::binary);
  if (!in) {
    const int err = errno;
    std::error_code ec;
    const bool folder = std::filesystem::is_directory(b.points, ec);
    v.fail("cannot read the point cloud '" + b.points + "': " + (folder ? "a directory" : std::strerror(err)));
  }
  auto fail_at = [&](long line, const std::string& what) {
    throw InputError(b.points + ":" + std::to_string(line) + ": " + key + ": " + what);
  };
  std::string text;
  long line = 0;
  std::size_t columns = 0;  // 4 or 5, from the header
  struct Row {
    CloudPoint p;
    long line;
  };
  std::vector<Row> rows;         // every row of the file (duplicates are checked over all of them)
  std::vector<char> taken;       // whether this body takes the row
  while (std::getline(in, text)) {
    ++line;
    const std::string t = trim(text);
    if (t.empty() || t[0] == '#') continue;  // blank lines and comments
    const std::vector<std::string> cells = split(t);
    if (columns == 0) {
      const std::vector<std::string> four{"x", "y", "z", "volume"};
      std::vector<std::string> five = four;
      five.emplace_back("material");
      if (cells != four && cells != five)
        fail_at(line, "expected the header x,y,z,volume or x,y,z,volume,material, got " + shown(t));
      columns = cells.size();
      continue;
    }
    if (cells.size() != columns)
      fail_at(line, "expected " + std::to_string(columns) + " columns (" +
                        std::string(columns == 5 ? "x,y,z,volume,material" : "x,y,z,volume") + "), got " +
                        std::to_string(cells.size()));
    Row r{{}, line};
    static const char* names[4] = {"x", "y", "z", "volume"};
    double xs[4];
    for (int c = 0; c < 4; ++c) {
      const scene_detail::NumberText status = scene_detail::parse_number(cells[c], xs[c]);
      if (status == scene_detail::NumberText::NotFinite)
        fail_at(line, std::string("column ") + names[c] + ": expected a finite number, got " + shown(cells[c]));
      if (status != scene_detail::NumberText::Ok)
        fail_at(line, std::string("column ") + names[c] + ": expected a number" +
                          (status == scene_detail::NumberText::Subnormal ? " of magnitude 0 or at least 2.2e-308" : "") +
                          ", got " + shown(cells[c]));
    }
    if (!(xs[3] > 0)) fail_at(line, "column volume: expected a positive volume [m^3], got " + shown(cells[3]));
    r.p.x = {xs[0], xs[1], xs[2]};
    r.p.volume = xs[3];
    bool mine = true;
    if (columns == 5) {
      const std::string& mat = cells[4];
      if (!scene_detail::valid_name(mat))
        fail_at(line, std::string("column material: expected a material name ") + scene_detail::kNameRule + ", got " +
                          scene_detail::quote_name(mat));
      mine = mat == b.material;
      if (std::none_of(materials.begin(), materials.end(), [&](const auto& m) { return m.first == mat; }))
        materials.emplace_back(mat, line);
    }
    rows.push_back(r);
    taken.push_back(mine ? 1 : 0);
  }
  if (in.bad()) v.fail("cannot read the point cloud '" + b.points + "': " + std::strerror(errno));
  if (columns == 0) v.fail("the point cloud '" + b.points + "' has no header line x,y,z,volume[,material]");
  if (rows.empty()) fail_at(line, "the point cloud has no points after its header");
  // Duplicates: rows sorted by position (then line), neighbours compared.
  std::vector<std::size_t> order(rows.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t c) {
    return rows[a].p.x != rows[c].p.x ? rows[a].p.x < rows[c].p.x : rows[a].line < rows[c].line;
  });
  // The first row (in file order) that repeats an earlier one is reported, with that earlier one.
  std::size_t repeat = rows.size(), twin = rows.size();
  for (std::size_t k = 1; k < order.size(); ++k)
    if (rows[order[k]].p.x == rows[order[k - 1]].p.x && order[k] < repeat) {
      repeat = order[k];
      twin = order[k - 1];
    }
  if (repeat < rows.size()) {
    const Row& r = rows[repeat];
    fail_at(r.line, "duplicate point (" + format_number(r.p.x[0]) + ", " + format_number(r.p.x[1]) + ", " +
                        format_number(r.p.x[2]) + "), the same as line " + std::to_string(rows[twin].line) +
                        "; expected each point once");
  }
  for (std::size_t k = 0; k < rows.size(); ++k)
    if (taken[k]) b.cloud.push_back(rows[k].p);
  if (b.cloud.empty()) {
    std::vector<std::string> named;
    for (const auto& m : materials) named.push_back(m.first);
    v.fail("no row of the point cloud '" + b.points + "' has the body's material '" + b.material +
           "' in its material column (it names " + join(named) + ")");
  }
}

}  // namespace peri::kinds
