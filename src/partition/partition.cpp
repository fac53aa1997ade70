// Who owns which node: the partition settings, the graphs METIS and PETSc partition (cells, bonds),
// and partition_nodes, which runs the chosen partitioner (rcb: rcb.cpp).
#include "peri/partition/partition.hpp"

#include <metis.h>
#include <petscmat.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include "peri/core/error.hpp"
#include "peri/core/petsc.hpp"

namespace peri {

PartitionMethod partition_method(const std::string& name) {
  if (name == "auto") return PartitionMethod::Auto;
  if (name == "rcb") return PartitionMethod::Rcb;
  if (name == "cells") return PartitionMethod::Cells;
  if (name == "bonds") return PartitionMethod::Bonds;
  if (name == "petsc") return PartitionMethod::Petsc;
  throw InputError("-partition_method " + name + ": expected auto (the default: rcb for one body filling its box, "
                   "else cells), rcb (recursive coordinate bisection), cells (coarse cell graph, METIS), "
                   "bonds (full bond graph, METIS) or petsc (MatPartitioning on the cell graph)");
}

const char* to_string(PartitionMethod m) {
  switch (m) {
    case PartitionMethod::Auto: return "auto";
    case PartitionMethod::Rcb: return "rcb";
    case PartitionMethod::Cells: return "cells";
    case PartitionMethod::Bonds: return "bonds";
    case PartitionMethod::Petsc: return "petsc";
  }
  return "?";
}

namespace {

// An integer option read as text (PETSc's own reading of "1.5" or "abc" ends in its error
// handler, exit status 4): InputError unless a whole integer in [lo, hi].
int integer_option(const char* option, long lo, long hi, int fallback) {
  char text[64] = "";
  PetscBool set = PETSC_FALSE;
  PERI_PETSC(PetscOptionsGetString(nullptr, nullptr, option, text, sizeof text, &set));
  if (!set) return fallback;
  long value = 0;
  const char* end = text + std::strlen(text);
  const auto r = std::from_chars(text, end, value);
  if (!*text || r.ec != std::errc() || r.ptr != end || value < lo || value > hi)
    throw InputError(std::string(option) + " " + text + ": expected an integer in [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "]");
  return static_cast<int>(value);
}

// The partitioner types this PETSc has, among those PETSc defines.
std::string partitioner_types() {
  std::string out;
  for (const char* t : {MATPARTITIONINGCURRENT, MATPARTITIONINGAVERAGE, MATPARTITIONINGSQUARE, MATPARTITIONINGPARMETIS,
                        MATPARTITIONINGPTSCOTCH, MATPARTITIONINGCHACO, MATPARTITIONINGPARTY, MATPARTITIONINGHIERARCH}) {
    void (*create)(void) = nullptr;
    PERI_PETSC(PetscFunctionListFind(MatPartitioningList, t, &create));
    if (create) out += (out.empty() ? "" : ", ") + std::string(t);
  }
  return out;
}

}  // namespace

PartitionSettings partition_settings_from_options() {
  PartitionSettings s;
  char name[64] = "";
  PetscBool set = PETSC_FALSE;
  PERI_PETSC(PetscOptionsGetString(nullptr, nullptr, "-partition_method", name, sizeof name, &set));
  if (set) s.method = partition_method(name);
  s.cells_per_part = integer_option("-partition_cells_per_part", 1, 1000000, s.cells_per_part);
  s.line_weight = integer_option("-partition_line_weight", 1, 64, s.line_weight);
  // The PETSc partitioner's type, checked against those this PETSc has (an unknown one ended in
  // PETSc's error handler on 2 ranks and went unread on 1).
  PERI_PETSC(PetscOptionsGetString(nullptr, nullptr, "-partition_mat_partitioning_type", name, sizeof name, &set));
  if (set) {
    PERI_PETSC(MatInitializePackage());
    void (*create)(void) = nullptr;
    PERI_PETSC(PetscFunctionListFind(MatPartitioningList, name, &create));
    if (!create)
      throw InputError(std::string("-partition_mat_partitioning_type ") + name +
                       ": not a partitioner of this PETSc build; expected one of: " + partitioner_types());
  }
  return s;
}

void Partition::release_maps() {
  std::vector<int>().swap(part);
  std::vector<std::int64_t>().swap(natural_to_global);
  std::vector<std::int64_t>().swap(global_to_natural);
}

namespace {

struct Box {
  std::array<double, 3> lo{}, hi{};
};

Box bounding_box(const Nodes& nodes) {
  Box b;
  const std::int64_t n = nodes.size();
  if (n == 0) return b;
  for (int d = 0; d < 3; ++d) b.lo[d] = b.hi[d] = nodes.X[d];
  for (std::int64_t i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) {
      b.lo[d] = std::min(b.lo[d], nodes.X[3 * i + d]);
      b.hi[d] = std::max(b.hi[d], nodes.X[3 * i + d]);
    }
  return b;
}

// Linear cell index of every node for cubic cells of size h; dims returned. Empty when the box
// would need more than `limit` cells.
std::vector<std::int64_t> linear_cells(const Nodes& nodes, const Box& box, double h, double limit,
                                       std::array<std::int64_t, 3>& dims) {
  double total = 1;
  for (int d = 0; d < 3; ++d) {
    dims[d] = static_cast<std::int64_t>(std::floor((box.hi[d] - box.lo[d]) / h)) + 1;
    total *= static_cast<double>(dims[d]);
  }
  if (total > limit) return {};
  const std::int64_t n = nodes.size();
  std::vector<std::int64_t> lin(n);
  for (std::int64_t i = 0; i < n; ++i) {
    std::int64_t c[3];
    for (int d = 0; d < 3; ++d)
      c[d] = std::clamp<std::int64_t>(static_cast<std::int64_t>((nodes.X[3 * i + d] - box.lo[d]) / h), 0, dims[d] - 1);
    lin[i] = (c[2] * dims[1] + c[1]) * dims[0] + c[0];
  }
  return lin;
}

std::int64_t occupied(const std::vector<std::int64_t>& lin, const std::array<std::int64_t, 3>& dims) {
  std::vector<std::uint8_t> used(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]), 0);
  std::int64_t count = 0;
  for (std::int64_t c : lin)
    if (!used[c]) {
      used[c] = 1;
      ++count;
    }
  return count;
}

