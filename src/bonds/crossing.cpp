#include "peri/bonds/crossing.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <initializer_list>

namespace peri {

namespace {

// |x| = m 2^e with m < 2^53 an integer and e >= -1074, read off the bits of a finite double.
struct Split {
  std::uint64_t m;
  int e;
  bool negative;
};

Split split(double x) {
  const auto bits = std::bit_cast<std::uint64_t>(x);
  const int field = static_cast<int>((bits >> 52) & 0x7ff);
  const std::uint64_t fraction = bits & ((std::uint64_t{1} << 52) - 1);
  if (field == 0) return {fraction, -1074, (bits >> 63) != 0};  // zero and subnormals
  return {fraction | (std::uint64_t{1} << 52), field - 1075, (bits >> 63) != 0};
}

// A non-negative integer in units of 2^-2148, the least non-zero |product| of two doubles. A
// product of two finite doubles is below 2^(106 + 2 * 971), i.e. below 2^4196 units; 66 limbs of
// 64 bits hold a sum of six of them with room to spare. Exact for every finite input: unlike
// expansions of doubles, nothing here can overflow or underflow.
constexpr int kLimbs = 66;

struct Fixed {
  std::uint64_t limb[kLimbs] = {};

  // Adds v * 2^shift (v < 2^106, 0 <= shift <= 4090).
  void add(unsigned __int128 v, int shift) {
    const int q = shift / 64, r = shift % 64;
    const auto lo = static_cast<std::uint64_t>(v), hi = static_cast<std::uint64_t>(v >> 64);
    const std::uint64_t w[3] = {lo << r, r ? (lo >> (64 - r)) | (hi << r) : hi, r ? hi >> (64 - r) : 0};
    std::uint64_t carry = 0;
    for (int k = q; k < kLimbs && (k < q + 3 || carry); ++k) {
      const std::uint64_t add = k < q + 3 ? w[k - q] : 0;
      const std::uint64_t s = limb[k] + add;
      const std::uint64_t t = s + carry;
      carry = (s < add) + (t < s);
      limb[k] = t;
    }
  }
};

// -1, 0, +1 as x < y, x == y, x > y.
int compare(const Fixed& x, const Fixed& y) {
  for (int k = kLimbs - 1; k >= 0; --k)
    if (x.limb[k] != y.limb[k]) return x.limb[k] > y.limb[k] ? 1 : -1;
  return 0;
}

// Exact sign of ax (by - cy) + bx (cy - ay) + cx (ay - by), expanded into its six products of
// input coordinates: each product m_x m_y 2^(e_x + e_y) exactly, summed into the positive and the
// negative part.
int orient2d_exact(const double* a, const double* b, const double* c) {
  for (const double* p : {a, b, c})
    if (!std::isfinite(p[0]) || !std::isfinite(p[1])) return 0;
  struct Term {
    double x, y;
    bool minus;
  };
  const Term terms[6] = {{a[0], b[1], false}, {a[0], c[1], true}, {b[0], c[1], false},
                         {b[0], a[1], true},  {c[0], a[1], false}, {c[0], b[1], true}};
  Fixed plus, minus;
  for (const Term& t : terms) {
    const Split x = split(t.x), y = split(t.y);
    if (x.m == 0 || y.m == 0) continue;
    const unsigned __int128 v = static_cast<unsigned __int128>(x.m) * y.m;
    ((x.negative != y.negative) != t.minus ? minus : plus).add(v, x.e + y.e + 2148);
  }
  return compare(plus, minus);
}

}  // namespace

int orient2d(const double* a, const double* b, const double* c) {
  // Floating-point filter. Each operation rounds with a relative error of at most u = 2^-53, and
  // a product landing below the normal range adds an absolute error of at most 2^-1075 (sums and
  // differences of doubles are exact there). Then |det - exact| < 3.01 u (|l| + |r|) + 3 * 2^-1075
  // (the same holds when the compiler fuses l - r into one fma), which `bound` exceeds: a det
  // beyond it has the exact sign. Overflow or a non-finite input leaves det or bound infinite or
  // NaN, which no comparison below passes.
  const double l = (b[0] - a[0]) * (c[1] - a[1]);
  const double r = (b[1] - a[1]) * (c[0] - a[0]);
  const double det = l - r;
  const double bound = 0x1p-51 * (std::fabs(l) + std::fabs(r)) + 0x1p-1070;
  if (det > bound) return 1;
  if (-det > bound) return -1;
  return orient2d_exact(a, b, c);  // (nearly) collinear points, extreme magnitudes, non-finite input
}

bool segments_cross(const double* a, const double* b, const double* c, const double* d) {
  // Disjoint bounding boxes: no common point (exact comparisons; most bonds end here). With a NaN
  // the test may go either way, and both ways end in false.
  if (std::max(a[0], b[0]) < std::min(c[0], d[0]) || std::max(c[0], d[0]) < std::min(a[0], b[0]) ||
      std::max(a[1], b[1]) < std::min(c[1], d[1]) || std::max(c[1], d[1]) < std::min(a[1], b[1]))
    return false;
  for (const double* p : {a, b, c, d})
    if (!std::isfinite(p[0]) || !std::isfinite(p[1])) return false;
  if ((a[0] == b[0] && a[1] == b[1]) || (c[0] == d[0] && c[1] == d[1])) return false;  // a point cuts nothing
  const int o1 = orient2d(a, b, c), o2 = orient2d(a, b, d);
  // All four points on one line: along it the segments are intervals, which overlap (or touch)
  // exactly when the bounding boxes do, as they do here.
  if (o1 == 0 && o2 == 0) return true;
  if (o1 * o2 > 0) return false;  // c and d strictly on the same side of the line a b
  const int o3 = orient2d(c, d, a), o4 = orient2d(c, d, b);
  return o3 * o4 <= 0;
}

}  // namespace peri
