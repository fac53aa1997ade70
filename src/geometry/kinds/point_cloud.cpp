// Point clouds of solids (`points: file`): a CSV file with the header x,y,z,volume or
// x,y,z,volume,material, one point a row; or an HDF5 file (.h5, .hdf5) with the 1D datasets x, y,
// z, volume and optionally material (strings), one point an index. Read while the scene is read,
// so that every problem of the file is an input error before anything is built:
// "<file>:<line>: bodies.<name>.points: ..." ("<file>: point <k>: ..." for HDF5).
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <numeric>
#include <sstream>

#include "common.hpp"
#include "peri/core/hdf5.hpp"

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

namespace {

struct CloudRow {
  CloudPoint p;
  long place;        // CSV: the line; HDF5: the point's index
  std::string material;  // "" without a material column
};

// HDF5 datasets of a point cloud: x, y, z, volume as doubles (any numeric type, 1D, one length),
// material as strings (fixed or variable length). InputError naming the file and dataset.
std::vector<CloudRow> read_h5_rows(const Value& v, const std::string& path, const std::string& key) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // failures are reported here, not on stderr
  if (H5Fis_hdf5(path.c_str()) <= 0)
    v.fail("cannot read the point cloud '" + path + "': not an HDF5 file");
  const H5Id file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) v.fail("cannot read the point cloud '" + path + "': HDF5 cannot open it");
  auto fail = [&](const std::string& what) { throw InputError(path + ": " + key + ": " + what); };
  auto open = [&](const char* name, bool required) {
    if (H5Lexists(file.get(), name, H5P_DEFAULT) <= 0) {
      if (required)
        fail(std::string("no dataset '") + name + "'; expected the 1D datasets x, y, z, volume (and optionally " +
             "material) of one length");
      return H5Id();
    }
    H5Id d(H5Dopen2(file.get(), name, H5P_DEFAULT), H5Dclose);
    if (!d.ok()) fail(std::string("'") + name + "' is not a dataset");
    return d;
  };
  auto length_of = [&](const H5Id& d, const char* name) {
    const H5Id space(H5Dget_space(d.get()), H5Sclose);
    hsize_t n = 0;
    if (!space.ok() || H5Sget_simple_extent_ndims(space.get()) != 1 ||
        H5Sget_simple_extent_dims(space.get(), &n, nullptr) != 1)
      fail(std::string("dataset '") + name + "': expected a 1D dataset, one value a point");
    return n;
  };
  hsize_t n = 0;
  std::vector<double> column[4];
  static const char* names[4] = {"x", "y", "z", "volume"};
  for (int c = 0; c < 4; ++c) {
    const H5Id d = open(names[c], true);
    const hsize_t len = length_of(d, names[c]);
    if (c == 0) n = len;
    if (len != n)
      fail(std::string("dataset '") + names[c] + "' has " + std::to_string(len) + " values, 'x' " +
           std::to_string(n) + "; expected one length");
    const H5Id type(H5Dget_type(d.get()), H5Tclose);
    const H5T_class_t cls = H5Tget_class(type.get());
    if (cls != H5T_FLOAT && cls != H5T_INTEGER)
      fail(std::string("dataset '") + names[c] + "': expected numbers (a float or integer type)");
    column[c].resize(n);
    if (n > 0 && H5Dread(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, column[c].data()) < 0)
      fail(std::string("dataset '") + names[c] + "': HDF5 cannot read it as doubles");
  }
  std::vector<std::string> material;
  if (const H5Id d = open("material", false); d.ok()) {
    if (length_of(d, "material") != n) fail("dataset 'material' does not have the length of 'x'; expected one length");
    const H5Id type(H5Dget_type(d.get()), H5Tclose);
    if (H5Tget_class(type.get()) != H5T_STRING) fail("dataset 'material': expected strings (material names)");
    material.resize(n);
    if (H5Tis_variable_str(type.get()) > 0) {
      const H5Id mem(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(mem.get(), H5T_VARIABLE);
      H5Tset_cset(mem.get(), H5Tget_cset(type.get()));  // (HDF5 converts neither UTF-8 nor ASCII to the other)
      std::vector<char*> text(n, nullptr);
      if (n > 0 && H5Dread(d.get(), mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, text.data()) < 0)
        fail("dataset 'material': HDF5 cannot read its strings");
      for (hsize_t k = 0; k < n; ++k) material[k] = text[k] ? text[k] : "";
      const H5Id space(H5Dget_space(d.get()), H5Sclose);
      H5Dvlen_reclaim(mem.get(), space.get(), H5P_DEFAULT, text.data());
    } else {
      const std::size_t size = H5Tget_size(type.get());
      const H5Id mem(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(mem.get(), size);
      H5Tset_strpad(mem.get(), H5T_STR_NULLPAD);
      H5Tset_cset(mem.get(), H5Tget_cset(type.get()));
      std::vector<char> text(n * size);
      if (n > 0 && H5Dread(d.get(), mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, text.data()) < 0)
        fail("dataset 'material': HDF5 cannot read its strings");
      for (hsize_t k = 0; k < n; ++k) {
        const char* t = &text[k * size];
        material[k] = trim(std::string(t, strnlen(t, size)));
      }
    }
  }
  std::vector<CloudRow> rows(n);
  for (hsize_t k = 0; k < n; ++k) {
    CloudRow& r = rows[k];
    r.place = static_cast<long>(k);
    auto at = [&](const std::string& what) {
      throw InputError(path + ": point " + std::to_string(k) + ": " + key + ": " + what);
    };
    for (int c = 0; c < 4; ++c) {
      const double x = column[c][k];
      if (!std::isfinite(x)) at(std::string("dataset ") + names[c] + ": expected a finite number, got " + format_number(x));
      if (x != 0 && std::fabs(x) < 2.2250738585072014e-308)
        at(std::string("dataset ") + names[c] + ": expected a number of magnitude 0 or at least 2.2e-308, got " +
           format_number(x));
    }
    if (!(column[3][k] > 0))
      at("dataset volume: expected a positive volume [m^3], got " + format_number(column[3][k]));
    r.p.x = {column[0][k], column[1][k], column[2][k]};
    r.p.volume = column[3][k];
    if (!material.empty()) {
      if (!scene_detail::valid_name(material[k]))
        at(std::string("dataset material: expected a material name ") + scene_detail::kNameRule + ", got " +
           scene_detail::quote_name(material[k]));
      r.material = material[k];
    }
  }
  if (rows.empty()) fail("the point cloud has no points (its datasets are empty)");
  return rows;
}

// Two points within 1e-8 of the points' size (the cube root of their median volume), as meshes
// refuse nodes within 1e-8 mean edges: one point given twice with round-off, whose bond would set
// a stable step of nothing (a point 1e-15 m from another: dt 2e-7 -> 1e-12 s). Hashed on cells of
// the points' size; the first twin in file order is named.
template <class Place>
void refuse_near_twins(const std::vector<CloudRow>& rows, Place place, const char* word, const std::string& key) {
  if (rows.size() < 2) return;
  std::vector<double> volumes;
  volumes.reserve(rows.size());
  for (const CloudRow& r : rows) volumes.push_back(r.p.volume);
  std::nth_element(volumes.begin(), volumes.begin() + static_cast<std::ptrdiff_t>(volumes.size() / 2), volumes.end());
  const double size = std::cbrt(volumes[volumes.size() / 2]), tol = 1e-8 * size;
  std::vector<Vec3> x;
  x.reserve(rows.size());
  for (const CloudRow& r : rows) x.push_back(r.p.x);
  const auto [repeat, twin] = first_close_pair(x, size, tol);
  if (repeat == rows.size()) return;
  const CloudRow& r = rows[repeat];
  throw InputError(place(r.place) + ": " + key + ": point (" + format_number(r.p.x[0]) + ", " +
                   format_number(r.p.x[1]) + ", " + format_number(r.p.x[2]) + ") within " + [&] {
                     std::ostringstream t;
                     t.precision(3);
                     t << tol;
                     return t.str();
                   }() + " m of " + word + " " + std::to_string(rows[twin].place) +
                   " (1e-8 of the points' size, the cube root of their median volume); expected each point once");
}

// What every cloud's rows go through: the materials named (b.cloud_materials, each at the place
// it first appears), no point twice (the first repeat in file order is named with its twin), no
// point of the body's material with a volume beyond the horizon's ball, and b.cloud: the rows of
// the body's material (all of them without a material column).
// place(k): a row's place in messages ("file:line", "file: point k"); word: what the twin is
// called ("line", "point"); column: what holds materials ("column", "dataset").
template <class Place>
void keep_cloud_rows(const Value& v, Body& b, const std::vector<CloudRow>& rows, Place place, const char* word,
                     const char* column) {
  const std::string key = "bodies." + b.name + ".points";
  for (const CloudRow& r : rows)
    if (!r.material.empty() && std::none_of(b.cloud_materials.begin(), b.cloud_materials.end(),
                                            [&](const auto& m) { return m.first == r.material; }))
      b.cloud_materials.emplace_back(r.material, place(r.place));
  // Duplicates: rows sorted by position (then place), neighbours compared.
  std::vector<std::size_t> order(rows.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t c) {
    return rows[a].p.x != rows[c].p.x ? rows[a].p.x < rows[c].p.x : rows[a].place < rows[c].place;
  });
  std::size_t repeat = rows.size(), twin = rows.size();
  for (std::size_t k = 1; k < order.size(); ++k)
    if (rows[order[k]].p.x == rows[order[k - 1]].p.x && order[k] < repeat) {
      repeat = order[k];
      twin = order[k - 1];
    }
  if (repeat < rows.size()) {
    const CloudRow& r = rows[repeat];
    throw InputError(place(r.place) + ": " + key + ": duplicate point (" + format_number(r.p.x[0]) + ", " +
                     format_number(r.p.x[1]) + ", " + format_number(r.p.x[2]) + "), the same as " + word + " " +
                     std::to_string(rows[twin].place) + "; expected each point once");
  }
  // A point stands for the material about it: a volume beyond the ball of the horizon is more than
  // its whole family spans (a volume in other units, or a stray value), and would set the stable
  // step of its neighbours to nothing (one point of 1e30 m^3 among points of 1e-9 m^3 at a 1 mm
  // spacing: dt 6.6e-25 s). Before the twins, whose tolerance is the median volume's.
  const double delta = b.horizon_value(), ball = 4.0 / 3.0 * std::numbers::pi * delta * delta * delta;
  auto own = [&](const CloudRow& r) { return r.material.empty() || r.material == b.material; };
  for (const CloudRow& r : rows)
    if (own(r) && r.p.volume > ball) {
      std::ostringstream t;
      t.precision(3);
      t << ball;
      throw InputError(place(r.place) + ": " + key + ": " + column + " volume: " + format_number(r.p.volume) +
                       " m^3 is more than the ball of the horizon (4/3 pi delta^3 = " + t.str() + " m^3, delta = " +
                       format_number(delta) + " m); expected a point's own volume, about spacing^3 (" +
                       format_number(b.spacing * b.spacing * b.spacing) + " m^3) for points a spacing apart");
    }
  refuse_near_twins(rows, place, word, key);
  for (const CloudRow& r : rows)
    if (own(r)) b.cloud.push_back(r.p);
  if (b.cloud.empty()) {
    std::vector<std::string> named;
    for (const auto& m : b.cloud_materials) named.push_back(m.first);
    v.fail("no row of the point cloud '" + b.points + "' has the body's material '" + b.material + "' in its material " +
           column + " (it names " + join(named) + ")");
  }
}

}  // namespace

