#include "peri/core/collective.hpp"

#include <sys/statvfs.h>

namespace peri {

std::string agree_on_message(const std::string& mine, MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  int failed = mine.empty() ? 0 : 1, any = 0;
  MPI_Allreduce(&failed, &any, 1, MPI_INT, MPI_MAX, comm);
  if (!any) return "";
  // Rank 0's message if it has one, else the first failing rank's.
  int first = failed ? rank : 1 << 30, lowest = 0;
  MPI_Allreduce(&first, &lowest, 1, MPI_INT, MPI_MIN, comm);
  long len = rank == lowest ? static_cast<long>(mine.size()) : 0;
  MPI_Bcast(&len, 1, MPI_LONG, lowest, comm);
  std::string msg = rank == lowest ? mine : std::string(static_cast<std::size_t>(len), ' ');
  MPI_Bcast(msg.data(), static_cast<int>(len), MPI_CHAR, lowest, comm);
  if (lowest != 0) msg += " (on rank " + std::to_string(lowest) + ")";
  return msg;
}

double free_bytes(const std::string& path) {
  struct statvfs s;
  if (statvfs(path.c_str(), &s) != 0) return -1;
  return static_cast<double>(s.f_bavail) * static_cast<double>(s.f_frsize);
}

}  // namespace peri
