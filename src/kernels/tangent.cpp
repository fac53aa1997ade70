#include "peri/kernels/tangent.hpp"

#include "peri/kernels/bond_loop.hpp"

namespace peri {

void row_tangent(const BondLaw& law, const BondView& view, std::int32_t row, std::vector<std::int32_t>& cols,
                 std::vector<double>& blocks) {
  law.entry().row_tangent(law.constants(), view, row, cols, blocks);
}

double reference_stiffness_sum(const BondLaw& law, const BondView& view, const std::int32_t* rows,
                               std::size_t nrows) {
  double sum = 0;
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    double row = 0;
    for (const FamilyBond& bond : family(view, i)) row += bond.measure() * law.reference_stiffness(bond.xi2());
    sum += view.volume[i] * row;
  }
  return sum;
}

}  // namespace peri
