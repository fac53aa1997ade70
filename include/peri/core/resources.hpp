// Resources: will a scene fit? A size estimate (nodes, bonds, bytes; discretization.hpp) turned
// into the memory one rank and one host need, compared with the memory the host has, before
// anything large is allocated. Refused scenes get the estimate in their message.
#pragma once
#include <mpi.h>

#include <cstdint>
#include <string>

#include "peri/geometry/discretization.hpp"

namespace peri {

struct MemoryNeed {
  double per_rank = 0;  ///< bytes on an ordinary rank: its share plus the replicated node arrays
  double rank0 = 0;     ///< bytes on rank 0, which also holds the partitioner's whole bond graph
};

/// Memory of a run of `ranks` ranks (pure; the model behind check_fits).
/// Every rank holds its 1/ranks share of estimate.bytes and, during setup, ~72 bytes per node of
/// replicated arrays (reference positions, measures, bodies, partition maps, cell list; freed once
/// the domain is built). The default cell-graph partitioner needs no per-bond memory; with
/// `-partition_method bonds` (full_bond_graph) and more than one rank, rank 0 also holds the
/// full bond graph inside METIS (~24 bytes per ordered bond).
MemoryNeed memory_need(const SizeEstimate& e, int ranks, bool full_bond_graph = false);

/// Bytes this host can give: MemAvailable of /proc/meminfo, lowered to the cgroup memory limit
/// when there is one. 0 when unknown (then nothing is refused).
double available_memory();

/// Refuse (InputError, same message on every rank) a scene whose estimate does not fit the
/// memory of the hosts it runs on. full_bond_graph: the partitioner is -partition_method bonds.
/// Collective.
void check_fits(const Scene& scene, MPI_Comm comm, bool full_bond_graph = false);

/// This process's memory from /proc/self/status: peak resident set (VmHWM) and current resident
/// set (VmRSS), in bytes; 0 where unknown.
struct ProcessMemory {
  double peak = 0, current = 0;
};
ProcessMemory process_memory();

/// One line: "about N nodes, B bonds, X GB in all".
std::string describe(const SizeEstimate& e);

}  // namespace peri
