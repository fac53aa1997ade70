// Brute-force reference for the segment-crossing predicate (test_crossing and fuzz_crossing): every
// coordinate converted exactly to an integer (the doubles of one case share a power-of-two scale),
// then the textbook parametric intersection in exact big-integer arithmetic. Slow and simple; no
// code shared with src/bonds/crossing.cpp.
#pragma once
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <vector>

namespace crossing_reference {

// Signed integer of any size: sign and magnitude (32-bit limbs, least significant first, no
// leading zero limbs; zero has no limbs and sign 0).
struct Int {
  int sign = 0;
  std::vector<std::uint32_t> mag;
};

inline int compare_mag(const std::vector<std::uint32_t>& x, const std::vector<std::uint32_t>& y) {
  if (x.size() != y.size()) return x.size() < y.size() ? -1 : 1;
  for (std::size_t k = x.size(); k-- > 0;)
    if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
  return 0;
}

inline void trim(std::vector<std::uint32_t>& x) {
  while (!x.empty() && x.back() == 0) x.pop_back();
}

inline std::vector<std::uint32_t> add_mag(const std::vector<std::uint32_t>& x, const std::vector<std::uint32_t>& y) {
  std::vector<std::uint32_t> z(std::max(x.size(), y.size()) + 1, 0);
  std::uint64_t carry = 0;
  for (std::size_t k = 0; k < z.size(); ++k) {
    const std::uint64_t s = carry + (k < x.size() ? x[k] : 0) + (k < y.size() ? y[k] : 0);
    z[k] = static_cast<std::uint32_t>(s);
    carry = s >> 32;
  }
  trim(z);
  return z;
}

// x - y for |x| >= |y|.
inline std::vector<std::uint32_t> sub_mag(const std::vector<std::uint32_t>& x, const std::vector<std::uint32_t>& y) {
  std::vector<std::uint32_t> z(x.size(), 0);
  std::int64_t borrow = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    std::int64_t s = static_cast<std::int64_t>(x[k]) - (k < y.size() ? y[k] : 0) - borrow;
    borrow = s < 0;
    if (s < 0) s += std::int64_t{1} << 32;
    z[k] = static_cast<std::uint32_t>(s);
  }
  trim(z);
  return z;
}

inline Int negate(Int x) {
  x.sign = -x.sign;
  return x;
}

inline Int add(const Int& x, const Int& y) {
  if (x.sign == 0) return y;
  if (y.sign == 0) return x;
  if (x.sign == y.sign) return {x.sign, add_mag(x.mag, y.mag)};
  const int c = compare_mag(x.mag, y.mag);
  if (c == 0) return {};
  return c > 0 ? Int{x.sign, sub_mag(x.mag, y.mag)} : Int{y.sign, sub_mag(y.mag, x.mag)};
}

inline Int sub(const Int& x, const Int& y) { return add(x, negate(y)); }

inline Int mul(const Int& x, const Int& y) {
  if (x.sign == 0 || y.sign == 0) return {};
  std::vector<std::uint32_t> z(x.mag.size() + y.mag.size(), 0);
  for (std::size_t i = 0; i < x.mag.size(); ++i) {
    std::uint64_t carry = 0;
    for (std::size_t j = 0; j < y.mag.size(); ++j) {
      const std::uint64_t t = static_cast<std::uint64_t>(x.mag[i]) * y.mag[j] + z[i + j] + carry;
      z[i + j] = static_cast<std::uint32_t>(t);
      carry = t >> 32;
    }
    for (std::size_t k = i + y.mag.size(); carry; ++k) {
      const std::uint64_t t = static_cast<std::uint64_t>(z[k]) + carry;
      z[k] = static_cast<std::uint32_t>(t);
      carry = t >> 32;
    }
  }
  trim(z);
  return {x.sign * y.sign, z};
}

inline int compare(const Int& x, const Int& y) {
  const Int d = sub(x, y);
  return d.sign;
}

// Finite double x = sign * m * 2^e with m < 2^53 and e >= -1074.
inline void decompose(double x, std::uint64_t& m, int& e, int& sign) {
  const auto bits = std::bit_cast<std::uint64_t>(x);
  const int field = static_cast<int>((bits >> 52) & 0x7ff);
  m = bits & ((std::uint64_t{1} << 52) - 1);
  e = field == 0 ? -1074 : field - 1075;
  if (field != 0) m |= std::uint64_t{1} << 52;
  sign = m == 0 ? 0 : ((bits >> 63) ? -1 : 1);
}

