#include "peri/partition.hpp"

#include <metis.h>

#include <chrono>
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
  if (rank == 0) {
    std::vector<idx_t> xadj(n + 1, 0), adjncy, vwgt(n);
    std::vector<std::int64_t> ids;
    std::vector<double> w;
    for (std::int64_t i = 0; i < n; ++i) {
      neighbours_of(nodes, cells, i, ids, w);
      for (std::int64_t j : ids) adjncy.push_back(static_cast<idx_t>(j));
      xadj[i + 1] = static_cast<idx_t>(adjncy.size());
      vwgt[i] = static_cast<idx_t>(ids.size()) + 1;  // work of a node ~ its bond count
    }
    idx_t nv = static_cast<idx_t>(n), ncon = 1, np = parts, objval = 0;
    idx_t options[METIS_NOPTIONS];
    METIS_SetDefaultOptions(options);
    options[METIS_OPTION_SEED] = 1;
    std::vector<idx_t> mpart(n);
    status = METIS_PartGraphKway(&nv, &ncon, xadj.data(), adjncy.data(), vwgt.data(), nullptr,
                                 nullptr, &np, nullptr, nullptr, options, &objval, mpart.data());
    for (std::int64_t i = 0; i < n; ++i) part[i] = static_cast<int>(mpart[i]);
    cut = objval;
  }
  MPI_Bcast(&status, 1, MPI_INT, 0, comm);
  if (status != METIS_OK) throw Error("METIS_PartGraphKway failed with status " + std::to_string(status));
  MPI_Bcast(part.data(), static_cast<int>(n), MPI_INT, 0, comm);
  MPI_Bcast(&cut, 1, MPI_LONG_LONG, 0, comm);
  Partition p = partition_from_parts(std::move(part), parts);
  p.edge_cut = cut;
  p.method = "metis-kway-bond-graph";
  p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return p;
}

}  // namespace peri
