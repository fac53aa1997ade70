#include "peri/stages/events.hpp"

namespace peri {
namespace {

Events register_events() {
  Events e;
  PetscClassId id;
  PetscClassIdRegister("peridrive", &id);
  PetscLogEventRegister("PeriSetup", id, &e.setup);
  // Phases of PeriSetup: nodes and the neighbour search structure, the partition, this rank's
  // bond families and ghosts, and the bond loop's plans.
  PetscLogEventRegister("PeriNodes", id, &e.nodes);
  PetscLogEventRegister("PeriPartition", id, &e.partition);
  PetscLogEventRegister("PeriBonds", id, &e.bonds);
  PetscLogEventRegister("PeriPlans", id, &e.plans);
  PetscLogEventRegister("PeriForces", id, &e.forces);
  PetscLogEventRegister("PeriHalo", id, &e.halo);
  PetscLogEventRegister("PeriUpdate", id, &e.update);
  PetscLogEventRegister("PeriOutput", id, &e.output);
  // Inside PeriForces: the long-range pairs (their halo exchange and sums), and inside that the
  // rebuilds of their halo and Verlet list.
  PetscLogEventRegister("PeriLongRange", id, &e.long_range);
  PetscLogEventRegister("PeriLongRangeBuild", id, &e.long_range_build);
  return e;
}

}  // namespace

const Events& events() {
  static const Events e = register_events();
  return e;
}

}  // namespace peri
