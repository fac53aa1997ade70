// peridrive-partition: partition a scene into P parts without running it, and report what a
// P-rank run would carry per rank (owned nodes and bonds, ghosts, neighbour ranks) and what the
// partitioner costs (time, memory). Feeds cluster/scaling_model.py.
//
//   peridrive-partition scene.yaml [--set KEY=VALUE ...] --parts 2,4,8,...,4096 [--csv FILE]
//
// One process, no MPI ranks needed: METIS k-way runs serially here exactly as on rank 0 of a run.
#include <mpi.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "peri/partition.hpp"

namespace {

long peak_rss_kb() {
  rusage r{};
  getrusage(RUSAGE_SELF, &r);
  return r.ru_maxrss;
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
    else if (a == "--set") {
      const std::string kv = value();
      const auto eq = kv.find('=');
      if (eq == std::string::npos || eq == 0) throw peri::InputError("--set " + kv + ": expected KEY=VALUE");
      overrides.push_back({kv.substr(0, eq), kv.substr(eq + 1)});
    } else if (a == "--help" || a == "-h") {
      std::puts("usage: peridrive-partition scene.yaml [--set KEY=VALUE ...] [--parts 2,4,...] [--csv FILE]");
      return 0;
    } else if (scene_path.empty() && a[0] != '-') scene_path = a;
    else throw peri::InputError("unknown argument " + a + "; see --help");
  }
  if (scene_path.empty()) throw peri::InputError("no scene file given; see --help");
  const peri::Scene scene = peri::load_scene(scene_path, overrides);
  const auto t0 = std::chrono::steady_clock::now();
  const peri::Nodes nodes = peri::discretize(scene);
  double max_reach = 0;
  for (const peri::BodyGeometry& g : nodes.bodies) max_reach = std::max(max_reach, peri::reach(g));
  const peri::CellList cells(nodes, max_reach);
  const peri::BondGraph graph = peri::bond_graph(nodes, cells);
  const double graph_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::int64_t n = nodes.size(), bonds = graph.offsets.back();
  std::printf("# %lld nodes, %lld ordered bonds; nodes + bond graph built in %.3g s, peak RSS %.1f MB\n",
              static_cast<long long>(n), static_cast<long long>(bonds), graph_seconds, peak_rss_kb() / 1024.0);
  std::ostringstream csv;
  csv << "parts,nodes,ordered_bonds,max_owned_nodes,max_owned_bonds,mean_owned_bonds,max_ghosts,mean_ghosts,"
         "max_neighbour_parts,mean_neighbour_parts,edge_cut,metis_seconds,peak_rss_mb\n";
  for (int P : parts) {
    if (P > n) continue;
    const auto m0 = std::chrono::steady_clock::now();
    std::int64_t cut = 0;
    const std::vector<int> part = peri::metis_kway(graph, P, cut);
    const double metis_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - m0).count();
    // Per part: owned nodes and bonds; ghosts = distinct off-part neighbours; neighbour parts.
    std::vector<std::int64_t> owned(P, 0), owned_bonds(P, 0), ghosts(P, 0);
    std::vector<std::vector<int>> neighbour_parts(P);
    std::vector<int> seen(n, -1);  // last part that counted node j as a ghost
    std::vector<std::vector<std::int32_t>> members(P);
    for (std::int64_t i = 0; i < n; ++i) members[part[i]].push_back(static_cast<std::int32_t>(i));
    for (int p = 0; p < P; ++p) {
      owned[p] = static_cast<std::int64_t>(members[p].size());
      for (std::int32_t i : members[p]) {
        owned_bonds[p] += graph.offsets[i + 1] - graph.offsets[i];
        for (std::int64_t b = graph.offsets[i]; b < graph.offsets[i + 1]; ++b) {
          const std::int32_t j = graph.adjacency[b];
          if (part[j] != p && seen[j] != p) {
            seen[j] = p;
            ++ghosts[p];
            neighbour_parts[p].push_back(part[j]);
          }
        }
      }
      auto& q = neighbour_parts[p];
      std::sort(q.begin(), q.end());
      q.erase(std::unique(q.begin(), q.end()), q.end());
    }
    auto max_of = [](const std::vector<std::int64_t>& v) { return *std::max_element(v.begin(), v.end()); };
    auto mean_of = [P](const std::vector<std::int64_t>& v) {
      double s = 0;
      for (auto x : v) s += static_cast<double>(x);
      return s / P;
    };
    std::vector<std::int64_t> nq(P);
    for (int p = 0; p < P; ++p) nq[p] = static_cast<std::int64_t>(neighbour_parts[p].size());
    csv << P << "," << n << "," << bonds << "," << max_of(owned) << "," << max_of(owned_bonds) << ","
        << mean_of(owned_bonds) << "," << max_of(ghosts) << "," << mean_of(ghosts) << "," << max_of(nq) << ","
        << mean_of(nq) << "," << cut << "," << metis_seconds << "," << peak_rss_kb() / 1024.0 << "\n";
    std::fprintf(stderr, "P = %d: METIS %.3g s, load imbalance %.3f, max ghosts %lld, edge cut %lld\n", P,
                 metis_seconds, max_of(owned_bonds) / mean_of(owned_bonds), static_cast<long long>(max_of(ghosts)),
                 static_cast<long long>(cut));
  }
  std::fputs(csv.str().c_str(), stdout);
  if (!csv_path.empty()) {
    std::ofstream f(csv_path);
    f << csv.str();
    if (!f) throw peri::Error("cannot write " + csv_path);
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
