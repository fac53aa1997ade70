// Fuzz target: the polygon-crack predicate (orient3d, segment_meets_triangle; libFuzzer entry point,
// replay.cpp drives it from ctest). The input is a mode byte and up to fifteen doubles (8 bytes
// each, little-endian; missing bytes are zeros) that make the bond p-q and the triangle a b c:
//   mode % 4 == 0: the fifteen doubles are the coordinates, as they come (NaN, infinities,
//                  subnormals and every magnitude included);
//   mode % 4 == 1: a, b, c as given (v[6..14]); p and q the rounded points a + s (b - a) +
//                  t (c - a) of the triangle's plane at s, t = v[0], v[1] and v[3], v[4], moved by
//                  a few units in the last place (v[2], v[5] bits): ends on and next to the plane;
//   mode % 4 == 2: a cubic lattice, x = x0 + (i + 1/2) dx with x0, y0, z0, dx = v[0..3] and small
//                  i, j, k from the bits of v[4..14] (bonds in the plane, through corners and edges);
//   mode % 4 == 3: as 0, then for s = 0, 1, 2 and f = mode's bits 2s+2 and 2s+3: point s copied
//                  onto point (s + f) % 5 where f > 0 (zero-length bonds, degenerate triangles).
// Finite input must match the brute-force reference (tests/crossing_reference.hpp) in all 12
// orders (the bond's two directions, the triangle's rotations and mirror); non-finite input must
// give orientation 0 and no meeting. Anything else aborts: a finding.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "../crossing_reference.hpp"
#include "fuzz_numbers.hpp"
#include "peri/bonds/crossing.hpp"

namespace {

using fuzz_numbers::finite;
using fuzz_numbers::nudge;

[[noreturn]] void finding(const char* what, const double* v) {
  std::fprintf(stderr, "fuzz_polygon finding: %s\n", what);
  for (int k = 0; k < 5; ++k) std::fprintf(stderr, "  %c (%a, %a, %a)\n", "pqabc"[k], v[3 * k], v[3 * k + 1], v[3 * k + 2]);
  std::abort();
}

void check_orientation(const double* a, const double* b, const double* c, const double* d, const double* all) {
  const int o = peri::orient3d(a, b, c, d);
  if (peri::orient3d(b, c, a, d) != o || peri::orient3d(b, a, c, d) != -o || peri::orient3d(a, b, d, c) != -o)
    finding("orient3d is not antisymmetric", all);
  const double v[12] = {a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2]};
  if (!finite(v, 12)) {
    if (o != 0) finding("orient3d is not 0 for a non-finite point", all);
    return;
  }
  if (o != crossing_reference::orientation3d(a, b, c, d)) finding("orient3d differs from the exact reference", all);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::uint8_t mode = data[0];
  double v[15] = {};
  std::memcpy(v, data + 1, std::min<std::size_t>(size - 1, sizeof v));
  double p[15];  // p, q, a, b, c (x, y, z each)
  std::memcpy(p, v, sizeof p);
  std::uint64_t bits[15];
  std::memcpy(bits, v, sizeof bits);
  switch (mode % 4) {
    case 1:
      for (int e = 0; e < 2; ++e) {
        const double s = v[3 * e], t = v[3 * e + 1];
        for (int c = 0; c < 3; ++c) {
          const int shift = static_cast<int>((bits[3 * e + 2] >> (8 * c)) & 0xff) % 9 - 4;
          p[3 * e + c] = nudge(p[6 + c] + s * (p[9 + c] - p[6 + c]) + t * (p[12 + c] - p[6 + c]), shift);
        }
      }
      break;
    case 2: {
      const double origin[3] = {v[0], v[1], v[2]}, dx = v[3];
      for (int k = 0; k < 15; ++k) {
        const int i = static_cast<int>((bits[4 + k % 11] >> (8 * (k / 11 + (k % 3)))) & 0x7) - 3;
        p[k] = origin[k % 3] + (i + 0.5) * dx;
      }
      break;
    }
    case 3:
      for (int s = 0; s < 3; ++s) {
        const int field = (mode >> (2 + 2 * s)) & 3;
        if (field == 0) continue;
        const int to = (s + field) % 5;
        for (int c = 0; c < 3; ++c) p[3 * to + c] = p[3 * s + c];
      }
      break;
    default:
      break;
  }
  const double *P = p, *Q = p + 3, *A = p + 6, *B = p + 9, *C = p + 12;
  check_orientation(A, B, C, P, p);
  check_orientation(A, B, C, Q, p);
  check_orientation(P, Q, A, B, p);
  const bool got = peri::segment_meets_triangle(P, Q, A, B, C);
  const double* t[3] = {A, B, C};
  static constexpr int kOrders[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  for (const auto& o : kOrders)
    for (int flip = 0; flip < 2; ++flip)
      if (peri::segment_meets_triangle(flip ? Q : P, flip ? P : Q, t[o[0]], t[o[1]], t[o[2]]) != got)
        finding("segment_meets_triangle depends on the order of the points", p);
  if (!finite(p, 15)) {
    if (got) finding("segment_meets_triangle is true for a non-finite point", p);
    return 0;
  }
  if (got != crossing_reference::segment_meets_triangle(P, Q, A, B, C))
    finding("segment_meets_triangle differs from the exact reference", p);
  return 0;
}
