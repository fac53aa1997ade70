// Irregular node sets for the tests and benchmarks: grids of spacing h whose nodes are each moved
// by up to `jitter` spacings along every axis (uniform, from a fixed seed), written into the
// temporary directory under `name`. A sheet is a Gmsh .msh 2.2 triangle mesh (two triangles per
// square), a block a point-cloud CSV (x, y, z, volume: the cell's h^3). Read by peridrive as
// `mesh:` and `points:` bodies, their rows have no family pattern (FamilyPatterns' free rows).
#pragma once
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

namespace peri::fixtures {

/// An nx x ny sheet of jittered nodes as a triangle mesh; returns the file's path.
inline std::string write_jittered_sheet(const std::string& name, int nx, int ny, double jitter, unsigned seed,
                                        double h = 1e-3) {
  const std::string path = (std::filesystem::temp_directory_path() / name).string();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-jitter, jitter);
  std::ofstream out(path);
  out << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" << nx * ny << "\n";
  char line[128];
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double x = h * (i + U(rng));
      const double y = h * (j + U(rng));
      std::snprintf(line, sizeof line, "%d %.17g %.17g 0\n", j * nx + i + 1, x, y);
      out << line;
    }
  out << "$EndNodes\n$Elements\n" << 2 * (nx - 1) * (ny - 1) << "\n";
  int e = 0;
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const int a = j * nx + i + 1, b = a + 1, c = a + nx + 1, d = a + nx;
      out << ++e << " 2 0 " << a << ' ' << b << ' ' << c << "\n" << ++e << " 2 0 " << a << ' ' << c << ' ' << d << "\n";
    }
  out << "$EndElements\n";
  return path;
}

/// An nx x ny x nz block of jittered points as a point cloud; returns the file's path.
inline std::string write_jittered_cloud(const std::string& name, int nx, int ny, int nz, double jitter,
                                        unsigned seed, double h = 1e-3) {
  const std::string path = (std::filesystem::temp_directory_path() / name).string();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-jitter, jitter);
  std::ofstream out(path);
  out << "x,y,z,volume\n";
  char line[160];
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const double x = h * (i + U(rng));
        const double y = h * (j + U(rng));
        const double z = h * (k + U(rng));
        std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,%.17g\n", x, y, z, h * h * h);
        out << line;
      }
  return path;
}

}  // namespace peri::fixtures
