#include "peri/kernels/tip_advance.hpp"

#include "peri/kernels/bond_loop.hpp"

namespace peri {

void stamp_breaks(const BondView& v, const std::int32_t* rows, std::size_t n, std::int32_t* count, double* stamp,
                  std::vector<std::int32_t>& damaged, double time) {
  for (std::size_t r = 0; r < n; ++r) {
    const std::int32_t i = rows[r];
    if (v.row_broken && !v.row_broken[i]) continue;  // no flagged bond
    std::int32_t c = 0;
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) c += v.broken[b] & kBrokenFlag;
    if (c <= count[i]) continue;
    if (count[i] == 0) damaged.push_back(i);
    count[i] = c;
    stamp[i] = time;
  }
}

void mark_crack_tips(const BondView& v, const std::vector<std::int32_t>& damaged, const double* stamp, double now,
                     std::uint8_t* tip) {
  for (std::int32_t i : damaged) {
    const double t = stamp[i];
    if (!(t < now)) continue;
    bool newest = true;
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1] && newest; ++b) {
      const double tj = stamp[v.neighbor[b]];
      newest = !(tj > t && tj < now);
    }
    tip[i] = newest ? 1 : 0;
  }
}

void latest_breaks(const std::vector<std::int32_t>& damaged, const int* body, const double* stamp, double now,
                   const std::vector<std::uint8_t>& by_body, std::vector<double>& latest) {
  for (std::int32_t i : damaged) {
    const auto b = static_cast<std::size_t>(body[i]);
    if (by_body[b] && stamp[i] < now && stamp[i] > latest[b]) latest[b] = stamp[i];
  }
}

void mark_latest_tips(const std::vector<std::int32_t>& damaged, const int* body, const double* stamp,
                      const std::vector<std::uint8_t>& by_body, const std::vector<double>& latest, std::uint8_t* tip) {
  for (std::int32_t i : damaged) {
    const auto b = static_cast<std::size_t>(body[i]);
    if (by_body[b]) tip[i] = stamp[i] == latest[b] ? 1 : 0;
  }
}

void mark_within(const BondView& v, std::int32_t owned, const int* body, const std::vector<std::int32_t>& marked_rows,
                 const std::vector<std::int32_t>& boundary_rows, const std::uint8_t* marked,
                 const std::vector<double>& radius2, std::uint8_t* out) {
  for (std::int32_t i : marked_rows) {
    if (!marked[i]) continue;
    out[i] = 1;
    const double r2 = radius2[body[i]];
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) {
      const std::int32_t j = v.neighbor[b];
      if (j < owned && v.xi2(i, b) <= r2) out[j] = 1;
    }
  }
  for (std::int32_t i : boundary_rows) {
    const double r2 = radius2[body[i]];
    for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1] && !out[i]; ++b) {
      const std::int32_t j = v.neighbor[b];
      if (j >= owned && marked[j] && v.xi2(i, b) <= r2) out[i] = 1;
    }
  }
}

}  // namespace peri
