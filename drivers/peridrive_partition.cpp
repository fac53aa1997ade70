// peridrive-partition: partition a scene into P parts without running it, and report what a
// P-rank run would carry per rank (owned nodes and bonds, ghosts, neighbour ranks, the bonds of
// rows next to a ghost, the largest message), the quality (edge cut, balance = largest part's
// bonds / mean) and what the partitioner costs (time, peak memory above its input). A run on P
// ranks reports the same halo figures in its summary.json ("halo"). Feeds cluster/scaling_model.py.
//
//   peridrive-partition scene.yaml [--set KEY=VALUE ...] --parts 2,4,8,...,4096
//                       [--method rcb,cells,bonds] [--cells-per-part 64] [--line-weight 2] [--csv FILE]
//
// One process, no MPI ranks needed: each partitioner runs serially, exactly as on rank 0 of a run
// (rcb: recursive coordinate bisection; cells: METIS on the coarse cell graph; bonds: METIS on the
// full bond graph, built inside the measurement), in a forked child so that its peak memory is its own.
#include <mpi.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "peri/partition/partition.hpp"
#include "peri/core/resources.hpp"
#include "peri/core/format.hpp"

namespace {

long peak_rss_kb() {
  rusage r{};
  getrusage(RUSAGE_SELF, &r);
  return r.ru_maxrss;
}

struct Measured {
  std::vector<int> part;
  double seconds = 0, peak_bytes = 0;
  long long graph_vertices = 0;
};

// Moves all `bytes` through a pipe with `io` (read or write), which may move fewer at a time.
template <class Io, class Byte>
bool transfer_all(Io io, int fd, Byte* p, std::size_t bytes) {
  while (bytes > 0) {
    const ssize_t r = io(fd, p, bytes);
    if (r <= 0) return false;
    p += r;
    bytes -= static_cast<std::size_t>(r);
  }
  return true;
}
bool read_all(int fd, void* data, std::size_t bytes) { return transfer_all(read, fd, static_cast<char*>(data), bytes); }
bool write_all(int fd, const void* data, std::size_t bytes) {
  return transfer_all(write, fd, static_cast<const char*>(data), bytes);
}

// Run one partitioner in a forked child: its time, its peak resident memory above the memory at
// the fork (the scene's nodes and cell list are its input, shared), and the parts.
Measured measure(const peri::Nodes& nodes, const peri::CellList& cells, int parts, peri::PartitionMethod method,
                 int cells_per_part, int line_weight) {
  int fds[2];
  if (pipe(fds) != 0) throw peri::Error("pipe failed");
  const std::int64_t n = nodes.size();
  const pid_t pid = fork();
  if (pid < 0) throw peri::Error("fork failed");
  if (pid == 0) {
    close(fds[0]);
    const double base = peri::process_memory().current;
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<int> part(n);
    long long vertices = n;
    int status = 0;
    try {
      if (method == peri::PartitionMethod::Rcb) {
        part = peri::rcb_parts(nodes, parts, line_weight);
      } else if (method == peri::PartitionMethod::Cells) {
        const peri::CellGraph g = peri::cell_graph(nodes, cells, peri::cell_size_for(nodes, parts, cells_per_part));
        const std::vector<int> cp = peri::metis_kway(g, parts, line_weight);
        for (std::int64_t i = 0; i < n; ++i) part[i] = cp[g.cell_of[i]];
        vertices = g.cells;
      } else {
        std::int64_t cut = 0;
        part = peri::metis_kway(peri::bond_graph(nodes, cells), parts, cut);
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "peridrive-partition: error: %s\n", e.what());
      status = 1;
    }
    double head[2] = {std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
                      peri::process_memory().peak - base};
    const bool ok = status == 0 && write_all(fds[1], head, sizeof head) && write_all(fds[1], &vertices, sizeof vertices) &&
                    write_all(fds[1], part.data(), part.size() * sizeof(int));
    close(fds[1]);
    _exit(ok ? 0 : 1);
  }
  close(fds[1]);
  Measured m;
  double head[2];
  m.part.resize(n);
  const bool ok = read_all(fds[0], head, sizeof head) && read_all(fds[0], &m.graph_vertices, sizeof m.graph_vertices) &&
                  read_all(fds[0], m.part.data(), m.part.size() * sizeof(int));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (!ok || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw peri::Error(std::string("the ") + peri::to_string(method) + " partitioner failed for " + std::to_string(parts) + " parts");
  m.seconds = head[0];
  m.peak_bytes = head[1];
  return m;
}

std::vector<int> parse_parts(const std::string& text) {
  std::vector<int> parts;
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) {
    int p = 0;
    try {
      p = std::stoi(item);
    } catch (const std::exception&) {
      p = 0;
    }
    if (p < 2) throw peri::InputError("--parts " + text + ": expected a comma list of integers >= 2, got '" + item + "'");
    parts.push_back(p);
  }
  if (parts.empty()) throw peri::InputError("--parts: expected a comma list of integers >= 2");
  return parts;
}

int run(int argc, char** argv) {
  std::string scene_path, csv_path;
  std::vector<peri::PartitionMethod> methods{peri::PartitionMethod::Cells, peri::PartitionMethod::Bonds};
  bool default_methods = true;
  int cells_per_part = 64, line_weight = peri::kLineWeight;
  std::vector<peri::Override> overrides;
  std::vector<int> parts{2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096};
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    auto value = [&]() -> std::string {
      if (k + 1 >= argc) throw peri::InputError("option " + a + " needs a value");
      return argv[++k];
    };
    if (a == "--parts") parts = parse_parts(value());
    else if (a == "--csv") csv_path = value();
    else if (a == "--cells-per-part") {
      const std::string v = value();
      try {
        cells_per_part = std::stoi(v);
      } catch (const std::exception&) {
        cells_per_part = 0;
      }
      if (cells_per_part < 1) throw peri::InputError("--cells-per-part " + v + ": expected an integer >= 1");
    } else if (a == "--line-weight") {
      const std::string v = value();
      try {
        line_weight = std::stoi(v);
      } catch (const std::exception&) {
        line_weight = 0;
      }
      if (line_weight < 1 || line_weight > 64)
        throw peri::InputError("--line-weight " + v + ": expected an integer in [1, 64]");
    } else if (a == "--method") {
      methods.clear();
      std::stringstream list(value());
      std::string item;
      while (std::getline(list, item, ',')) {
        if (item == "petsc") throw peri::InputError("--method petsc: this serial tool measures rcb, cells and bonds; "
                                                    "PETSc MatPartitioning runs inside peridrive (-partition_method petsc)");
        if (item == "auto") throw peri::InputError("--method auto: name the partitioners to measure (rcb, cells, bonds)");
        methods.push_back(peri::partition_method(item));
      }
      if (methods.empty()) throw peri::InputError("--method: expected a comma list of rcb, cells, bonds");
      default_methods = false;
    }
    else if (a == "--set") {
      const std::string kv = value();
      const auto eq = kv.find('=');
      if (eq == std::string::npos || eq == 0) throw peri::InputError("--set " + peri::shown_value(kv) + ": expected KEY=VALUE");
      overrides.push_back({kv.substr(0, eq), kv.substr(eq + 1)});
    } else if (a == "--help" || a == "-h") {
      std::puts(
          "usage: peridrive-partition scene.yaml [--set KEY=VALUE ...] [--parts 2,4,...] [--method rcb,cells,bonds]\n"
          "                           [--cells-per-part 64] [--line-weight 2] [--csv FILE]\n"
          "Partitions the scene for each P with each method (rcb: recursive coordinate bisection, peridrive's\n"
          "default for one body filling its box, x extents divided by --line-weight; cells: METIS on the coarse\n"
          "cell graph, peridrive's default otherwise, its cut bonds within an x row of cells weighted --line-weight\n"
          "times, as -partition_line_weight; bonds: METIS on the full bond graph; default: rcb where peridrive\n"
          "would take it, then cells and bonds) and prints per P and method: largest part's nodes\n"
          "and bonds, ghosts, neighbour parts, boundary rows' bonds, the largest message, edge cut, balance,\n"
          "the partitioner's time and its peak memory.");
      return 0;
    } else if (scene_path.empty() && a[0] != '-') scene_path = a;
    else throw peri::InputError("unknown argument " + peri::shown_value(a) + "; see --help");
  }
  if (scene_path.empty()) throw peri::InputError("no scene file given; see --help");
  const peri::Scene scene = peri::load_scene(scene_path, overrides);
  // The CSV file is opened before the work, so that a path that cannot be written is refused
  // at once rather than after every partition.
  std::ofstream csv_file;
  if (!csv_path.empty()) {
    csv_file.open(csv_path);
    if (!csv_file) throw peri::InputError("--csv " + csv_path + ": cannot write the file");
  }
  const auto t0 = std::chrono::steady_clock::now();
  const peri::Nodes nodes = peri::discretize(scene);
  if (default_methods && peri::fills_its_box(nodes)) methods.insert(methods.begin(), peri::PartitionMethod::Rcb);
  double max_reach = 0;
  for (const peri::BodyGeometry& g : nodes.bodies) max_reach = std::max(max_reach, peri::reach(g));
  const peri::CellList cells(nodes, max_reach);
  const peri::BondGraph graph = peri::bond_graph(nodes, cells);
  const double graph_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::int64_t n = nodes.size(), bonds = graph.offsets.back();
  std::printf("# %lld nodes, %lld ordered bonds; nodes + bond graph built in %.3g s, peak RSS %.1f MB\n",
              static_cast<long long>(n), static_cast<long long>(bonds), graph_seconds, peak_rss_kb() / 1024.0);
  // More parts than nodes leave parts empty: those P are skipped, and said so.
  std::string skipped;
  for (int P : parts)
    if (P > n) skipped += (skipped.empty() ? "" : ", ") + std::to_string(P);
  if (!skipped.empty()) {
    if (std::all_of(parts.begin(), parts.end(), [n](int P) { return P > n; }))
      throw peri::InputError("--parts: every value (" + skipped + ") exceeds the scene's " + std::to_string(n) +
                             " nodes; expected at most " + std::to_string(n) + " parts");
    std::fprintf(stderr, "peridrive-partition: note: parts beyond the scene's %lld nodes skipped: %s\n",
                 static_cast<long long>(n), skipped.c_str());
  }
  std::ostringstream csv;
  csv << "parts,method,nodes,ordered_bonds,max_owned_nodes,max_owned_bonds,mean_owned_bonds,max_ghosts,mean_ghosts,"
         "max_neighbour_parts,mean_neighbour_parts,edge_cut,balance,graph_vertices,metis_seconds,partitioner_peak_mb,"
         "max_boundary_bonds,mean_boundary_bonds,max_message_ghosts\n";
  for (int P : parts)
  for (peri::PartitionMethod method : methods) {
    if (P > n) continue;
    const Measured measured = measure(nodes, cells, P, method, cells_per_part, line_weight);
    const std::vector<int>& part = measured.part;
    const double metis_seconds = measured.seconds;
    const peri::PartitionQuality quality = peri::quality(graph, part, P);
    const std::int64_t cut = quality.edge_cut;
    // Per part: owned nodes and bonds; ghosts = distinct off-part neighbours; neighbour parts.
    // Boundary bonds: those of rows with an off-part neighbour (computed after the halo arrives;
    // the interior rows' overlap it). Message: the ghosts one part receives from one other.
    std::vector<std::int64_t> owned(P, 0), owned_bonds(P, 0), ghosts(P, 0), boundary_bonds(P, 0);
    std::int64_t max_message = 0;
    std::vector<std::int64_t> from_part(P, 0);
    std::vector<std::vector<int>> neighbour_parts(P);
    std::vector<int> seen(n, -1);  // last part that counted node j as a ghost
    std::vector<std::vector<std::int32_t>> members(P);
    for (std::int64_t i = 0; i < n; ++i) members[part[i]].push_back(static_cast<std::int32_t>(i));
    for (int p = 0; p < P; ++p) {
      owned[p] = static_cast<std::int64_t>(members[p].size());
      for (std::int32_t i : members[p]) {
        const std::int64_t row = graph.offsets[i + 1] - graph.offsets[i];
        owned_bonds[p] += row;
        bool boundary = false;
        for (std::int64_t b = graph.offsets[i]; b < graph.offsets[i + 1]; ++b) {
          const std::int32_t j = graph.adjacency[b];
          if (part[j] == p) continue;
          boundary = true;
          if (seen[j] != p) {
            seen[j] = p;
            ++ghosts[p];
            ++from_part[part[j]];
            neighbour_parts[p].push_back(part[j]);
          }
        }
        if (boundary) boundary_bonds[p] += row;
      }
      auto& q = neighbour_parts[p];
      std::sort(q.begin(), q.end());
      q.erase(std::unique(q.begin(), q.end()), q.end());
      for (int r : q) {
        max_message = std::max(max_message, from_part[r]);
        from_part[r] = 0;
      }
    }
    auto max_of = [](const std::vector<std::int64_t>& v) { return *std::max_element(v.begin(), v.end()); };
    auto mean_of = [P](const std::vector<std::int64_t>& v) {
      double s = 0;
      for (auto x : v) s += static_cast<double>(x);
      return s / P;
    };
    std::vector<std::int64_t> nq(P);
    for (int p = 0; p < P; ++p) nq[p] = static_cast<std::int64_t>(neighbour_parts[p].size());
    csv << P << "," << peri::to_string(method) << "," << n << "," << bonds << "," << max_of(owned) << "," << max_of(owned_bonds) << ","
        << mean_of(owned_bonds) << "," << max_of(ghosts) << "," << mean_of(ghosts) << "," << max_of(nq) << ","
        << mean_of(nq) << "," << cut << "," << quality.balance << "," << measured.graph_vertices << ","
        << metis_seconds << "," << measured.peak_bytes / 1e6 << "," << max_of(boundary_bonds) << ","
        << mean_of(boundary_bonds) << "," << max_message << "\n";
    std::fprintf(stderr, "P = %d, %s: %.3g s, %.1f MB, balance %.4f, max ghosts %lld, edge cut %lld (%lld graph vertices)\n",
                 P, peri::to_string(method), metis_seconds, measured.peak_bytes / 1e6, quality.balance,
                 static_cast<long long>(max_of(ghosts)), static_cast<long long>(cut),
                 static_cast<long long>(measured.graph_vertices));
  }
  std::fputs(csv.str().c_str(), stdout);
  if (!csv_path.empty()) {
    csv_file << csv.str();
    csv_file.close();
    if (!csv_file) throw peri::Error("--csv " + csv_path + ": writing the file failed");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);  // the library's types need MPI initialised; one process is enough
  int status = 0;
  try {
    status = run(argc, argv);
  } catch (const peri::InputError& e) {
    std::fprintf(stderr, "peridrive-partition: error: %s\n", e.what());
    status = 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "peridrive-partition: error: %s\n", e.what());
    status = 1;
  }
  MPI_Finalize();
  return status;
}