// x / 2^scale as an integer (exact: scale is at most the exponent of every input of the case).
inline Int to_int(double x, int scale) {
  std::uint64_t m;
  int e, sign;
  decompose(x, m, e, sign);
  if (sign == 0) return {};
  const int shift = e - scale;  // >= 0
  std::vector<std::uint32_t> mag(static_cast<std::size_t>(shift / 32) + 3, 0);
  const int q = shift / 32, r = shift % 32;
  const unsigned __int128 v = static_cast<unsigned __int128>(m) << r;  // < 2^85
  for (int k = 0; k < 3; ++k) mag[q + k] = static_cast<std::uint32_t>(v >> (32 * k));
  trim(mag);
  return {sign, mag};
}

// Least exponent of the non-zero values among n finite doubles (0 when all are zero).
inline int common_scale(const double* v, int n) {
  int scale = 1 << 20;
  for (int k = 0; k < n; ++k) {
    std::uint64_t m;
    int e, sign;
    decompose(v[k], m, e, sign);
    if (sign != 0) scale = std::min(scale, e);
  }
  return scale == (1 << 20) ? 0 : scale;
}

struct Point {
  Int x, y;
};

inline Int cross(const Point& p, const Point& q) { return sub(mul(p.x, q.y), mul(p.y, q.x)); }
inline Int dot(const Point& p, const Point& q) { return add(mul(p.x, q.x), mul(p.y, q.y)); }
inline Point minus(const Point& p, const Point& q) { return {sub(p.x, q.x), sub(p.y, q.y)}; }

/// Exact sign of (b - a) x (c - a) (finite xy coordinates).
inline int orientation(const double* a, const double* b, const double* c) {
  const double v[6] = {a[0], a[1], b[0], b[1], c[0], c[1]};
  const int s = common_scale(v, 6);
  const Point pa{to_int(a[0], s), to_int(a[1], s)}, pb{to_int(b[0], s), to_int(b[1], s)},
      pc{to_int(c[0], s), to_int(c[1], s)};
  return cross(minus(pb, pa), minus(pc, pa)).sign;
}

/// Whether the closed segments [a, b] and [c, d] share a point, by solving a + t (b - a) =
/// c + u (d - c) for t, u in [0, 1] exactly (parallel: on one line and overlapping parameter
/// intervals); zero-length segments cross nothing (the documented rule). Finite coordinates.
inline bool segments_cross(const double* a, const double* b, const double* c, const double* d) {
  const double v[8] = {a[0], a[1], b[0], b[1], c[0], c[1], d[0], d[1]};
  const int s = common_scale(v, 8);
  const Point pa{to_int(a[0], s), to_int(a[1], s)}, pb{to_int(b[0], s), to_int(b[1], s)},
      pc{to_int(c[0], s), to_int(c[1], s)}, pd{to_int(d[0], s), to_int(d[1], s)};
  const Point r = minus(pb, pa), q = minus(pc, pa), w = minus(pd, pc);
  if ((r.x.sign == 0 && r.y.sign == 0) || (w.x.sign == 0 && w.y.sign == 0)) return false;
  Int den = cross(r, w), t = cross(q, w), u = cross(q, r);
  if (den.sign != 0) {
    if (den.sign < 0) {
      den = negate(den);
      t = negate(t);
      u = negate(u);
    }
    return t.sign >= 0 && compare(t, den) <= 0 && u.sign >= 0 && compare(u, den) <= 0;
  }
  if (u.sign != 0) return false;  // parallel, on different lines
  // One line: c and d at parameters t0, t1 of a + t (b - a), scaled by |b - a|^2.
  const Int t0 = dot(q, r), t1 = dot(minus(pd, pa), r), len2 = dot(r, r);
  const Int& lo = compare(t0, t1) <= 0 ? t0 : t1;
  const Int& hi = compare(t0, t1) <= 0 ? t1 : t0;
  const Int zero{};
  const Int& from = compare(lo, zero) >= 0 ? lo : zero;
  const Int& to = compare(hi, len2) <= 0 ? hi : len2;
  return compare(from, to) <= 0;
}

struct Point3 {
  Int x, y, z;
};

