// Helpers shared by the geometric fuzz targets (fuzz_crossing, fuzz_polygon).
#pragma once
#include <cmath>
#include <limits>

namespace fuzz_numbers {

/// x moved by k units in the last place.
inline double nudge(double x, int k) {
  for (; k > 0; --k) x = std::nextafter(x, std::numeric_limits<double>::infinity());
  for (; k < 0; ++k) x = std::nextafter(x, -std::numeric_limits<double>::infinity());
  return x;
}

/// Whether all n values are finite.
inline bool finite(const double* p, int n) {
  for (int k = 0; k < n; ++k)
    if (!std::isfinite(p[k])) return false;
  return true;
}

}  // namespace fuzz_numbers
