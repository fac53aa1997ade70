// Fuzz target: the pre-crack predicate (orient2d, segments_cross; libFuzzer entry point, replay.cpp
// drives it from ctest). The input is a mode byte and up to eight doubles (8 bytes each,
// little-endian; missing bytes are zeros) that make the bond a-b and the crack c-d:
//   mode % 4 == 0: the eight doubles are the coordinates, as they come (NaN, infinities,
//                  subnormals and every magnitude included);
//   mode % 4 == 1: a and b as given; c and d the rounded points of the line a b at parameters
//                  v[4] and v[5], moved by a few units in the last place (v[6], v[7] bits);
//   mode % 4 == 2: a lattice like a sheet's, x = x0 + (i + 1/2) dx and y = y0 + (j + 1/2) dx
//                  with x0 = v[0], y0 = v[1], dx = v[2] and small i, j from the bits of v[3..7];
//   mode % 4 == 3: as 0, then for s = 0, 1, 2 and f = mode's bits 2s+2 and 2s+3: point s copied
//                  onto point (s + f) % 4 where f > 0 (shared end points, zero-length segments).
// Finite input must match the brute-force reference (tests/crossing_reference.hpp) in every order
// of the end points; non-finite input must give orientation 0 and no crossing. Anything else
// aborts: a finding.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "../crossing_reference.hpp"
#include "fuzz_numbers.hpp"
#include "peri/bonds/crossing.hpp"

namespace {

using fuzz_numbers::finite;
using fuzz_numbers::nudge;

[[noreturn]] void finding(const char* what, const double* p) {
  std::fprintf(stderr, "fuzz_crossing finding: %s\n  a (%a, %a) b (%a, %a) c (%a, %a) d (%a, %a)\n", what, p[0],
               p[1], p[2], p[3], p[4], p[5], p[6], p[7]);
  std::abort();
}

void check_orientation(const double* a, const double* b, const double* c, const double* all) {
  const int o = peri::orient2d(a, b, c);
  if (peri::orient2d(b, c, a) != o || peri::orient2d(c, a, b) != o || peri::orient2d(b, a, c) != -o ||
      peri::orient2d(a, c, b) != -o)
    finding("orient2d is not antisymmetric", all);
  const double v[6] = {a[0], a[1], b[0], b[1], c[0], c[1]};
  if (!finite(v, 6)) {
    if (o != 0) finding("orient2d is not 0 for a non-finite point", all);
    return;
  }
  if (o != crossing_reference::orientation(a, b, c)) finding("orient2d differs from the exact reference", all);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::uint8_t mode = data[0];
  double v[8] = {};
  std::memcpy(v, data + 1, std::min<std::size_t>(size - 1, sizeof v));
  double p[8];  // a, b, c, d (x, y each)
  std::memcpy(p, v, sizeof p);
  std::uint64_t bits[8];
  std::memcpy(bits, v, sizeof bits);
  switch (mode % 4) {
    case 1:
      for (int k = 0; k < 2; ++k) {
        const double t = v[4 + k];
        for (int c = 0; c < 2; ++c) {
          const int shift = static_cast<int>((bits[6 + k] >> (8 * c)) & 0xff) % 9 - 4;
          p[4 + 2 * k + c] = nudge(p[c] + t * (p[2 + c] - p[c]), shift);
        }
      }
      break;
    case 2: {
      const double x0 = v[0], y0 = v[1], dx = v[2];
      for (int k = 0; k < 8; ++k) {
        const int i = static_cast<int>((bits[3 + k / 2] >> (16 * (k % 2))) & 0xff) - 128;
        p[k] = (k % 2 ? y0 : x0) + (i + 0.5) * dx;
      }
      break;
    }
    case 3:
      for (int s = 0; s < 3; ++s) {  // field s of mode's bits 2-7: 0 nothing, else point s onto point s + field
        const int field = (mode >> (2 + 2 * s)) & 3;
        if (field == 0) continue;
        const int to = (s + field) % 4;
        p[2 * to] = p[2 * s];
        p[2 * to + 1] = p[2 * s + 1];
      }
      break;
    default:
      break;
  }
  const double* a = p;
  const double* b = p + 2;
  const double* c = p + 4;
  const double* d = p + 6;
  check_orientation(a, b, c, p);
  check_orientation(a, b, d, p);
  check_orientation(c, d, a, p);
  check_orientation(c, d, b, p);
  const bool got = peri::segments_cross(a, b, c, d);
  const double* q[4] = {a, b, c, d};
  for (int order = 1; order < 8; ++order) {
    const double* e = q[(order & 1) ? 1 : 0];
    const double* f = q[(order & 1) ? 0 : 1];
    const double* g = q[(order & 2) ? 3 : 2];
    const double* h = q[(order & 2) ? 2 : 3];
    if (order & 4) {
      std::swap(e, g);
      std::swap(f, h);
    }
    if (peri::segments_cross(e, f, g, h) != got) finding("segments_cross depends on the order of the end points", p);
  }
  if (!finite(p, 8)) {
    if (got) finding("segments_cross is true for a non-finite point", p);
    return 0;
  }
  if (got != crossing_reference::segments_cross(a, b, c, d)) finding("segments_cross differs from the exact reference", p);
  return 0;
}
