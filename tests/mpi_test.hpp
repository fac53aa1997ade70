// Shared by the tests that run under MPI (tests/mpi_main.cpp initializes PETSc and prints
// results on rank 0 only; the exit status is the worst over all ranks).
#pragma once
#include <petscsys.h>

namespace peri {

inline int world_rank() {
  int r;
  MPI_Comm_rank(PETSC_COMM_WORLD, &r);
  return r;
}

}  // namespace peri
