// Tangent: the bond stiffness of a family, for the quasi-static loader's Newton iterations.
// Pure kernel (no MPI, no PETSc): for an owned row i it returns the 3 x 3(n+1) block row of
// K = -d(F V)/du, where F_i = sum_j k w_ij V_j (x_j - x_i) is the force density of eq. (12)
// written with the law's coefficient k = f / y (models/laws/, one definition with the forces):
//   A_ij = V_i w_ij V_j [k I + 2 k' r r^T],  r = x_j - x_i,  k' = dk/d(y^2)
//   K_ii = sum_j A_ij,   K_ij = -A_ij.
#pragma once
#include <cstdint>
#include <vector>

#include "peri/kernels/forces.hpp"

namespace peri {

/// Block row of the tangent of owned row `row` over its intact bonds (current positions from
/// view.x). On return `cols` holds the local column indices (the row itself first, then one per
/// intact bond) and `blocks` the 3 x 3*cols.size() row-major values (PETSc's MatSetValuesBlocked
/// layout for one block row).
void row_tangent(const BondLaw& law, const BondView& view, std::int32_t row, std::vector<std::int32_t>& cols,
                 std::vector<double>& blocks);

/// Sum over `rows` of V_i sum_j w_ij V_j C_ij (C: reference bond stiffness), a stiffness scale [N/m]
/// of the tangent's diagonal at the reference state.
double reference_stiffness_sum(const BondLaw& law, const BondView& view, const std::int32_t* rows,
                               std::size_t nrows);

}  // namespace peri
