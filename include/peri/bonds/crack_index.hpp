// Pre-cracks indexed by where they lie, so that a bond tests only the cracks near it (crosses()
// in bonds.hpp): the pre-crack pass of a sheet with many cracks costs O(bonds x cracks near a
// node), not O(bonds x cracks).
//
// A uniform grid of square cells over the cracks' xy bounding box: each crack is listed in every
// cell that has a point within `reach` of it (Chebyshev distance, a superset of the Euclidean
// one; a polygon, of its xy bounding box). A bond no longer than `reach` can only meet cracks that pass within `reach` of its first
// end, all listed in that end's cell. Cells are at least `reach` wide, about one crack's share of
// the box, and wide enough that the lists hold O(cracks + 4M) entries whatever the cracks' lengths.
#pragma once
#include <cstdint>
#include <vector>

#include "peri/scene/scene.hpp"

namespace peri {

class CrackIndex {
 public:
  /// `reach` [m]: the longest bond that will be asked about.
  CrackIndex(std::vector<const Crack*> cracks, double reach);
  /// crosses(a, b, crack) for some indexed crack that cuts bodies of this dimension
  /// (Crack::cuts_dimension); a-b no longer than the reach. With `met` (one flag per crack, in
  /// the order given), every crack not yet flagged that the bond meets is flagged too.
  bool crosses_any(const double* a, const double* b, int dimension, std::vector<char>* met = nullptr) const;

 private:
  std::vector<const Crack*> cracks_;
  double x0_ = 0, y0_ = 0, size_ = 1;
  std::int64_t nx_ = 0, ny_ = 0;
  std::vector<std::int64_t> start_;  // per cell, into listed_ (cells + 1)
  std::vector<std::int32_t> listed_;  // crack indices grouped by cell, ascending inside a cell
};

}  // namespace peri
