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

// A non-negative integer in units of 2^-Unit (2^-2148: the least non-zero |product| of two
// doubles; 2^-3222, of three) in Limbs limbs of 64 bits. A product of two finite doubles is below
// 2^(106 + 2 * 971), i.e. below 2^4196 units; 66 limbs hold a sum of six of them with room to
// spare. A product of three is below 2^(159 + 3 * 971 + 3222) units; 100 limbs hold a sum of 24.
// Exact for every finite input: unlike expansions of doubles, nothing here can overflow or
// underflow.
template <int Limbs>
struct Fixed {
  std::uint64_t limb[Limbs] = {};

  // Adds w * 2^shift, w given as `words` words of 64 bits, least significant first (0 <= shift,
  // shift + 64 words below 64 Limbs).
  template <int Words>
  void add(const std::uint64_t (&w)[Words], int shift) {
    const int q = shift / 64, r = shift % 64;
    std::uint64_t carry = 0;
    for (int k = q; k < Limbs && (k <= q + Words || carry); ++k) {
      const int i = k - q;  // word i of w << r: the low bits of w[i], the high bits of w[i - 1]
      std::uint64_t add = 0;
      if (i <= Words) {
        const std::uint64_t lo = i < Words ? w[i] << r : 0;
        const std::uint64_t hi = (i > 0 && r) ? w[i - 1] >> (64 - r) : 0;
        add = lo | hi;
      }
      const std::uint64_t s = limb[k] + add;
      const std::uint64_t t = s + carry;
      carry = (s < add) + (t < s);
      limb[k] = t;
    }
  }
};

// -1, 0, +1 as x < y, x == y, x > y.
template <int Limbs>
int compare(const Fixed<Limbs>& x, const Fixed<Limbs>& y) {
  for (int k = Limbs - 1; k >= 0; --k)
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
  Fixed<66> plus, minus;
  for (const Term& t : terms) {
    const Split x = split(t.x), y = split(t.y);
    if (x.m == 0 || y.m == 0) continue;
    const unsigned __int128 v = static_cast<unsigned __int128>(x.m) * y.m;
    const std::uint64_t w[2] = {static_cast<std::uint64_t>(v), static_cast<std::uint64_t>(v >> 64)};
    ((x.negative != y.negative) != t.minus ? minus : plus).add(w, x.e + y.e + 2148);
  }
  return compare(plus, minus);
}

// Exact sign of det [a - d; b - d; c - d], expanded as the 4 x 4 determinant with rows
// [p_x, p_y, p_z, 1] into its 24 products of three input coordinates, each summed exactly.
int orient3d_exact(const double* a, const double* b, const double* c, const double* d) {
  const double* row[4] = {a, b, c, d};
  for (const double* p : row)
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(p[k])) return 0;
  Fixed<100> plus, minus;
  int perm[4] = {0, 1, 2, 3};  // column of each row; the row whose column is 3 contributes its 1
  do {
    int inversions = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) inversions += perm[i] > perm[j];
    Split f[3];
    int n = 0;
    bool zero = false, negative = inversions % 2 == 1;
    for (int r = 0; r < 4; ++r) {
      if (perm[r] == 3) continue;
      f[n] = split(row[r][perm[r]]);
      zero = zero || f[n].m == 0;
      negative = negative != f[n].negative;
      ++n;
    }
    if (zero) continue;
    // m0 m1 m2 < 2^159 in three words.
    const unsigned __int128 p01 = static_cast<unsigned __int128>(f[0].m) * f[1].m;
    const unsigned __int128 lo = static_cast<unsigned __int128>(static_cast<std::uint64_t>(p01)) * f[2].m;
    const unsigned __int128 hi = static_cast<unsigned __int128>(static_cast<std::uint64_t>(p01 >> 64)) * f[2].m +
                                 static_cast<std::uint64_t>(lo >> 64);
    const std::uint64_t w[3] = {static_cast<std::uint64_t>(lo), static_cast<std::uint64_t>(hi),
                                static_cast<std::uint64_t>(hi >> 64)};
    (negative ? minus : plus).add(w, f[0].e + f[1].e + f[2].e + 3222);
  } while (std::next_permutation(perm, perm + 4));
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

