// Partition: which rank owns which node. METIS k-way on the bond graph (vertex weight = bond
// count), computed once on rank 0 and broadcast; nodes are renumbered so each rank's owned nodes
// are contiguous (natural order kept inside a part). Another partitioner plugs in by filling the
// same `part` array.
#pragma once
#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

#include "peri/bonds.hpp"

namespace peri {

struct Partition {
  int parts = 1;
  std::vector<int> part;                         ///< natural id -> owning rank
  std::vector<std::int64_t> natural_to_global;   ///< natural id -> global (PETSc) index
  std::vector<std::int64_t> global_to_natural;   ///< global index -> natural id
  std::vector<std::int64_t> part_begin;          ///< parts + 1 offsets in global numbering
  std::int64_t edge_cut = 0;                     ///< bonds between parts (METIS objective)
  double seconds = 0;                            ///< wall time of the partitioner
  std::string method = "none";
};

/// Assign parts from a given natural-id -> part array (any partitioner), renumbering nodes.
Partition partition_from_parts(std::vector<int> part, int parts);

/// The bond graph of all nodes (natural ids, CSR), as the partitioner sees it.
struct BondGraph {
  std::vector<std::int64_t> offsets{0};
  std::vector<std::int32_t> adjacency;
};
BondGraph bond_graph(const Nodes& nodes, const CellList& cells);

/// METIS k-way parts of a bond graph (vertex weight = degree + 1, the work of a node); sets the
/// edge cut. Serial. Throws Error if METIS fails.
std::vector<int> metis_kway(const BondGraph& graph, int parts, std::int64_t& edge_cut);

/// METIS k-way on the bond graph into `parts` parts, computed on rank 0 of comm and broadcast.
Partition partition_nodes(const Nodes& nodes, const CellList& cells, int parts, MPI_Comm comm);

}  // namespace peri
