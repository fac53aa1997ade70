// Domain: one rank's share of the discretized bodies. Local numbering puts owned nodes first
// (in global order) and ghosts after (sorted by global index). Bond families are stored for owned
// rows only, in natural-id order of the neighbours, so a node's force is summed in the same order
// on any number of ranks (results independent of the rank count bit for bit).
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "peri/partition/partition.hpp"

namespace peri {

struct Domain {
  int rank = 0, ranks = 1;
  std::int64_t global_nodes = 0;   ///< nodes over all ranks
  std::int64_t global_begin = 0;   ///< first owned global index
  std::int32_t owned = 0, ghosts = 0;
  std::vector<std::int64_t> natural;  ///< local -> natural id (owned, then ghosts)
  std::vector<std::int64_t> global;   ///< local -> global index
  std::vector<double> X;              ///< 3 * local reference positions [m]
  std::vector<double> volume;         ///< local measures [m^3]
  std::vector<int> body;              ///< local body index
  BondFamilies bonds;                 ///< families of owned rows
  std::vector<std::int32_t> interior_rows;  ///< owned rows whose neighbours are all owned
  std::vector<std::int32_t> boundary_rows;  ///< owned rows with at least one ghost neighbour
  std::int64_t initially_broken = 0;  ///< owned ordered bonds broken by pre-cracks
  std::vector<char> crack_met;        ///< per scene crack broken at the start: it met an owned bond
  /// Per scene crack (slits) and body [crack * bodies + body]: the owned ordered bonds of a curved
  /// sheet (a sphere, a curved mesh) it broke at the start whose midpoint lies farther than the
  /// body's horizon from the slit's segment in space. A slit is taken in the xy plane, so on a
  /// curved sheet it cuts every wall above and below it; these bonds are the walls it does not
  /// touch. crack_far_most: per crack, the largest such distance [m] (0: none).
  std::vector<std::int64_t> crack_far;
  std::vector<double> crack_far_most;
  std::int32_t local() const { return owned + ghosts; }
};

/// Build this rank's domain from the global node set and the partition. `stop` is polled now
/// and then: once it returns true, the build returns at once with an unfinished domain.
Domain build_domain(const Scene& scene, const Nodes& nodes, const CellList& cells,
                    const Partition& partition, int rank, const std::function<bool()>& stop = {});

}  // namespace peri
