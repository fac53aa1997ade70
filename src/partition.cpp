#include "peri/partition.hpp"

#include <metis.h>

#include <chrono>
#include <limits>
#include <numeric>

#include "peri/error.hpp"

namespace peri {

Partition partition_from_parts(std::vector<int> part, int parts) {
  Partition p;
  p.parts = parts;
  p.part = std::move(part);
  const std::int64_t n = static_cast<std::int64_t>(p.part.size());
  p.part_begin.assign(parts + 1, 0);
  for (std::int64_t i = 0; i < n; ++i) ++p.part_begin[p.part[i] + 1];
  std::partial_sum(p.part_begin.begin(), p.part_begin.end(), p.part_begin.begin());
  std::vector<std::int64_t> fill(p.part_begin.begin(), p.part_begin.end() - 1);
  p.natural_to_global.resize(n);
  p.global_to_natural.resize(n);
  for (std::int64_t i = 0; i < n; ++i) {  // stable: natural order inside a part
    const std::int64_t g = fill[p.part[i]]++;
    p.natural_to_global[i] = g;
    p.global_to_natural[g] = i;
  }
  return p;
}

BondGraph bond_graph(const Nodes& nodes, const CellList& cells) {
  // Count first, then fill: the graph is allocated once at its exact size.
  const std::int64_t n = nodes.size();
  BondGraph g;
  g.offsets.assign(n + 1, 0);
  std::vector<std::int64_t> ids;
  std::vector<double> w;
  for (std::int64_t i = 0; i < n; ++i) {
    neighbours_of(nodes, cells, i, ids, w);
    g.offsets[i + 1] = g.offsets[i] + static_cast<std::int64_t>(ids.size());
  }
  g.adjacency.resize(static_cast<std::size_t>(g.offsets[n]));
  for (std::int64_t i = 0; i < n; ++i) {
    neighbours_of(nodes, cells, i, ids, w);
    for (std::size_t k = 0; k < ids.size(); ++k) g.adjacency[g.offsets[i] + k] = static_cast<std::int32_t>(ids[k]);
  }
  return g;
}

std::vector<int> metis_kway(const BondGraph& graph, int parts, std::int64_t& edge_cut) {
  static_assert(sizeof(idx_t) == sizeof(std::int32_t), "METIS built with 32-bit idx_t expected");
  const std::int64_t n = static_cast<std::int64_t>(graph.offsets.size()) - 1;
  if (graph.offsets[n] > std::numeric_limits<idx_t>::max())
    throw Error("the bond graph has " + std::to_string(graph.offsets[n]) +
                " ordered bonds, more than 32-bit METIS can index; use a coarser spacing");
  std::vector<idx_t> xadj(n + 1), vwgt(n);
  for (std::int64_t i = 0; i <= n; ++i) xadj[i] = static_cast<idx_t>(graph.offsets[i]);
  for (std::int64_t i = 0; i < n; ++i) vwgt[i] = xadj[i + 1] - xadj[i] + 1;
  idx_t nv = static_cast<idx_t>(n), ncon = 1, np = parts, objval = 0;
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_SEED] = 1;
  std::vector<idx_t> mpart(n);
  const int status = METIS_PartGraphKway(&nv, &ncon, xadj.data(), const_cast<idx_t*>(graph.adjacency.data()),
                                         vwgt.data(), nullptr, nullptr, &np, nullptr, nullptr, options,
                                         &objval, mpart.data());
  if (status != METIS_OK) throw Error("METIS_PartGraphKway failed with status " + std::to_string(status));
  edge_cut = objval;
  return {mpart.begin(), mpart.end()};
}

Partition partition_nodes(const Nodes& nodes, const CellList& cells, int parts, MPI_Comm comm) {
  const std::int64_t n = nodes.size();
  std::vector<int> part(n, 0);
  if (parts <= 1) {
    Partition p = partition_from_parts(std::move(part), 1);
    return p;
  }
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  if (n < parts) throw InputError("the scene has " + std::to_string(n) + " nodes, fewer than the " +
                                  std::to_string(parts) + " ranks; use fewer ranks");
  const auto t0 = std::chrono::steady_clock::now();
  long long cut = 0;
  int status = METIS_OK;
  std::string failure;
  if (rank == 0) {
    try {
      std::int64_t edge_cut = 0;
      part = metis_kway(bond_graph(nodes, cells), parts, edge_cut);
      cut = edge_cut;
    } catch (const Error& e) {
      status = METIS_ERROR;
      failure = e.what();
    }
  }
  MPI_Bcast(&status, 1, MPI_INT, 0, comm);
  if (status != METIS_OK) throw Error(rank == 0 ? failure : "METIS_PartGraphKway failed on rank 0");
  MPI_Bcast(part.data(), static_cast<int>(n), MPI_INT, 0, comm);
  MPI_Bcast(&cut, 1, MPI_LONG_LONG, 0, comm);
  Partition p = partition_from_parts(std::move(part), parts);
  p.edge_cut = cut;
  p.method = "metis-kway-bond-graph";
  p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return p;
}

}  // namespace peri
