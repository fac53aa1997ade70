// Partition: which rank owns which node; nodes are renumbered so each rank's owned nodes are
// contiguous, in storage_order inside a part (natural order; irregular bodies along a Morton
// curve). Four partitioners fill the same `part` array (option -partition_method; the default,
// auto, takes rcb for a scene of one square-grid body that fills its box, e.g. a block or a
// rectangular sheet, and cells for any other):
//   rcb    recursive coordinate bisection of the nodes: each range of parts is halved by a plane
//          across its longest extent (x's extent divided by the line weight, so that cuts keep x
//          lines whole), at the node where the nodes' weight (their bond counts on a grid that
//          fills its box, else 1) reaches the left parts' share, moved to the nearer end of the
//          grid line it falls in where that costs at most 0.5% of the share. Flat cuts along grid
//          planes; every rank computes it (no communication), O(N log N log P).
//   cells  METIS k-way on a coarse graph: nodes binned into cubic cells of about the
//          horizon (down to half of it where needed for 64 cells per part), vertex weight = ordered
//          bonds of the cell's nodes, edge weight = bonds between two cells; nodes inherit their
//          cell's part. Serial on rank 0, memory O(cells) besides a 4-byte cell id per node.
//   bonds  METIS k-way on the full bond graph (vertex weight = bond count + 1), serial on rank 0;
//          about 17-21 bytes per ordered bond on rank 0 at 1M nodes.
//   petsc  PETSc MatPartitioning (type from -partition_mat_partitioning_type, default ptscotch
//          where PETSc has it) on the same coarse cell graph, its rows spread over the ranks.
#pragma once
#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

#include "peri/bonds/bonds.hpp"

