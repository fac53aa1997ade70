// Resources: will a scene fit? A size estimate (nodes, bonds, bytes; discretization.hpp) turned
// into the memory one rank and one host need, compared with the memory the host has, before
// anything large is allocated. Refused scenes get the estimate in their message.
#pragma once
#include <mpi.h>

#include <cstdint>
#include <string>

#include "peri/discretization.hpp"

namespace peri {

struct MemoryNeed {
  double per_rank = 0;  ///< bytes on an ordinary rank: its share plus the replicated node arrays
  double rank0 = 0;     ///< bytes on rank 0, which also holds the partitioner's whole bond graph
};

/// Memory of a run of `ranks` ranks (pure; the model behind check_fits).
/// Every rank holds its 1/ranks share of estimate.bytes and ~64 bytes per node of replicated
/// arrays (reference positions, measures, bodies, partition maps, cell list); with more than one
/// rank, rank 0 holds the partitioner's graph (~24 bytes per ordered bond).
MemoryNeed memory_need(const SizeEstimate& e, int ranks);

/// Bytes this host can give: MemAvailable of /proc/meminfo, lowered to the cgroup memory limit
/// when there is one. 0 when unknown (then nothing is refused).
double available_memory();

/// Refuse (InputError, same message on every rank) a scene whose estimate does not fit the
/// memory of the hosts it runs on. Collective.
void check_fits(const Scene& scene, MPI_Comm comm);

/// One line: "about N nodes, B bonds, X GB in all".
std::string describe(const SizeEstimate& e);

}  // namespace peri
