// The run's phases as PETSc log events, so that -log_view tells where the time goes: setup and
// its phases (nodes, partition, bonds, plans), then each step's forces (with the long-range
// pairs and their rebuilds inside), halo exchange, update and output.
#pragma once
#include <petsclog.h>

namespace peri {

struct Events {
  PetscLogEvent setup, nodes, partition, bonds, plans, forces, halo, update, output, long_range, long_range_build;
};
/// Registered on first use.
const Events& events();

}  // namespace peri
