// Fracture energy: the energy release rate G of a peridynamic membrane, measured as the work
// needed to advance a crack slowly, and its closed form, eq. (30). No MPI, no PETSc.
//
// Method. When a straight crack advances quasi-statically by a segment, every bond crossing the
// segment is stretched slowly up to its critical stretch lambda_0 and breaks there, taking its
// energy at breaking w_0 (eq. 26) with it; bonds not crossing it are unloaded again (elastic, no
// loss). The work needed per unit new crack area (thickness h times length) is therefore
//   G_h = sum over bonds (i, j) crossing the segment of w_0(|xi_ij|) w_ij V_i V_j / (h |segment|),
// computed on the discretization the solver uses (nodes, partial-area weights w_ij, the same
// bond-crossing test as the pre-cracks). Its continuum limit is eq. (30):
//   G = 2 h int_0^delta w_0(xi) xi^2 dxi   (the inner integrals of (30) give int_0^xi acos(z/xi) dz = xi),
// which is 2 h w_0 delta^3 / 3 for g = 1 and constant lambda_0.
#pragma once
#include <cstdint>

#include "peri/bonds/bonds.hpp"
#include "peri/models/model.hpp"

namespace peri {

struct CrackAdvanceEnergy {
  double energy = 0;          ///< sum of w_0 w_ij V_i V_j over the crossing bonds [J]
  double release_rate = 0;    ///< G_h = energy / (h |segment|) [J/m^2]
  std::int64_t bonds = 0;     ///< bonds crossing the segment
};

/// Work to advance a crack through `body` by the segment `advance` (membrane bodies; the segment
/// must lie at least a horizon inside the body so that families are complete).
CrackAdvanceEnergy crack_advance_energy(const Nodes& nodes, const CellList& cells, const BondLaw& law, int body,
                                        const Crack& advance);

/// The same work for a volume (solid bodies): the bonds crossing the polygon crack `advance` (at
/// least a horizon inside the body), per unit of its area,
///   G_h = sum of w_0(|xi_ij|) w_ij V_i V_j over them / area.
/// Its continuum limit is pmb_release_rate_3d.
CrackAdvanceEnergy crack_advance_energy_3d(const Nodes& nodes, const CellList& cells, const BondLaw& law, int body,
                                           const Crack& advance);

/// The energy release rate of a peridynamic volume: the energy of the bonds crossing a unit area
/// of a plane, G = pi int_0^delta w_0(xi) xi^3 dxi (a bond of length xi at angle phi to the normal
/// crosses the plane from within xi cos(phi) of it: int_0^xi (1 - z/xi) dz = xi/2 over the
/// sphere's 2 pi); pi c s_0^2 delta^5 / 10 for the PMB bond's w_0 = c s_0^2 xi / 2 (Silling and
/// Askari 2005).
double release_rate_3d(const BondLaw& law);

/// Eq. (30): G = 2 h int_0^delta w_0(xi) xi^2 dxi for the law's influence function and critical
/// stretch (closed form 2 h w_0 delta^3 / 3 for g = 1 and constant lambda_0).
double eq30_release_rate(const BondLaw& law, double thickness);

}  // namespace peri