int orient3d(const double* a, const double* b, const double* c, const double* d) {
  // Floating-point filter (Shewchuk's orient3d bound, doubled): trusted only where every
  // difference of coordinates is zero or between 2^-250 and 2^250, so that no product below
  // overflows or underflows and each operation rounds with a relative error of at most 2^-53.
  double v[9];
  for (int k = 0; k < 3; ++k) {
    v[k] = a[k] - d[k];
    v[3 + k] = b[k] - d[k];
    v[6 + k] = c[k] - d[k];
  }
  bool moderate = true;
  for (double x : v) {
    const double m = std::fabs(x);
    moderate = moderate && (m == 0 || (m > 0x1p-250 && m < 0x1p250));  // false for NaN and infinity
  }
  if (moderate) {
    const double ax = v[0], ay = v[1], az = v[2], bx = v[3], by = v[4], bz = v[5], cx = v[6], cy = v[7], cz = v[8];
    const double bc = by * cz - bz * cy, ca = cy * az - cz * ay, ab = ay * bz - az * by;
    const double det = ax * bc + bx * ca + cx * ab;
    const double permanent = (std::fabs(by * cz) + std::fabs(bz * cy)) * std::fabs(ax) +
                             (std::fabs(cy * az) + std::fabs(cz * ay)) * std::fabs(bx) +
                             (std::fabs(ay * bz) + std::fabs(az * by)) * std::fabs(cx);
    const double bound = 0x1p-49 * permanent;
    if (det > bound) return 1;
    if (-det > bound) return -1;
  }
  return orient3d_exact(a, b, c, d);
}

namespace {

// The coordinates k0 and k1 of p.
struct Projected {
  double p[2];
  Projected(const double* x, int k0, int k1) : p{x[k0], x[k1]} {}
  operator const double*() const { return p; }
};

// Closed triangle a b c and closed segment [p, q] in one plane, projected along an axis where the
// triangle's projection has area: an end inside the triangle, or the segment meeting an edge.
bool coplanar_meet(const double* p, const double* q, const double* a, const double* b, const double* c) {
  static constexpr int kAxes[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  for (const auto& axes : kAxes) {
    const Projected A(a, axes[0], axes[1]), B(b, axes[0], axes[1]), C(c, axes[0], axes[1]);
    const int turn = orient2d(A, B, C);
    if (turn == 0) continue;
    const Projected P(p, axes[0], axes[1]), Q(q, axes[0], axes[1]);
    for (const double* x : {static_cast<const double*>(P), static_cast<const double*>(Q)})
      if (orient2d(A, B, x) * turn >= 0 && orient2d(B, C, x) * turn >= 0 && orient2d(C, A, x) * turn >= 0) return true;
    return segments_cross(P, Q, A, B) || segments_cross(P, Q, B, C) || segments_cross(P, Q, C, A);
  }
  return false;  // a degenerate triangle
}

}  // namespace

bool triangle_degenerate(const double* a, const double* b, const double* c) {
  static constexpr int kAxes[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  for (const auto& axes : kAxes)
    if (orient2d(Projected(a, axes[0], axes[1]), Projected(b, axes[0], axes[1]), Projected(c, axes[0], axes[1])) != 0)
      return false;
  return true;
}

bool segment_meets_triangle(const double* p, const double* q, const double* a, const double* b, const double* c) {
  for (const double* x : {p, q, a, b, c})
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(x[k])) return false;
  // Disjoint bounding boxes: no common point (most bonds end here).
  for (int k = 0; k < 3; ++k)
    if (std::max(p[k], q[k]) < std::min({a[k], b[k], c[k]}) || std::min(p[k], q[k]) > std::max({a[k], b[k], c[k]}))
      return false;
  if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2]) return false;  // a point cuts nothing
  if (triangle_degenerate(a, b, c)) return false;
  const int sp = orient3d(a, b, c, p), sq = orient3d(a, b, c, q);
  if (sp == 0 && sq == 0) return coplanar_meet(p, q, a, b, c);
  if (sp * sq > 0) return false;  // both ends strictly on one side of the triangle's plane
  // The line p q meets the plane in one point; it lies in the closed triangle when the three
  // volumes of p, q and an edge have no two opposite signs.
  const int o[3] = {orient3d(p, q, a, b), orient3d(p, q, b, c), orient3d(p, q, c, a)};
  const bool positive = o[0] > 0 || o[1] > 0 || o[2] > 0, negative = o[0] < 0 || o[1] < 0 || o[2] < 0;
  return !(positive && negative);
}

}  // namespace peri