// Scale factor that keeps a sum of weights within 32-bit METIS/PETSc indices.
std::int64_t weight_divisor(std::int64_t total) {
  const std::int64_t limit = std::int64_t(1) << 29;
  return total > limit ? (total + limit - 1) / limit : 1;
}

}  // namespace

double cell_size_for(const Nodes& nodes, int parts, int cells_per_part) {
  double h = 0, spacing = 0;
  for (const BodyGeometry& g : nodes.bodies) {
    h = std::max(h, g.horizon);
    spacing = std::max(spacing, g.spacing);
  }
  if (!(h > 0)) h = spacing > 0 ? spacing : 1.0;
  // Not below half the horizon (nor the spacing): smaller cells have (2 delta / h + 1)^3 cell
  // neighbours each and the cell graph would outgrow the bond graph it replaces.
  const double floor = std::max(spacing, 0.5 * h);
  const Box box = bounding_box(nodes);
  const double want = static_cast<double>(cells_per_part) * parts;
  const double limit = 4.0 * static_cast<double>(nodes.size()) + 64;
  for (;;) {
    std::array<std::int64_t, 3> dims{};
    const std::vector<std::int64_t> lin = linear_cells(nodes, box, h, limit, dims);
    if (lin.empty()) return h / 0.8;  // the previous size: a sparse box has enough cells
    if (static_cast<double>(occupied(lin, dims)) >= want || h <= floor) return h;
    h = std::max(0.8 * h, floor);
  }
}