void read_point_cloud(const Value& v, Body& b) {
  const std::string given = v.name();
  b.points = resolve_input_path(v, given);
  const std::string key = "bodies." + b.name + ".points";
  std::string ext = std::filesystem::path(b.points).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".h5" || ext == ".hdf5") {
    std::error_code ec;
    if (std::filesystem::is_directory(b.points, ec)) v.fail("cannot read the point cloud '" + b.points + "': a directory");
    if (!std::ifstream(b.points, std::ios::binary)) {
      const int err = errno;
      v.fail("cannot read the point cloud '" + b.points + "': " + std::strerror(err));
    }
    std::vector<CloudRow> rows = read_h5_rows(v, b.points, key);
    auto point_at = [&](long k) { return b.points + ": point " + std::to_string(k); };
    keep_cloud_rows(v, b, rows, point_at, "point", "dataset");
    return;
  }
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
  std::vector<CloudRow> rows;  // every row of the file (duplicates are checked over all of them)
  while (std::getline(in, text)) {
    ++line;
    if (line == 1 && text.starts_with(kUtf8Bom)) text.erase(0, kUtf8Bom.size());  // spreadsheets' "CSV UTF-8"
    const std::string t = trim(text);
    if (t.empty() || t[0] == '#') continue;  // blank lines and comments
    std::vector<std::string> cells = split(t);
    if (columns == 0) {
      const std::vector<std::string> four{"x", "y", "z", "volume"};
      std::vector<std::string> five = four;
      five.emplace_back("material");
      for (std::string& c : cells)  // X,Y,Z,Volume as well
        std::transform(c.begin(), c.end(), c.begin(), [](unsigned char ch) { return std::tolower(ch); });
      if (cells != four && cells != five)
        fail_at(line, "expected the header x,y,z,volume or x,y,z,volume,material, got " + shown(t));
      columns = cells.size();
      continue;
    }
    if (cells.size() != columns)
      fail_at(line, "expected " + std::to_string(columns) + " columns (" +
                        std::string(columns == 5 ? "x,y,z,volume,material" : "x,y,z,volume") + "), got " +
                        std::to_string(cells.size()));
    CloudRow r{{}, line, {}};
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
    if (columns == 5) {
      r.material = cells[4];
      if (!scene_detail::valid_name(r.material))
        fail_at(line, std::string("column material: expected a material name ") + scene_detail::kNameRule + ", got " +
                          scene_detail::quote_name(r.material));
    }
    rows.push_back(std::move(r));
  }
  if (in.bad()) v.fail("cannot read the point cloud '" + b.points + "': " + std::strerror(errno));
  if (columns == 0) v.fail("the point cloud '" + b.points + "' has no header line x,y,z,volume[,material]");
  if (rows.empty()) fail_at(line, "the point cloud has no points after its header");
  keep_cloud_rows(v, b, rows, [&](long l) { return b.points + ":" + std::to_string(l); }, "line", "column");
}

}  // namespace peri::kinds
