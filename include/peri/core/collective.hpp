// Verdicts every rank reaches together: a failure seen by some ranks becomes the same exception
// on all of them, at the same point, so that no rank waits in a collective call (an MPI
// reduction, a parallel HDF5 call) that another rank has left.
#pragma once
#include <mpi.h>

#include <string>

namespace peri {

/// One verdict for all ranks: empty when no rank has a message, else the message of the lowest
/// failing rank (naming that rank when it is not rank 0). Collective.
std::string agree_on_message(const std::string& mine, MPI_Comm comm);

/// Free bytes for an unprivileged writer on the file system that holds `path` (a file or a
/// directory), or -1 when it cannot be told.
double free_bytes(const std::string& path);

}  // namespace peri