CellGraph cell_graph(const Nodes& nodes, const CellList& cells, double size, int share, int shares) {
  CellGraph g;
  g.cell_size = size;
  const std::int64_t n = nodes.size();
  const Box box = bounding_box(nodes);
  std::array<std::int64_t, 3> dims{};
  std::vector<std::int64_t> lin = linear_cells(nodes, box, size, HUGE_VAL, dims);
  // Occupied cells, numbered in linear (z, y, x) order: neighbouring ids are neighbouring cells.
  {
    std::vector<std::int64_t> sorted(lin);
    std::sort(sorted.begin(), sorted.end());
    sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
    g.cells = static_cast<std::int64_t>(sorted.size());
    if (g.cells > std::numeric_limits<std::int32_t>::max()) throw Error("too many partition cells");
    g.cell_line.resize(sorted.size());
    for (std::size_t c = 0; c < sorted.size(); ++c) g.cell_line[c] = sorted[c] / dims[0];
    g.cell_of.resize(n);
    for (std::int64_t i = 0; i < n; ++i)
      g.cell_of[i] = static_cast<std::int32_t>(std::lower_bound(sorted.begin(), sorted.end(), lin[i]) - sorted.begin());
  }
  std::vector<std::int64_t>().swap(lin);
  const std::int64_t row_begin = g.cells * share / shares, row_end = g.cells * (share + 1) / shares;
  g.row_begin = row_begin;
  // Nodes of the rows built, grouped by cell (natural order inside a cell).
  std::vector<std::int64_t> start(row_end - row_begin + 1, 0);
  for (std::int64_t i = 0; i < n; ++i)
    if (g.cell_of[i] >= row_begin && g.cell_of[i] < row_end) ++start[g.cell_of[i] - row_begin + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<std::int32_t> members(static_cast<std::size_t>(start.back()));
  {
    std::vector<std::int64_t> fill(start.begin(), start.end() - 1);
    for (std::int64_t i = 0; i < n; ++i)
      if (g.cell_of[i] >= row_begin && g.cell_of[i] < row_end)
        members[fill[g.cell_of[i] - row_begin]++] = static_cast<std::int32_t>(i);
  }
  std::vector<std::int64_t> acc(g.cells, 0);
  std::vector<std::int32_t> touched;
  std::vector<std::int64_t> ids;
  std::vector<double> w;
  g.vertex_weight.assign(row_end - row_begin, 0);
  g.offsets.assign(1, 0);
  for (std::int64_t c = row_begin; c < row_end; ++c) {
    for (std::int64_t m = start[c - row_begin]; m < start[c - row_begin + 1]; ++m) {
      neighbours_of(nodes, cells, members[m], ids, w);
      g.vertex_weight[c - row_begin] += static_cast<std::int64_t>(ids.size());
      for (std::int64_t j : ids) {
        const std::int32_t d = g.cell_of[j];
        if (d == c) continue;
        if (acc[d]++ == 0) touched.push_back(d);
      }
    }
    std::sort(touched.begin(), touched.end());
    for (std::int32_t d : touched) {
      g.adjacency.push_back(d);
      g.edge_weight.push_back(acc[d]);
      acc[d] = 0;
    }
    touched.clear();
    g.offsets.push_back(static_cast<std::int64_t>(g.adjacency.size()));
  }
  return g;
}

namespace {

// The partitioner's weight of edge k of cell c (kLineWeight).
std::int64_t partition_edge_weight(const CellGraph& g, std::int64_t c, std::int64_t k, int line_weight) {
  return g.cell_line[c] == g.cell_line[g.adjacency[k]] ? g.edge_weight[k] * line_weight : g.edge_weight[k];
}

}  // namespace

std::vector<int> metis_kway(const CellGraph& graph, int parts, int line_weight) {
  static_assert(sizeof(idx_t) == sizeof(std::int32_t), "METIS built with 32-bit idx_t expected");
  const std::int64_t n = graph.cells;
  if (graph.row_begin != 0 || static_cast<std::int64_t>(graph.vertex_weight.size()) != n)
    throw Error("metis_kway: the cell graph must hold all rows");
  if (graph.offsets[n] > std::numeric_limits<idx_t>::max()) throw Error("the cell graph is too large for 32-bit METIS");
  std::int64_t vsum = 0, esum = 0;
  for (std::int64_t v : graph.vertex_weight) vsum += v + 1;
  for (std::int64_t c = 0; c < n; ++c)
    for (std::int64_t k = graph.offsets[c]; k < graph.offsets[c + 1]; ++k) esum += partition_edge_weight(graph, c, k, line_weight);
  const std::int64_t vdiv = weight_divisor(vsum), ediv = weight_divisor(esum);
  std::vector<idx_t> xadj(n + 1), adjncy(graph.adjacency.begin(), graph.adjacency.end()), vwgt(n),
      adjwgt(graph.edge_weight.size());
  for (std::int64_t i = 0; i <= n; ++i) xadj[i] = static_cast<idx_t>(graph.offsets[i]);
  for (std::int64_t i = 0; i < n; ++i) vwgt[i] = static_cast<idx_t>(std::max<std::int64_t>(1, (graph.vertex_weight[i] + 1) / vdiv));
  for (std::int64_t c = 0; c < n; ++c)
    for (std::int64_t k = graph.offsets[c]; k < graph.offsets[c + 1]; ++k)
      adjwgt[k] = static_cast<idx_t>(std::max<std::int64_t>(1, partition_edge_weight(graph, c, k, line_weight) / ediv));
  idx_t nv = static_cast<idx_t>(n), ncon = 1, np = parts, objval = 0;
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_SEED] = 1;
  options[METIS_OPTION_UFACTOR] = 5;  // 0.5% imbalance allowed (default 3%): cells are coarse, bonds the work
  std::vector<idx_t> mpart(n);
  const int status = METIS_PartGraphKway(&nv, &ncon, xadj.data(), adjncy.data(), vwgt.data(), nullptr,
                                         adjwgt.data(), &np, nullptr, nullptr, options, &objval, mpart.data());
  if (status != METIS_OK) throw Error("METIS_PartGraphKway failed with status " + std::to_string(status));
  return {mpart.begin(), mpart.end()};
}

