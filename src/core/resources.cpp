#include "peri/core/resources.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "peri/core/error.hpp"

namespace peri {
namespace {

double read_number_file(const char* path) {
  std::ifstream in(path);
  std::string s;
  if (!(in >> s) || s == "max") return 0;
  try {
    return std::stod(s);
  } catch (...) {
    return 0;
  }
}

/// Count or size as text; an estimate that overflowed reads ">1e308".
std::string num(double v, const char* unit = "") {
  char buf[64];
  if (std::isfinite(v)) std::snprintf(buf, sizeof buf, "%.4g%s", v, unit);
  else std::snprintf(buf, sizeof buf, ">1e308%s", unit);
  return buf;
}
std::string gb(double bytes) { return num(bytes / 1e9, " GB"); }

}  // namespace

MemoryNeed memory_need(const SizeEstimate& e, int ranks, bool full_bond_graph) {
  MemoryNeed m;
  m.per_rank = e.bytes / std::max(ranks, 1) + 72.0 * e.nodes;
  m.rank0 = m.per_rank + (ranks > 1 && full_bond_graph ? 24.0 * e.bonds : 0.0);
  return m;
}

double available_memory() {
  double available = 0;
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  double kb = 0;
  std::string unit;
  while (meminfo >> key >> kb >> unit)
    if (key == "MemAvailable:") {
      available = kb * 1024.0;
      break;
    }
  const double limit = std::max(read_number_file("/sys/fs/cgroup/memory.max"),
                                read_number_file("/sys/fs/cgroup/memory/memory.limit_in_bytes"));
  if (limit > 0 && limit < 1e18 && (available == 0 || limit < available)) available = limit;
  return available;
}

ProcessMemory process_memory() {
  ProcessMemory m;
  std::ifstream status("/proc/self/status");
  std::string key;
  double kb = 0;
  std::string line;
  while (std::getline(status, line)) {
    std::istringstream s(line);
    if (!(s >> key >> kb)) continue;
    if (key == "VmHWM:") m.peak = kb * 1024.0;
    else if (key == "VmRSS:") m.current = kb * 1024.0;
  }
  return m;
}

std::string describe(const SizeEstimate& e) {
  return "about " + num(e.nodes) + " nodes, " + num(e.bonds / 2) + " bonds, " + gb(e.bytes) + " in all";
}

void check_fits(const Scene& scene, MPI_Comm comm, bool full_bond_graph) {
  int rank = 0, ranks = 1, host_ranks = 1, host_rank = 0;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  MPI_Comm host;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, rank, MPI_INFO_NULL, &host);
  MPI_Comm_size(host, &host_ranks);
  MPI_Comm_rank(host, &host_rank);
  // Rank 0's host carries the partitioner's bond graph as well (-partition_method bonds).
  int has_rank0 = rank == 0, host_has_rank0 = 0;
  MPI_Allreduce(&has_rank0, &host_has_rank0, 1, MPI_INT, MPI_MAX, host);
  MPI_Comm_free(&host);

  const SizeEstimate e = estimate_size(scene);
  const MemoryNeed m = memory_need(e, ranks, full_bond_graph);
  double need = m.per_rank * host_ranks + (host_has_rank0 ? m.rank0 - m.per_rank : 0.0);
  if (!(need <= 1e300)) need = HUGE_VAL;  // an overflowed estimate (huge sizes) must still refuse
  const double have = available_memory();
  // The worst host decides, the same way on every rank.
  double local[2] = {have > 0 ? need / have : 0.0, need}, worst[2];
  MPI_Allreduce(local, worst, 2, MPI_DOUBLE, MPI_MAX, comm);
  double have_min = have > 0 ? have : 1e300, have_all = 0;
  MPI_Allreduce(&have_min, &have_all, 1, MPI_DOUBLE, MPI_MIN, comm);
  if (worst[0] <= 1.0) return;
  std::ostringstream msg;
  msg << scene.file << ": the scene cannot fit in memory: " << describe(e) << "; " << gb(m.per_rank)
      << " per rank (" << gb(m.rank0) << " on rank 0) on " << ranks << " rank" << (ranks > 1 ? "s" : "")
      << ", up to " << gb(worst[1]) << " on one host, which has " << gb(have_all)
      << " available; increase the spacing, or run on more hosts";
  throw InputError(msg.str());
}

}  // namespace peri
