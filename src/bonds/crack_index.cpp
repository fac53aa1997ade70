#include "peri/bonds/crack_index.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "peri/bonds/bonds.hpp"

namespace peri {

namespace {

struct Box {
  double lo[2], hi[2];
};

// A crack's extent in x and y.
Box xy_box(const Crack& c) {
  Box box{{std::min(c.from[0], c.to[0]), std::min(c.from[1], c.to[1])},
          {std::max(c.from[0], c.to[0]), std::max(c.from[1], c.to[1])}};
  if (c.is_polygon()) {
    box = {{INFINITY, INFINITY}, {-INFINITY, -INFINITY}};
    for (const Vec3& x : c.polygon)
      for (int d = 0; d < 2; ++d) box.lo[d] = std::min(box.lo[d], x[d]), box.hi[d] = std::max(box.hi[d], x[d]);
  }
  return box;
}

}  // namespace

CrackIndex::CrackIndex(std::vector<const Crack*> cracks, double reach) : cracks_(std::move(cracks)) {
  if (cracks_.empty()) return;
  // 1% wider than the longest bond: rounding in the cell arithmetic may only list a crack in more
  // cells, never in fewer than it passes near.
  const double m = 1.01 * reach;
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, length = 0;
  for (const Crack* c : cracks_) {
    const Box box = xy_box(*c);
    for (int d = 0; d < 2; ++d) {
      lo[d] = std::min(lo[d], box.lo[d]);
      hi[d] = std::max(hi[d], box.hi[d]);
    }
    length += std::hypot(box.hi[0] - box.lo[0], box.hi[1] - box.lo[1]);
  }
  x0_ = lo[0] - m;
  y0_ = lo[1] - m;
  const double w = hi[0] + m - x0_, h = hi[1] + m - y0_, n = static_cast<double>(cracks_.size());
  // Cells: at least the reach, about one crack's share of the box, and wide enough that the long
  // cracks' lists stay within about 16 entries per crack plus 4M.
  size_ = std::max({m, std::sqrt(w * h / n), 3.0 * length / (16.0 * n + 4e6)});
  while (std::isfinite(size_) && (w / size_ + 1) * (h / size_ + 1) > 4 * n + 4096) size_ *= 1.5;
  if (!(std::isfinite(size_) && size_ > 0 && std::isfinite(w) && std::isfinite(h))) {
    // Coordinates beyond what a grid can cover: one cell, every crack tested against every bond.
    nx_ = ny_ = 1;
    size_ = INFINITY;
    start_ = {0, static_cast<std::int64_t>(cracks_.size())};
    listed_.resize(cracks_.size());
    for (std::size_t k = 0; k < cracks_.size(); ++k) listed_[k] = static_cast<std::int32_t>(k);
    return;
  }
  nx_ = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(w / size_)));
  ny_ = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(h / size_)));
  auto column = [&](double x) { return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor((x - x0_) / size_)), 0, nx_ - 1); };
  auto row = [&](double y) { return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor((y - y0_) / size_)), 0, ny_ - 1); };
  // Every cell with a point within m (Chebyshev) of crack k: per row of cells, the part of the
  // crack within m of the row (its y range grown by m), grown by m along x.
  // A polygon: every cell within m of its xy bounding box.
  auto visit = [&](std::size_t k, auto&& list) {
    const Crack& c = *cracks_[k];
    if (c.is_polygon()) {
      const Box box = xy_box(c);
      for (std::int64_t j = row(box.lo[1] - m), j1 = row(box.hi[1] + m); j <= j1; ++j)
        for (std::int64_t i = column(box.lo[0] - m), i1 = column(box.hi[0] + m); i <= i1; ++i) list(j * nx_ + i);
      return;
    }
    const double cx = c.from[0], cy = c.from[1], ex = c.to[0] - cx, ey = c.to[1] - cy;
    for (std::int64_t j = row(std::min(cy, cy + ey) - m), j1 = row(std::max(cy, cy + ey) + m); j <= j1; ++j) {
      double t0 = 0, t1 = 1;
      if (ey != 0) {
        t0 = (y0_ + static_cast<double>(j) * size_ - m - cy) / ey;
        t1 = (y0_ + static_cast<double>(j + 1) * size_ + m - cy) / ey;
        if (t0 > t1) std::swap(t0, t1);
        t0 = std::max(t0, 0.0);
        t1 = std::min(t1, 1.0);
        if (t0 > t1) continue;
      }
      const double xa = cx + t0 * ex, xb = cx + t1 * ex;
      for (std::int64_t i = column(std::min(xa, xb) - m), i1 = column(std::max(xa, xb) + m); i <= i1; ++i)
        list(j * nx_ + i);
    }
  };
  start_.assign(static_cast<std::size_t>(nx_ * ny_) + 1, 0);
  for (std::size_t k = 0; k < cracks_.size(); ++k) visit(k, [&](std::int64_t cell) { ++start_[cell + 1]; });
  for (std::size_t cell = 1; cell < start_.size(); ++cell) start_[cell] += start_[cell - 1];
  listed_.resize(static_cast<std::size_t>(start_.back()));
  std::vector<std::int64_t> next(start_.begin(), start_.end() - 1);
  for (std::size_t k = 0; k < cracks_.size(); ++k)
    visit(k, [&](std::int64_t cell) { listed_[next[cell]++] = static_cast<std::int32_t>(k); });
}

bool CrackIndex::crosses_any(const double* a, const double* b, int dimension, std::vector<char>* met) const {
  if (cracks_.empty()) return false;
  std::int64_t cell = 0;
  if (std::isfinite(size_)) {
    const double i = std::floor((a[0] - x0_) / size_), j = std::floor((a[1] - y0_) / size_);
    // Outside the grid: farther than the reach from every crack.
    if (!(i >= 0 && i < static_cast<double>(nx_) && j >= 0 && j < static_cast<double>(ny_))) return false;
    cell = static_cast<std::int64_t>(j) * nx_ + static_cast<std::int64_t>(i);
  }
  bool any = false;
  for (std::int64_t p = start_[cell]; p < start_[cell + 1]; ++p) {
    const std::int32_t k = listed_[p];
    if (any && (*met)[k]) continue;
    if (!cracks_[k]->cuts_dimension(dimension) || !crosses(a, b, *cracks_[k])) continue;
    if (!met) return true;
    (*met)[k] = 1;
    any = true;
  }
  return any;
}

}  // namespace peri