PartitionQuality quality(const CellGraph& graph, const std::vector<int>& cell_part, int parts) {
  PartitionQuality q;
  std::vector<std::int64_t> load(parts, 0);
  std::int64_t cut2 = 0, total = 0;
  for (std::int64_t c = 0; c < static_cast<std::int64_t>(graph.vertex_weight.size()); ++c) {
    const std::int64_t gc = graph.row_begin + c;
    load[cell_part[gc]] += graph.vertex_weight[c];
    total += graph.vertex_weight[c];
    for (std::int64_t k = graph.offsets[c]; k < graph.offsets[c + 1]; ++k)
      if (cell_part[graph.adjacency[k]] != cell_part[gc]) cut2 += graph.edge_weight[k];
  }
  q.edge_cut = cut2 / 2;
  q.balance = total > 0 ? static_cast<double>(*std::max_element(load.begin(), load.end())) * parts / static_cast<double>(total) : 1.0;
  return q;
}

PartitionQuality quality(const BondGraph& graph, const std::vector<int>& part, int parts) {
  PartitionQuality q;
  std::vector<std::int64_t> load(parts, 0);
  std::int64_t cut2 = 0;
  const std::int64_t n = static_cast<std::int64_t>(graph.offsets.size()) - 1;
  for (std::int64_t i = 0; i < n; ++i) {
    load[part[i]] += graph.offsets[i + 1] - graph.offsets[i];
    for (std::int64_t b = graph.offsets[i]; b < graph.offsets[i + 1]; ++b) cut2 += part[graph.adjacency[b]] != part[i];
  }
  q.edge_cut = cut2 / 2;
  const std::int64_t total = graph.offsets[n];
  q.balance = total > 0 ? static_cast<double>(*std::max_element(load.begin(), load.end())) * parts / static_cast<double>(total) : 1.0;
  return q;
}

std::vector<std::int64_t> storage_order(const Nodes& nodes) {
  std::vector<std::int64_t> order(static_cast<std::size_t>(nodes.size()));
  std::iota(order.begin(), order.end(), std::int64_t{0});
  auto spread = [](std::uint64_t a) {  // the 21 bits of a at every third bit
    a &= 0x1fffff;
    a = (a | a << 32) & 0x1f00000000ffffull;
    a = (a | a << 16) & 0x1f0000ff0000ffull;
    a = (a | a << 8) & 0x100f00f00f00f00full;
    a = (a | a << 4) & 0x10c30c30c30c30c3ull;
    a = (a | a << 2) & 0x1249249249249249ull;
    return a;
  };
  std::vector<std::pair<std::uint64_t, std::int64_t>> keyed;
  for (const BodyGeometry& g : nodes.bodies) {
    if (!g.irregular || g.count < 2) continue;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (std::int64_t i = g.first; i < g.first + g.count; ++i)
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::min(lo[c], nodes.X[3 * i + c]);
        hi[c] = std::max(hi[c], nodes.X[3 * i + c]);
      }
    keyed.clear();
    keyed.reserve(static_cast<std::size_t>(g.count));
    for (std::int64_t i = g.first; i < g.first + g.count; ++i) {
      std::uint64_t key = 0;
      for (int c = 0; c < 3; ++c) {
        const double extent = hi[c] - lo[c];
        const double t = extent > 0 ? (nodes.X[3 * i + c] - lo[c]) / extent : 0.0;
        key |= spread(static_cast<std::uint64_t>(t * 2097151.0)) << c;
      }
      keyed.emplace_back(key, i);
    }
    std::sort(keyed.begin(), keyed.end());  // ties by natural id: the same order on every rank
    for (std::size_t k = 0; k < keyed.size(); ++k) order[g.first + static_cast<std::int64_t>(k)] = keyed[k].second;
  }
  return order;
}

