#include "peri/kernels/tangent.hpp"

#include <cmath>

namespace peri {

double coefficient_slope(const BondLaw& law, double xi2, double y2) noexcept {
  const double xi = std::sqrt(xi2);
  const double g = law.influence(xi);
  if (law.kind == ModelKind::Membrane) {
    // k = 2cg/xi^2 (1 - xi^4/y^4)  =>  dk/dy^2 = 4 c g xi^2 / y^6   (derivative of eq. 15 / y)
    double slope = 4.0 * law.c * g * xi2 / (y2 * y2 * y2);
    if (law.hardening) {
      // k_h = a (lambda^(n-1) - 1)/y, a = c' n g/xi  (eq. 16)  =>  dk_h/dy^2 = (dk_h/dy) / (2y)
      const double y = std::sqrt(y2), lam = y / xi, n = law.hard_n;
      const double a = law.hard_c * n * g / xi;
      const double dk_dy = a * ((n - 1.0) * std::pow(lam, n - 2.0) / (xi * y) - (std::pow(lam, n - 1.0) - 1.0) / y2);
      slope += dk_dy / (2.0 * y);
    }
    return slope;
  }
  // PMB: k = c g (1/xi - 1/y)  =>  dk/dy^2 = c g / (2 y^3)
  const double y = std::sqrt(y2);
  return 0.5 * law.c * g / (y2 * y);
}

void row_tangent(const BondLaw& law, const BondView& view, std::int32_t row, std::vector<std::int32_t>& cols,
                 std::vector<double>& blocks) {
  const std::int64_t begin = view.offsets[row], end = view.offsets[row + 1];
  cols.clear();
  cols.push_back(row);
  for (std::int64_t b = begin; b < end; ++b)
    if (!view.broken[b]) cols.push_back(view.neighbor[b]);
  const std::size_t n = cols.size(), stride = 3 * n;
  blocks.assign(3 * stride, 0.0);
  const double* Xi = view.X + 3 * static_cast<std::size_t>(row);
  const double* ui = view.u + 3 * static_cast<std::size_t>(row);
  std::size_t col = 1;
  for (std::int64_t b = begin; b < end; ++b) {
    if (view.broken[b]) continue;
    const std::int32_t j = view.neighbor[b];
    const double* Xj = view.X + 3 * static_cast<std::size_t>(j);
    const double* uj = view.u + 3 * static_cast<std::size_t>(j);
    double r[3];
    for (int c = 0; c < 3; ++c) r[c] = Xj[c] - Xi[c] + uj[c] - ui[c];
    const double xi2 = view.xi2(row, b);
    const double y2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    const double scale = view.volume[row] * view.measure(row, b);
    const double k = law.coefficient(xi2, y2), k2 = 2.0 * coefficient_slope(law, xi2, y2);
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) {
        const double A = scale * ((a == c ? k : 0.0) + k2 * r[a] * r[c]);
        blocks[a * stride + c] += A;                // K_ii
        blocks[a * stride + 3 * col + c] = -A;      // K_ij
      }
    ++col;
  }
}

double reference_stiffness_sum(const BondLaw& law, const BondView& view, const std::int32_t* rows,
                               std::size_t nrows) {
  double sum = 0;
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    double row = 0;
    for (std::int64_t b = view.offsets[i]; b < view.offsets[i + 1]; ++b)
      row += view.measure(i, b) * law.reference_stiffness(view.xi2(i, b));
    sum += view.volume[i] * row;
  }
  return sum;
}

}  // namespace peri
