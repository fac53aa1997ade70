// The release stage (e.g. after a quasi-static preload): every intact bond crossing the named
// cracks breaks in the current state, and its current energy becomes dissipated energy, so the
// energy balance continues exactly. No time passes.
#pragma once
#include <cstdint>

#include "peri/diagnostics/energies.hpp"
#include "peri/stages/problem.hpp"

namespace peri {

/// Breaks the bonds crossing `stage`'s cracks; books their energy and count in the ledger.
/// Returns the bonds released on all ranks (bonds, not ordered bonds). Collective.
std::int64_t release_cracks(Problem& p, const Stage& stage, EnergyLedger& ledger);

/// Before the run (after the domain is built, with the bodies p.bodies): each release stage's
/// cracks must cross some bond of the reference configuration, broken or not; a stage whose
/// cracks cross none (misplaced: outside every body they cut) is refused with InputError on every
/// rank. Collective.
void check_release_stages(const Problem& p);

}  // namespace peri