Partition partition_from_parts(const Nodes& nodes, std::vector<int> part, int parts) {
  Partition p;
  p.parts = parts;
  p.part = std::move(part);
  const std::int64_t n = static_cast<std::int64_t>(p.part.size());
  if (n != nodes.size()) throw Error("partition_from_parts: a part for each of the " + std::to_string(nodes.size()) + " nodes");
  p.part_begin.assign(parts + 1, 0);
  for (std::int64_t i = 0; i < n; ++i) ++p.part_begin[p.part[i] + 1];
  std::partial_sum(p.part_begin.begin(), p.part_begin.end(), p.part_begin.begin());
  std::vector<std::int64_t> fill(p.part_begin.begin(), p.part_begin.end() - 1);
  p.natural_to_global.resize(n);
  p.global_to_natural.resize(n);
  for (const std::int64_t i : storage_order(nodes)) {  // stable: storage order inside a part
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

namespace {

// Rows [rank's share) of the cell graph on every rank; the whole graph gathered on rank 0 (the
// per-node neighbour search, the costly part, is split over the ranks).
CellGraph cell_graph_on_root(const Nodes& nodes, const CellList& cells, double size, MPI_Comm comm) {
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  CellGraph g = cell_graph(nodes, cells, size, rank, ranks);
  const std::int64_t total = g.cells;
  if (ranks == 1) return g;
  const int rows = static_cast<int>(g.vertex_weight.size()), edges = static_cast<int>(g.adjacency.size());
  std::vector<int> row_counts(ranks), edge_counts(ranks), row_displs(ranks, 0), edge_displs(ranks, 0);
  MPI_Gather(&rows, 1, MPI_INT, row_counts.data(), 1, MPI_INT, 0, comm);
  MPI_Gather(&edges, 1, MPI_INT, edge_counts.data(), 1, MPI_INT, 0, comm);
  std::int64_t all_edges = 0;
  for (int r = 1; r < ranks; ++r) {
    row_displs[r] = row_displs[r - 1] + row_counts[r - 1];
    edge_displs[r] = edge_displs[r - 1] + edge_counts[r - 1];
  }
  if (rank == 0) all_edges = static_cast<std::int64_t>(edge_displs[ranks - 1]) + edge_counts[ranks - 1];
  if (all_edges > std::numeric_limits<int>::max()) throw Error("the cell graph is too large to gather");
  std::vector<std::int64_t> degree(rows), all_degree(rank == 0 ? total : 0), vw(rank == 0 ? total : 0),
      ew(rank == 0 ? all_edges : 0);
  std::vector<std::int32_t> adj(rank == 0 ? all_edges : 0);
  for (int r = 0; r < rows; ++r) degree[r] = g.offsets[r + 1] - g.offsets[r];
  MPI_Gatherv(degree.data(), rows, MPI_INT64_T, all_degree.data(), row_counts.data(), row_displs.data(), MPI_INT64_T, 0, comm);
  MPI_Gatherv(g.vertex_weight.data(), rows, MPI_INT64_T, vw.data(), row_counts.data(), row_displs.data(), MPI_INT64_T, 0, comm);
  MPI_Gatherv(g.adjacency.data(), edges, MPI_INT32_T, adj.data(), edge_counts.data(), edge_displs.data(), MPI_INT32_T, 0, comm);
  MPI_Gatherv(g.edge_weight.data(), edges, MPI_INT64_T, ew.data(), edge_counts.data(), edge_displs.data(), MPI_INT64_T, 0, comm);
  if (rank != 0) return g;
  g.row_begin = 0;
  g.offsets.assign(total + 1, 0);
  for (std::int64_t c = 0; c < total; ++c) g.offsets[c + 1] = g.offsets[c] + all_degree[c];
  g.vertex_weight = std::move(vw);
  g.adjacency = std::move(adj);
  g.edge_weight = std::move(ew);
  return g;
}

// MatPartitioning on the cell graph, rows spread evenly over the ranks of comm; every rank gets
// the part of every cell.
std::vector<int> petsc_cell_parts(const Nodes& nodes, const CellList& cells, double size, int parts, int line_weight,
                                  MPI_Comm comm, CellGraph& local, std::string& type_used) {
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  local = cell_graph(nodes, cells, size, rank, ranks);  // this rank's rows
  const PetscInt m = static_cast<PetscInt>(local.vertex_weight.size());
  long long sums[2] = {0, 0}, global_sums[2];
  for (std::int64_t v : local.vertex_weight) sums[0] += v + 1;
  for (PetscInt r = 0; r < m; ++r)
    for (std::int64_t k = local.offsets[r]; k < local.offsets[r + 1]; ++k)
      sums[1] += partition_edge_weight(local, local.row_begin + r, k, line_weight);
  MPI_Allreduce(sums, global_sums, 2, MPI_LONG_LONG, MPI_SUM, comm);
  const std::int64_t vdiv = weight_divisor(global_sums[0]), ediv = weight_divisor(global_sums[1]);
  PetscInt *ia, *ja, *values, *vwgt;
  PERI_PETSC(PetscMalloc1(m + 1, &ia));
  PERI_PETSC(PetscMalloc1(local.adjacency.size(), &ja));
  PERI_PETSC(PetscMalloc1(local.adjacency.size(), &values));
  PERI_PETSC(PetscMalloc1(m, &vwgt));
  for (PetscInt r = 0; r <= m; ++r) ia[r] = static_cast<PetscInt>(local.offsets[r]);
  for (PetscInt r = 0; r < m; ++r)
    for (std::int64_t k = local.offsets[r]; k < local.offsets[r + 1]; ++k) {
      ja[k] = local.adjacency[k];
      values[k] = static_cast<PetscInt>(
          std::max<std::int64_t>(1, partition_edge_weight(local, local.row_begin + r, k, line_weight) / ediv));
    }
  for (PetscInt r = 0; r < m; ++r)
    vwgt[r] = static_cast<PetscInt>(std::max<std::int64_t>(1, (local.vertex_weight[r] + 1) / vdiv));
  OwnedMat adj;
  PERI_PETSC(MatCreateMPIAdj(comm, m, static_cast<PetscInt>(local.cells), ia, ja, values, adj.out()));  // owns ia, ja, values
  OwnedPartitioning mp;
  PERI_PETSC(MatPartitioningCreate(comm, mp.out()));
  PERI_PETSC(PetscObjectSetOptionsPrefix(reinterpret_cast<PetscObject>(mp.get()), "partition_"));
  PERI_PETSC(MatPartitioningSetAdjacency(mp, adj));
  PERI_PETSC(MatPartitioningSetNParts(mp, parts));
  PERI_PETSC(MatPartitioningSetVertexWeights(mp, vwgt));  // owns vwgt
  PERI_PETSC(MatPartitioningSetUseEdgeWeights(mp, PETSC_TRUE));
#if defined(PETSC_HAVE_PTSCOTCH)
  PERI_PETSC(MatPartitioningSetType(mp, MATPARTITIONINGPTSCOTCH));
#elif defined(PETSC_HAVE_PARMETIS)
  PERI_PETSC(MatPartitioningSetType(mp, MATPARTITIONINGPARMETIS));
#endif
  PERI_PETSC(MatPartitioningSetFromOptions(mp));
  MatPartitioningType type;
  PERI_PETSC(MatPartitioningGetType(mp, &type));
  type_used = type;
  OwnedIS is, all;
  PERI_PETSC(MatPartitioningApply(mp, is.out()));
  PERI_PETSC(ISAllGather(is, all.out()));
  const ISIndices p(all);
  std::vector<int> cell_part(p.data(), p.data() + local.cells);
  return cell_part;
}

}  // namespace

Partition partition_nodes(const Nodes& nodes, const CellList& cells, int parts, MPI_Comm comm,
                          PartitionSettings settings) {
  const std::int64_t n = nodes.size();
  std::vector<int> part(n, 0);
  if (parts <= 1) return partition_from_parts(nodes, std::move(part), 1);
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  if (n < parts) throw InputError("the scene has " + std::to_string(n) + " nodes, fewer than the " +
                                  std::to_string(parts) + " ranks; use fewer ranks");
  const auto t0 = std::chrono::steady_clock::now();
  settings.method = resolve_partition_method(settings.method, nodes);
  if (settings.method == PartitionMethod::Rcb) {
    Partition p = partition_from_parts(nodes, rcb_parts(nodes, parts, settings.line_weight), parts);
    p.edge_cut = -1;  // not known here: the domains count it (bonds to ghost nodes)
    p.graph_vertices = n;
    p.method = "rcb-node-coordinates";
    p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return p;
  }
  long long figures[2] = {0, 0};  // edge cut, graph vertices
  double balance = 1;
  std::string method;
  const CellGraph graph = settings.method == PartitionMethod::Cells
                              ? cell_graph_on_root(nodes, cells, cell_size_for(nodes, parts, settings.cells_per_part), comm)
                              : CellGraph{};
  if (settings.method == PartitionMethod::Petsc) {
    const double size = cell_size_for(nodes, parts, settings.cells_per_part);
    CellGraph local;
    std::string type;
    const std::vector<int> cell_part = petsc_cell_parts(nodes, cells, size, parts, settings.line_weight, comm, local, type);
    for (std::int64_t i = 0; i < n; ++i) part[i] = cell_part[local.cell_of[i]];
    // Quality from the rows each rank built.
    std::vector<long long> load(parts + 1, 0), sum(parts + 1);
    for (std::size_t c = 0; c < local.vertex_weight.size(); ++c) {
      const std::int64_t gc = local.row_begin + static_cast<std::int64_t>(c);
      load[cell_part[gc]] += local.vertex_weight[c];
      for (std::int64_t k = local.offsets[c]; k < local.offsets[c + 1]; ++k)
        if (cell_part[local.adjacency[k]] != cell_part[gc]) load[parts] += local.edge_weight[k];
    }
    MPI_Allreduce(load.data(), sum.data(), parts + 1, MPI_LONG_LONG, MPI_SUM, comm);
    long long total = 0;
    for (int k = 0; k < parts; ++k) total += sum[k];
    balance = total > 0 ? double(*std::max_element(sum.begin(), sum.end() - 1)) * parts / double(total) : 1.0;
    figures[0] = sum[parts] / 2;
    figures[1] = local.cells;
    method = "petsc-" + type + "-cell-graph";
  } else {
    int status = METIS_OK;
    std::string failure;
    if (rank == 0) {
      try {
        if (settings.method == PartitionMethod::Cells) {
          const CellGraph& g = graph;
          const std::vector<int> cell_part = metis_kway(g, parts, settings.line_weight);
          for (std::int64_t i = 0; i < n; ++i) part[i] = cell_part[g.cell_of[i]];
          const PartitionQuality q = quality(g, cell_part, parts);
          figures[0] = q.edge_cut;
          figures[1] = g.cells;
          balance = q.balance;
        } else {
          const BondGraph g = bond_graph(nodes, cells);
          std::int64_t cut = 0;
          part = metis_kway(g, parts, cut);
          const PartitionQuality q = quality(g, part, parts);
          figures[0] = q.edge_cut;
          figures[1] = n;
          balance = q.balance;
        }
      } catch (const Error& e) {
        status = METIS_ERROR;
        failure = e.what();
      }
    }
    MPI_Bcast(&status, 1, MPI_INT, 0, comm);
    if (status != METIS_OK) throw Error(rank == 0 ? failure : "METIS_PartGraphKway failed on rank 0");
    MPI_Bcast(part.data(), static_cast<int>(n), MPI_INT, 0, comm);
    MPI_Bcast(figures, 2, MPI_LONG_LONG, 0, comm);
    MPI_Bcast(&balance, 1, MPI_DOUBLE, 0, comm);
    method = settings.method == PartitionMethod::Cells ? "metis-kway-cell-graph" : "metis-kway-bond-graph";
  }
  Partition p = partition_from_parts(nodes, std::move(part), parts);
  p.edge_cut = figures[0];
  p.graph_vertices = figures[1];
  p.balance = balance;
  p.method = method;
  p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return p;
}

}  // namespace peri