inline Point3 minus3(const Point3& p, const Point3& q) { return {sub(p.x, q.x), sub(p.y, q.y), sub(p.z, q.z)}; }

// det [u; v; w] by the rule of Sarrus.
inline Int det3(const Point3& u, const Point3& v, const Point3& w) {
  Int d = mul(u.x, sub(mul(v.y, w.z), mul(v.z, w.y)));
  d = sub(d, mul(u.y, sub(mul(v.x, w.z), mul(v.z, w.x))));
  return add(d, mul(u.z, sub(mul(v.x, w.y), mul(v.y, w.x))));
}

// The points as integers at their common scale.
inline std::vector<Point3> to_points(std::initializer_list<const double*> pts) {
  std::vector<double> v;
  for (const double* p : pts) v.insert(v.end(), p, p + 3);
  const int s = common_scale(v.data(), static_cast<int>(v.size()));
  std::vector<Point3> out;
  for (const double* p : pts) out.push_back({to_int(p[0], s), to_int(p[1], s), to_int(p[2], s)});
  return out;
}

/// Exact sign of det [a - d; b - d; c - d] (finite 3-vectors).
inline int orientation3d(const double* a, const double* b, const double* c, const double* d) {
  const std::vector<Point3> p = to_points({a, b, c, d});
  return det3(minus3(p[0], p[3]), minus3(p[1], p[3]), minus3(p[2], p[3])).sign;
}

/// Whether the closed segment [p, q] and the closed triangle a b c share a point: p + t (q - p) =
/// a + u (b - a) + v (c - a) solved by Cramer's rule in exact integers (t in [0, 1], u, v >= 0,
/// u + v <= 1); a segment parallel to the plane meets the triangle only in that plane, where the
/// test is 2D (an end inside, or an edge crossed). Zero-length segments and degenerate triangles
/// meet nothing. Finite coordinates.
inline bool segment_meets_triangle(const double* p, const double* q, const double* a, const double* b,
                                   const double* c) {
  const std::vector<Point3> P = to_points({p, q, a, b, c});
  const Point3 dir = minus3(P[1], P[0]), ab = minus3(P[2], P[3]), ac = minus3(P[2], P[4]), r = minus3(P[2], P[0]);
  if (dir.x.sign == 0 && dir.y.sign == 0 && dir.z.sign == 0) return false;
  const Point3 e1 = minus3(P[3], P[2]), e2 = minus3(P[4], P[2]);
  const Point3 normal{sub(mul(e1.y, e2.z), mul(e1.z, e2.y)), sub(mul(e1.z, e2.x), mul(e1.x, e2.z)),
                      sub(mul(e1.x, e2.y), mul(e1.y, e2.x))};
  if (normal.x.sign == 0 && normal.y.sign == 0 && normal.z.sign == 0) return false;  // degenerate triangle
  Int D = det3(dir, ab, ac);
  if (D.sign != 0) {
    Int t = det3(r, ab, ac), u = det3(dir, r, ac), v = det3(dir, ab, r);
    if (D.sign < 0) D = negate(D), t = negate(t), u = negate(u), v = negate(v);
    return t.sign >= 0 && compare(t, D) <= 0 && u.sign >= 0 && v.sign >= 0 && compare(add(u, v), D) <= 0;
  }
  if (det3(e1, e2, minus3(P[0], P[2])).sign != 0) return false;  // parallel, off the plane
  // In the plane: drop an axis along which the normal has a component.
  const int drop = normal.z.sign != 0 ? 2 : (normal.x.sign != 0 ? 0 : 1);
  auto flat = [&](const double* x, double* out) {
    int n = 0;
    for (int k = 0; k < 3; ++k)
      if (k != drop) out[n++] = x[k];
  };
  double fp[2], fq[2], fa[2], fb[2], fc[2];
  flat(p, fp), flat(q, fq), flat(a, fa), flat(b, fb), flat(c, fc);
  const int turn = orientation(fa, fb, fc);
  for (const double* x : {fp, fq})
    if (orientation(fa, fb, x) * turn >= 0 && orientation(fb, fc, x) * turn >= 0 && orientation(fc, fa, x) * turn >= 0)
      return true;
  return segments_cross(fp, fq, fa, fb) || segments_cross(fp, fq, fb, fc) || segments_cross(fp, fq, fc, fa);
}

}  // namespace crossing_reference