namespace peri {

struct Partition {
  int parts = 1;
  std::vector<int> part;                         ///< natural id -> owning rank
  std::vector<std::int64_t> natural_to_global;   ///< natural id -> global (PETSc) index
  std::vector<std::int64_t> global_to_natural;   ///< global index -> natural id
  std::vector<std::int64_t> part_begin;          ///< parts + 1 offsets in global numbering
  std::int64_t edge_cut = 0;                     ///< bonds between parts (METIS objective)
  double balance = 1;                            ///< largest part's ordered bonds / mean
  double seconds = 0;                            ///< wall time of the partitioner
  std::int64_t graph_vertices = 0;               ///< vertices of the graph partitioned (cells or nodes)
  std::string method = "none";
  /// Release the per-node maps (part, natural_to_global, global_to_natural) once the domain is
  /// built; parts, part_begin and the figures stay.
  void release_maps();
};

enum class PartitionMethod { Auto, Rcb, Cells, Bonds, Petsc };

/// A cell-graph edge between two cells of one row along x (the natural order's fastest axis)
/// weighs this many times its bonds: a cut across x splits grid lines, whose rows next to the cut
/// leave the stride-1 runs of the bond loop for strided or gathered ones (about twice the cost per
/// bond), while a cut across y or z keeps every line whole. 1 weighs every cut bond alike.
constexpr int kLineWeight = 2;
/// "auto", "rcb", "cells", "bonds" or "petsc"; InputError naming the option otherwise.
PartitionMethod partition_method(const std::string& name);
const char* to_string(PartitionMethod m);

struct PartitionSettings {
  PartitionMethod method = PartitionMethod::Auto;
  int cells_per_part = 64;  ///< cells: shrink cells (not below half the horizon nor the spacing)
                            ///< until this many per part
  int line_weight = kLineWeight;  ///< cells, petsc: weight of a cut bond between cells of one x row;
                                  ///< rcb: an x extent counts 1/line_weight
};

/// Partition settings from the PETSc options database: -partition_method auto|rcb|cells|bonds|petsc,
/// -partition_cells_per_part N, -partition_line_weight W (1 ... 64). InputError (identical on every rank) for bad values.
PartitionSettings partition_settings_from_options();

/// The order nodes are stored in on their rank (natural ids): natural order, except that the nodes
/// of an irregular body (a mesh, a point cloud or a geodesic sphere: BodyGeometry::irregular,
/// whose node order need not follow space) follow a Morton curve through their reference
/// positions, in the body's place.
/// The bond loop walks rows in storage order, so consecutive rows share most neighbours in cache
/// and their neighbour lists and flags are read as one stream. A permutation of 0 .. N-1.
std::vector<std::int64_t> storage_order(const Nodes& nodes);

/// Assign parts from a given natural-id -> part array (any partitioner), renumbering nodes: each
/// part's nodes contiguous, in storage_order inside it. Rank-independent, as the natural order:
/// rows, bonds and output keep natural ids (Domain::natural).
Partition partition_from_parts(const Nodes& nodes, std::vector<int> part, int parts);

/// The bond graph of all nodes (natural ids, CSR), as the partitioner sees it.
struct BondGraph {
  std::vector<std::int64_t> offsets{0};
  std::vector<std::int32_t> adjacency;
};
BondGraph bond_graph(const Nodes& nodes, const CellList& cells);

/// METIS k-way parts of a bond graph (vertex weight = degree + 1, the work of a node); sets the
/// edge cut. Serial. Throws Error if METIS fails.
std::vector<int> metis_kway(const BondGraph& graph, int parts, std::int64_t& edge_cut);

/// Coarse graph of cubic cells (natural ids binned by reference position). Symmetric CSR without
/// self loops; edge_weight = number of bonds between the two cells' nodes (each bond once), so
/// the cut of a cell partition is exactly the bond edge cut of the node partition it induces.
struct CellGraph {
  double cell_size = 0;
  std::vector<std::int32_t> cell_of;          ///< natural id -> cell (occupied cells, ordered by position)
  std::vector<std::int64_t> offsets{0};       ///< cells + 1 (rows built; all by default)
  std::vector<std::int32_t> adjacency;
  std::vector<std::int64_t> edge_weight;      ///< bonds between the two cells
  std::vector<std::int64_t> vertex_weight;    ///< ordered bonds of the cell's nodes (rows built)
  std::vector<std::int64_t> cell_line;        ///< every occupied cell's row of cells along x
  std::int64_t cells = 0;                     ///< occupied cells in all
  std::int64_t row_begin = 0;                 ///< first row built (rows [row_begin, row_begin + rows))
};

/// Bin the nodes into cubic cells of edge `size` (see cell_size_for) and build share `share` of
/// `shares` equal row ranges of the cell graph: rows [cells * share / shares, cells * (share + 1)
/// / shares) (all rows by default). cell_of covers every node.
CellGraph cell_graph(const Nodes& nodes, const CellList& cells, double size, int share = 0, int shares = 1);

/// Cell size for `parts` parts: the largest horizon, shrunk by factors of 0.8 (not below half the
/// horizon nor the largest spacing) until at least cells_per_part * parts cells are occupied.
double cell_size_for(const Nodes& nodes, int parts, int cells_per_part);

/// METIS k-way on a cell graph (all rows); returns a part per cell. An edge weighs its bonds,
/// times line_weight between cells of one x row (kLineWeight). Weights are scaled down if their
/// sums exceed 32-bit METIS. Throws Error if METIS fails.
std::vector<int> metis_kway(const CellGraph& graph, int parts, int line_weight = kLineWeight);

/// Exact edge cut and balance (largest part's ordered bonds / mean) of a node partition.
struct PartitionQuality {
  std::int64_t edge_cut = 0;
  double balance = 1;
};
PartitionQuality quality(const CellGraph& graph, const std::vector<int>& cell_part, int parts);
PartitionQuality quality(const BondGraph& graph, const std::vector<int>& part, int parts);

/// Whether the nodes are one square-grid body with a node at every grid point of its box.
bool fills_its_box(const Nodes& nodes);

/// Ordered bonds of each node of such a body (fills_its_box) from its grid alone, before cracks:
/// what neighbours_of finds, without a neighbour search (rcb's node weights).
std::vector<std::int32_t> grid_bond_counts(const Nodes& nodes);

/// The partitioner `auto` stands for with these nodes: rcb for one square-grid body that fills its
/// box (every grid point a node), cells otherwise; any other method as given.
PartitionMethod resolve_partition_method(PartitionMethod method, const Nodes& nodes);

/// Recursive coordinate bisection (see the top of this file): a part per node, parts >= 1. An
/// x extent counts 1/line_weight of its length when choosing the axis to cut.
std::vector<int> rcb_parts(const Nodes& nodes, int parts, int line_weight = kLineWeight);

/// Parts of every node, with the chosen partitioner (collective on comm: METIS methods run on
/// rank 0 and broadcast; petsc runs on all ranks). parts <= 1: everything in part 0.
Partition partition_nodes(const Nodes& nodes, const CellList& cells, int parts, MPI_Comm comm,
                          PartitionSettings settings = {});

}  // namespace peri
