// The pre-crack predicate: orient2d and segments_cross (and crosses, which the domain, the release
// stage and the fracture-energy count call) against a brute-force exact reference
// (crossing_reference.hpp) on random, near-collinear, lattice and extreme inputs; the degenerate
// cases of the documented rule one by one; and whole sheets, where the broken bonds of a domain
// must be exactly those whose segment meets the crack.
#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "crossing_reference.hpp"
#include "peri/bonds/bonds.hpp"
#include "peri/bonds/crossing.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"

using namespace peri;
namespace ref = crossing_reference;

namespace {

struct Segments {
  double a[2], b[2], c[2], d[2];
};

peri::Crack crack_of(const double* c, const double* d) {
  peri::Crack k;
  k.from = {c[0], c[1], 0.0};
  k.to = {d[0], d[1], 0.0};
  return k;
}

// crosses() as the domain calls it (3-vectors, z ignored).
bool crosses_3d(const double* a, const double* b, const double* c, const double* d) {
  const double a3[3] = {a[0], a[1], 0.25}, b3[3] = {b[0], b[1], -3.0};
  return crosses(a3, b3, crack_of(c, d));
}

// Checks one case against the reference, in all eight orders of the end points (a <-> b, c <-> d,
// bond <-> crack); counts disagreements. `crossed` gets the reference answer.
int check_case(const Segments& s, bool* crossed = nullptr) {
  const bool want = ref::segments_cross(s.a, s.b, s.c, s.d);
  if (crossed) *crossed = want;
  int bad = 0;
  const double* p[4] = {s.a, s.b, s.c, s.d};
  for (int order = 0; order < 8; ++order) {
    const double* a = p[(order & 1) ? 1 : 0];
    const double* b = p[(order & 1) ? 0 : 1];
    const double* c = p[(order & 2) ? 3 : 2];
    const double* d = p[(order & 2) ? 2 : 3];
    if (order & 4) {
      std::swap(a, c);
      std::swap(b, d);
    }
    if (segments_cross(a, b, c, d) != want || crosses_3d(a, b, c, d) != want) ++bad;
  }
  if (bad)
    std::printf("disagreement: a (%a, %a) b (%a, %a) c (%a, %a) d (%a, %a): reference %d\n", s.a[0], s.a[1], s.b[0],
                s.b[1], s.c[0], s.c[1], s.d[0], s.d[1], int(want));
  return bad;
}

// Checks orient2d against the reference and its antisymmetry (cyclic shifts keep, swaps flip).
int check_orientation(const double* a, const double* b, const double* c) {
  const int want = ref::orientation(a, b, c);
  const int got[6] = {orient2d(a, b, c), orient2d(b, c, a), orient2d(c, a, b),
                      -orient2d(b, a, c), -orient2d(a, c, b), -orient2d(c, b, a)};
  int bad = 0;
  for (int g : got) bad += g != want;
  if (bad)
    std::printf("orientation disagreement: (%a, %a) (%a, %a) (%a, %a): reference %d, orient2d %d\n", a[0], a[1],
                b[0], b[1], c[0], c[1], want, got[0]);
  return bad;
}

// A random finite double of any magnitude (random bit pattern; NaN and infinity redrawn).
double any_finite(std::mt19937_64& rng) {
  for (;;) {
    const double x = std::bit_cast<double>(rng());
    if (std::isfinite(x)) return x;
  }
}

// x moved by k units in the last place.
double ulps(double x, int k) {
  for (; k > 0; --k) x = std::nextafter(x, std::numeric_limits<double>::infinity());
  for (; k < 0; ++k) x = std::nextafter(x, -std::numeric_limits<double>::infinity());
  return x;
}

}  // namespace

TEST(Orientation, MatchesExactReference) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::uniform_int_distribution<int> small(-3, 3), ulp(-4, 4);
  int bad = 0, zero = 0;
  for (int n = 0; n < 40000; ++n) {
    double p[3][2];
    switch (n % 5) {
      case 0:  // uniform
        for (auto& q : p) q[0] = U(rng), q[1] = U(rng);
        break;
      case 1:  // small integers scaled by an inexact spacing: many exactly collinear triples
        for (auto& q : p) q[0] = small(rng) * 1.0e-3, q[1] = small(rng) * 1.0e-3;
        break;
      case 2: {  // c on the line a b, rounded, then moved by a few ulps
        for (int k = 0; k < 2; ++k) p[k][0] = U(rng), p[k][1] = U(rng);
        const double t = 4.0 * U(rng);
        p[2][0] = ulps(p[0][0] + t * (p[1][0] - p[0][0]), ulp(rng));
        p[2][1] = ulps(p[0][1] + t * (p[1][1] - p[0][1]), ulp(rng));
        break;
      }
      case 3:  // every magnitude, subnormals included
        for (auto& q : p) q[0] = any_finite(rng), q[1] = any_finite(rng);
        break;
      default: {  // large offsets, tiny differences: the cancellation the filter must catch
        const double base = std::ldexp(1.0, std::uniform_int_distribution<int>(-1000, 1000)(rng));
        for (auto& q : p) q[0] = ulps(base, small(rng)), q[1] = ulps(-base, small(rng));
      }
    }
    bad += check_orientation(p[0], p[1], p[2]);
    zero += ref::orientation(p[0], p[1], p[2]) == 0;
  }
  EXPECT_EQ(bad, 0);
  EXPECT_GT(zero, 1000) << "too few exactly collinear triples to test the degenerate answers";
}

// Kettner, Mehlhorn, Pion, Schirra, Yap, "Classroom examples of robustness problems in geometric
// computations" (2008): p = (0.5 + x u, 0.5 + y u), u = 2^-53, against q = r/2 = (12, 12). The
// naive determinant gets many of these signs wrong.
TEST(Orientation, ClassroomCounterexamples) {
  const double q[2] = {12, 12}, r[2] = {24, 24};
  int bad = 0, naive_wrong = 0, zero = 0;
  for (int x = 0; x < 256; ++x)
    for (int y = 0; y < 256; ++y) {
      const double p[2] = {0.5 + x * 0x1p-53, 0.5 + y * 0x1p-53};
      bad += check_orientation(p, q, r);
      const int want = ref::orientation(p, q, r);
      const double naive = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
      naive_wrong += (naive > 0) - (naive < 0) != want;
      zero += want == 0;
    }
  std::printf("classroom grid: %d of 65536 naive signs wrong, %d exactly collinear\n", naive_wrong, zero);
  EXPECT_EQ(bad, 0);
  EXPECT_GT(naive_wrong, 1000) << "the grid should defeat a naive determinant";
}

TEST(Orientation, NonFiniteIsZero) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  const double a[2] = {0, 0}, b[2] = {1, 0};
  for (double bad : {nan, inf, -inf}) {
    const double c[2] = {bad, 1}, e[2] = {0.5, bad};
    EXPECT_EQ(orient2d(a, b, c), 0);
    EXPECT_EQ(orient2d(a, b, e), 0);
    EXPECT_EQ(orient2d(c, a, b), 0);
  }
  const double huge[2] = {1e308, -1e308}, far[2] = {-1e308, 1e308};  // differences overflow
  EXPECT_EQ(orient2d(huge, far, a), 0);  // a = (0, 0) lies on that line
  const double off[2] = {0x1p-1074, 0};
  EXPECT_EQ(orient2d(huge, far, off), ref::orientation(huge, far, off));
  EXPECT_EQ(orient2d(huge, far, off), -1);  // right of the direction (-1, 1), by 2^-1074
}

// The rule, case by case (the degenerate cases of docs/user/precracks.md).
TEST(Crossing, DegenerateCasesFollowTheRule) {
  struct Named {
    const char* what;
    Segments s;
    bool crosses;
  };
  const double h = 1.0 / 3.0;  // inexact, so that collinearity rests on exact arithmetic
  const Named cases[] = {
      {"proper crossing", {{0, -1}, {0, 1}, {-1, 0}, {1, 0}}, true},
      {"parallel, apart", {{0, 1}, {1, 1}, {0, 0}, {1, 0}}, false},
      {"bond end on the crack's interior", {{h, 0}, {h, 1}, {0, 0}, {1, 0}}, true},
      {"bond end just off the crack", {{h, 0x1p-60}, {h, 1}, {0, 0}, {1, 0}}, false},
      {"crack end on the bond's interior", {{0, -1}, {0, 1}, {0, h}, {1, h}}, true},
      {"crack end just short of the bond", {{0, -1}, {0, 1}, {0x1p-1074, h}, {1, h}}, false},
      {"end points coincide, not collinear", {{0, 0}, {h, 1}, {0, 0}, {1, 0}}, true},
      {"collinear, overlapping", {{h, h}, {3 * h, 3 * h}, {2 * h, 2 * h}, {5, 5}}, true},
      {"collinear, one inside the other", {{-1, -1}, {1, 1}, {-h, -h}, {h, h}}, true},
      {"collinear, touching end to end", {{0, 0}, {h, h}, {h, h}, {1, 1}}, true},
      {"collinear, disjoint", {{0.0095, 0.0095}, {0.00975, 0.00975}, {1, 1}, {2, 2}}, false},
      {"collinear, disjoint by one ulp", {{0, 0}, {h, 2 * h}, {ulps(h, 1), ulps(2 * h, 1)}, {1, 2}}, false},
      {"collinear vertical, overlapping", {{h, 0}, {h, 2}, {h, 1}, {h, 3}}, true},
      {"collinear vertical, disjoint", {{h, 0}, {h, 1}, {h, 1.5}, {h, 3}}, false},
      {"zero-length bond on the crack", {{h, 0}, {h, 0}, {0, 0}, {1, 0}}, false},
      {"zero-length crack on the bond", {{0, 0}, {1, 1}, {0.5, 0.5}, {0.5, 0.5}}, false},
  };
  for (const Named& n : cases) {
    bool want = false;
    EXPECT_EQ(check_case(n.s, &want), 0) << n.what;
    EXPECT_EQ(want, n.crosses) << n.what << ": the reference disagrees with the documented rule";
    EXPECT_EQ(segments_cross(n.s.a, n.s.b, n.s.c, n.s.d), n.crosses) << n.what;
  }
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  const double a[2] = {0, -1}, b[2] = {0, 1}, c[2] = {-1, 0}, d[2] = {1, 0};
  for (double bad : {nan, inf, -inf}) {
    const double e[2] = {bad, 0}, f[2] = {0, bad};
    EXPECT_FALSE(segments_cross(a, b, e, d));
    EXPECT_FALSE(segments_cross(a, f, c, d));
    EXPECT_FALSE(segments_cross(e, f, c, d));
  }
}

TEST(Crossing, MatchesExactReferenceOnRandomAndAdversarialSegments) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::uniform_int_distribution<int> grid(0, 3), ulp(-2, 2), pick(0, 3);
  int bad = 0, crossed = 0, collinear_touching = 0, collinear_apart = 0, end_on_other = 0;
  for (int n = 0; n < 60000; ++n) {
    Segments s;
    double* p[4] = {s.a, s.b, s.c, s.d};
    switch (n % 6) {
      case 0:  // uniform
        for (double* q : p) q[0] = U(rng), q[1] = U(rng);
        break;
      case 1:
        if (n % 4 == 1) {  // a 4 x 4 lattice with an inexact spacing: collinear, touching, zero-length
          for (double* q : p) q[0] = 0.1 * grid(rng), q[1] = 0.1 * grid(rng);
        } else {  // on one line, any doubles: y = x, y = -x, y = 2x, horizontal or vertical
          const int line = pick(rng);
          const double k = U(rng);
          for (double* q : p) {
            const double t = n % 8 == 3 ? 0.25 * grid(rng) : U(rng);
            q[0] = line == 3 ? k : t;
            q[1] = line == 0 ? t : line == 1 ? -t : line == 2 ? 2 * t : k;
          }
        }
        break;
      case 2: {  // the crack on the bond's line (rounded, nudged by an ulp or two)
        for (int k = 0; k < 2; ++k) p[k][0] = U(rng), p[k][1] = U(rng);
        for (int k = 2; k < 4; ++k) {
          const double t = 3.0 * U(rng);
          p[k][0] = ulps(s.a[0] + t * (s.b[0] - s.a[0]), ulp(rng));
          p[k][1] = ulps(s.a[1] + t * (s.b[1] - s.a[1]), ulp(rng));
        }
        break;
      }
      case 3: {  // an end point of one on the other segment (rounded) or on an end point
        for (double* q : p) q[0] = U(rng), q[1] = U(rng);
        const double t = 0.5 + 0.5 * U(rng);
        double* moved = p[pick(rng)];
        const double* from = moved == s.a || moved == s.b ? s.c : s.a;
        const double* to = moved == s.a || moved == s.b ? s.d : s.b;
        if (n % 4 == 3) {
          moved[0] = from[0], moved[1] = from[1];
        } else {
          moved[0] = ulps(from[0] + t * (to[0] - from[0]), ulp(rng));
          moved[1] = ulps(from[1] + t * (to[1] - from[1]), ulp(rng));
        }
        break;
      }
      case 4: {  // bonds of a sheet's lattice and a crack on a lattice line (the 45-degree slit)
        const double dx = 0.00015625 * (1.0 + 0.25 * U(rng)), o = 0.01 * U(rng);
        auto node = [&](int i, int j, double* q) { q[0] = o + (i + 0.5) * dx, q[1] = o + (j + 0.5) * dx; };
        const int i = grid(rng) * 3, j = grid(rng) * 3;
        node(i, j, s.a);
        node(i + grid(rng) - 1, j + grid(rng) - 1, s.b);
        const double t0 = 12.0 * U(rng), t1 = 12.0 * U(rng);
        node(0, 0, s.c);
        s.d[0] = s.c[0], s.d[1] = s.c[1];
        s.c[0] += t0 * dx, s.c[1] += t0 * dx, s.d[0] += t1 * dx, s.d[1] += t1 * dx;
        break;
      }
      default:  // every magnitude
        for (double* q : p) q[0] = any_finite(rng), q[1] = any_finite(rng);
    }
    bool want = false;
    bad += check_case(s, &want);
    crossed += want;
    const int o1 = ref::orientation(s.a, s.b, s.c), o2 = ref::orientation(s.a, s.b, s.d);
    const bool proper_lengths = (s.a[0] != s.b[0] || s.a[1] != s.b[1]) && (s.c[0] != s.d[0] || s.c[1] != s.d[1]);
    if (proper_lengths && o1 == 0 && o2 == 0) (want ? collinear_touching : collinear_apart) += 1;
    if (proper_lengths && want && (o1 == 0) != (o2 == 0)) ++end_on_other;
  }
  std::printf("%d of 60000 cross; collinear: %d meeting, %d apart; %d with an end point on the other\n", crossed,
              collinear_touching, collinear_apart, end_on_other);
  EXPECT_EQ(bad, 0);
  // Every degenerate class is well represented.
  EXPECT_GT(collinear_touching, 500);
  EXPECT_GT(collinear_apart, 500);
  EXPECT_GT(end_on_other, 500);
}

namespace {

// Whether the reference says the bond x y meets one of the cracks: a slit in xy, a polygon as its
// fan of triangles in space.
bool reference_meets(const std::vector<Crack>& cracks, const double* x, const double* y) {
  for (const Crack& c : cracks) {
    if (!c.is_polygon()) {
      if (ref::segments_cross(x, y, c.from.data(), c.to.data())) return true;
      continue;
    }
    for (std::size_t k = 1; k + 1 < c.polygon.size(); ++k)
      if (ref::segment_meets_triangle(x, y, c.polygon[0].data(), c.polygon[k].data(), c.polygon[k + 1].data()))
        return true;
  }
  return false;
}

// One sheet (or block) discretized once; each crack set builds a one-rank domain over it.
struct Sheet {
  Scene scene;
  Nodes nodes;
  explicit Sheet(const char* text) : scene(parse_scene(text, "crossing-test")), nodes(discretize(scene)) {}

  // Ordered bonds (natural ids i < j) that the domain breaks and that the reference says meet a
  // crack; each bond checked at both of its ends.
  void compare(const std::vector<Crack>& cracks, std::int64_t& broken, std::int64_t& expected,
               std::int64_t& wrong, std::int64_t& asymmetric) const {
    Scene s = scene;
    s.cracks = cracks;
    const CellList cells(nodes, reach(nodes.bodies[0]));
    const Partition part = partition_from_parts(nodes, std::vector<int>(nodes.size(), 0), 1);
    const Domain d = build_domain(s, nodes, cells, part, 0);
    std::set<std::pair<std::int64_t, std::int64_t>> flagged, seen;
    broken = expected = wrong = asymmetric = 0;
    for (std::int32_t r = 0; r < d.owned; ++r)
      for (std::int64_t b = d.bonds.offsets[r]; b < d.bonds.offsets[r + 1]; ++b) {
        const std::int64_t i = d.natural[r], j = d.natural[d.bonds.neighbor[b]];
        const auto key = std::minmax(i, j);
        if (d.bonds.broken[b]) flagged.insert(key);
        if (!seen.insert(key).second) continue;
        expected += reference_meets(cracks, &nodes.X[3 * i], &nodes.X[3 * j]);
      }
    for (std::int32_t r = 0; r < d.owned; ++r)
      for (std::int64_t b = d.bonds.offsets[r]; b < d.bonds.offsets[r + 1]; ++b) {
        const std::int64_t i = d.natural[r], j = d.natural[d.bonds.neighbor[b]];
        const bool meets = reference_meets(cracks, &nodes.X[3 * i], &nodes.X[3 * j]);
        wrong += (d.bonds.broken[b] != 0) != meets;
        asymmetric += (d.bonds.broken[b] != 0) != (flagged.count(std::minmax(i, j)) != 0);
      }
    broken = static_cast<std::int64_t>(flagged.size());
    EXPECT_EQ(2 * broken, d.initially_broken);
  }
};

Crack crack(double x0, double y0, double x1, double y1) {
  Crack c;
  c.from = {x0, y0, 0.0};
  c.to = {x1, y1, 0.0};
  return c;
}

// A 1 cm sheet at the origin (nodes at (i + 1/2) dx, so its diagonal nodes lie exactly on y = x).
const char* kSheet =
    "name: s\nmaterials:\n  m: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2.0}\n"
    "bodies:\n  sheet: {kind: membrane, material: m, origin: [0, 0, 0], size: [0.01, 0.01], thickness: 0.0005,\n"
    "          spacing: 0.0005, quadrature: partial_area}\nstages:\n  - {name: r, steps: 1}\n";

}  // namespace

TEST(Crossing, CrackFarOutsideTheSheetBreaksNothing) {
  const Sheet sheet(kSheet);
  std::int64_t broken, expected, wrong, asymmetric;
  // On the sheet's diagonal line, beyond its corner (either way), and shifted off that line.
  for (const Crack& c : {crack(1, 1, 2, 2), crack(2, 2, 1, 1), crack(-2, -2, -1, -1), crack(1.0001, 1, 2, 2),
                         crack(0.0101, 0.0101, 0.05, 0.05), crack(-0.005, -0.005, -0.0001, -0.0001)}) {
    sheet.compare({c}, broken, expected, wrong, asymmetric);
    EXPECT_EQ(broken, 0) << "crack (" << c.from[0] << ", " << c.from[1] << ") - (" << c.to[0] << ", " << c.to[1] << ")";
    EXPECT_EQ(expected, 0);
    EXPECT_EQ(wrong, 0);
  }
}

TEST(Crossing, SlitsBreakExactlyTheBondsTheyMeet) {
  const Sheet sheet(kSheet);
  const double dx = 0.0005;
  const double* X = sheet.nodes.X.data();
  const auto node = [&](int i, int j) { return 3 * static_cast<std::size_t>(j * 20 + i); };
  const std::size_t n37 = node(3, 7), n12_7 = node(12, 7), n5_2 = node(5, 2), n5_9 = node(5, 9);
  struct Case {
    const char* what;
    std::vector<Crack> cracks;
  };
  const std::vector<Case> cases = {
      // 45 degrees along the nodes' diagonal, ends between nodes: the bonds on the diagonal
      // beyond either end stay intact.
      {"45-degree slit on the diagonal", {crack(0.0025, 0.0025, 0.006, 0.006)}},
      {"45-degree slit off the nodes", {crack(0.0021, 0.0033, 0.0063, 0.0075)}},
      // Along a row of nodes (collinear bonds overlapping it are broken), ends between nodes.
      {"slit along a row", {crack(X[n37] - 0.3 * dx, X[n37 + 1], X[n12_7] + 0.3 * dx, X[n12_7 + 1])}},
      // Ends exactly on nodes: every bond of those nodes meets the slit.
      {"slit from node to node", {crack(X[n5_2], X[n5_2 + 1], X[n5_9], X[n5_9 + 1])}},
      // Tip midway between nodes, so that bonds with odd offsets pass through it.
      {"slit tip between nodes", {crack(0.001, 0.005, 0.005, 0.005)}},
      {"two crossing slits", {crack(0.001, 0.009, 0.009, 0.001), crack(0.0025, 0.0025, 0.006, 0.006)}},
  };
  for (const Case& c : cases) {
    std::int64_t broken, expected, wrong, asymmetric;
    sheet.compare(c.cracks, broken, expected, wrong, asymmetric);
    std::printf("%-32s %4lld bonds broken, %4lld meet the slit\n", c.what, static_cast<long long>(broken),
                static_cast<long long>(expected));
    EXPECT_GT(expected, 10) << c.what;
    EXPECT_EQ(broken, expected) << c.what;
    EXPECT_EQ(wrong, 0) << c.what << ": bonds broken that do not meet the slit, or the reverse";
    EXPECT_EQ(asymmetric, 0) << c.what << ": the two ends of a bond disagree";
  }
  // Random slits across the sheet (any angle, ends anywhere).
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> U(-0.002, 0.012);
  std::int64_t total = 0;
  for (int n = 0; n < 20; ++n) {
    std::int64_t broken, expected, wrong, asymmetric;
    sheet.compare({crack(U(rng), U(rng), U(rng), U(rng))}, broken, expected, wrong, asymmetric);
    EXPECT_EQ(wrong, 0);
    EXPECT_EQ(asymmetric, 0);
    total += broken;
  }
  EXPECT_GT(total, 500);
}

namespace {

// Checks orient3d against the reference and its symmetries (even permutations keep the sign, odd
// ones flip it).
int check_orientation3d(const double* a, const double* b, const double* c, const double* d) {
  const int want = ref::orientation3d(a, b, c, d);
  const int got[6] = {orient3d(a, b, c, d),  orient3d(b, c, a, d),  orient3d(c, a, b, d),
                      -orient3d(b, a, c, d), -orient3d(a, b, d, c), orient3d(a, d, b, c)};
  int bad = 0;
  for (int g : got) bad += g != want;
  if (bad)
    std::printf("orient3d disagreement: (%a %a %a) (%a %a %a) (%a %a %a) (%a %a %a): reference %d, orient3d %d\n",
                a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2], want, got[0]);
  return bad;
}

}  // namespace

TEST(Orientation3d, MatchesExactReference) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::uniform_int_distribution<int> small(-2, 2), ulp(-3, 3);
  int bad = 0, zero = 0;
  for (int n = 0; n < 12000; ++n) {
    double p[4][3];
    switch (n % 6) {
      case 0:  // uniform
        for (auto& q : p)
          for (double& x : q) x = U(rng);
        break;
      case 1:  // small integers scaled by an inexact spacing: many exactly coplanar quadruples
        for (auto& q : p)
          for (double& x : q) x = small(rng) * 1.0e-3;
        break;
      case 2: {  // d in the plane a b c, rounded, then moved by a few ulps
        for (int k = 0; k < 3; ++k)
          for (double& x : p[k]) x = U(rng);
        const double s = 2 * U(rng), t = 2 * U(rng);
        for (int c = 0; c < 3; ++c) p[3][c] = ulps(p[0][c] + s * (p[1][c] - p[0][c]) + t * (p[2][c] - p[0][c]), ulp(rng));
        break;
      }
      case 3:  // every magnitude, subnormals included (fewer: the reference is slow there)
        if (n % 30 != 3) continue;
        for (auto& q : p)
          for (double& x : q) x = any_finite(rng);
        break;
      case 4: {  // large offsets, tiny differences
        const double base = std::ldexp(1.0, std::uniform_int_distribution<int>(-300, 300)(rng));
        for (auto& q : p)
          for (int c = 0; c < 3; ++c) q[c] = ulps(c == 1 ? -base : base, small(rng));
        break;
      }
      default: {  // a lattice plane x = 0.0045 of a 1 mm grid and points on, next to and off it
        for (auto& q : p) {
          q[0] = small(rng) == 0 ? 0.0045 : (small(rng) + 0.5) * 1.0e-3;
          q[1] = (small(rng) + 0.5) * 1.0e-3;
          q[2] = (small(rng) + 0.5) * 1.0e-3;
        }
      }
    }
    bad += check_orientation3d(p[0], p[1], p[2], p[3]);
    zero += ref::orientation3d(p[0], p[1], p[2], p[3]) == 0;
  }
  EXPECT_EQ(bad, 0);
  EXPECT_GT(zero, 400) << "too few exactly coplanar quadruples to test the degenerate answers";
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double o[3] = {0, 0, 0}, x[3] = {1, 0, 0}, y[3] = {0, 1, 0}, z[3] = {0, 0, 1}, bad_z[3] = {0, 0, nan};
  EXPECT_EQ(orient3d(x, y, z, o), -orient3d(y, x, z, o));
  EXPECT_NE(orient3d(x, y, z, o), 0);
  EXPECT_EQ(orient3d(x, y, bad_z, o), 0);
}

TEST(PolygonCrack, SegmentTriangleMatchesReference) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::uniform_int_distribution<int> small(-2, 2), ulp(-2, 2);
  int bad = 0, meets = 0, coplanar_meets = 0, touching = 0;
  for (int n = 0; n < 30000; ++n) {
    double p[5][3];  // p, q, a, b, c
    switch (n % 4) {
      case 0:
        for (auto& v : p)
          for (double& x : v) x = U(rng);
        break;
      case 3:  // all five in the plane z = 2 mm: the test in the plane
        for (auto& v : p) v[0] = small(rng) * 1.0e-3, v[1] = small(rng) * 1.0e-3, v[2] = 2.0e-3;
        break;
      case 1:  // small integers: segments through corners and edges, in the plane, degenerate triangles
        for (auto& v : p)
          for (double& x : v) x = small(rng) * 1.0e-3;
        break;
      default: {  // the segment's ends near the triangle's plane (rounded, moved by ulps)
        for (int k = 2; k < 5; ++k)
          for (double& x : p[k]) x = U(rng);
        for (int k = 0; k < 2; ++k) {
          const double s = U(rng), t = U(rng);
          for (int c = 0; c < 3; ++c) p[k][c] = ulps(p[2][c] + s * (p[3][c] - p[2][c]) + t * (p[4][c] - p[2][c]), ulp(rng));
        }
      }
    }
    const bool want = ref::segment_meets_triangle(p[0], p[1], p[2], p[3], p[4]);
    meets += want;
    const int sp = ref::orientation3d(p[2], p[3], p[4], p[0]), sq = ref::orientation3d(p[2], p[3], p[4], p[1]);
    coplanar_meets += want && sp == 0 && sq == 0 && !triangle_degenerate(p[2], p[3], p[4]);
    touching += want && (sp == 0) != (sq == 0);
    // Both directions of the segment, the triangle's three rotations and its mirror.
    const int orders[6][3] = {{2, 3, 4}, {3, 4, 2}, {4, 2, 3}, {2, 4, 3}, {4, 3, 2}, {3, 2, 4}};
    for (const auto& o : orders)
      for (int flip = 0; flip < 2; ++flip) {
        const bool got = segment_meets_triangle(p[flip], p[1 - flip], p[o[0]], p[o[1]], p[o[2]]);
        if (got != want) {
          ++bad;
          std::printf("segment-triangle disagreement in case %d: reference %d\n", n, int(want));
        }
      }
  }
  std::printf("%d of 30000 meet; %d in the triangle's plane, %d with one end on it\n", meets, coplanar_meets, touching);
  EXPECT_EQ(bad, 0);
  EXPECT_GT(meets, 3000);
  EXPECT_GT(coplanar_meets, 200);
  EXPECT_GT(touching, 300);
}

namespace {

// A 10 mm cube of 1 mm nodes at the origin (nodes at (i + 1/2) mm), horizon 3 mm.
const char* kBlock =
    "name: b\nmaterials:\n  m: {model: pmb, density: 2200, micromodulus: 1.0e19, critical_stretch: 0.05}\n"
    "bodies:\n  block: {kind: solid, material: m, origin: [0, 0, 0], size: [0.01, 0.01, 0.01], spacing: 0.001,\n"
    "          horizon: 0.003015}\nstages:\n  - {name: r, steps: 1}\n";

// A polygon crack as the scene reader makes it (checked, with its plane's filter).
Crack polygon(const std::vector<Vec3>& corners) {
  std::string text = std::string(kBlock) + "cracks:\n  - {polygon: [";
  char corner[128];
  for (std::size_t k = 0; k < corners.size(); ++k) {
    std::snprintf(corner, sizeof corner, "%s[%.17g, %.17g, %.17g]", k ? ", " : "", corners[k][0], corners[k][1], corners[k][2]);
    text += corner;
  }
  const Scene scene = parse_scene(text + "]}\n", "polygon-test");
  EXPECT_TRUE(std::isfinite(scene.cracks.at(0).plane_tolerance));
  return scene.cracks.at(0);
}

}  // namespace

// Polygon cracks in a block break exactly the bonds whose reference segment meets them: between
// node layers, through a layer of nodes (every bond of those nodes that meets it), tilted, and
// ending inside the block (the bonds past its edges stay intact).
TEST(PolygonCrack, BlockBreaksExactlyTheBondsThePolygonsMeet) {
  const Sheet block(kBlock);
  struct Case {
    const char* what;
    std::vector<Crack> cracks;
    std::int64_t at_least;
  };
  std::vector<Case> cases = {
      {"plane between layers", {polygon({{0.005, -1, -1}, {0.005, 1, -1}, {0.005, 1, 1}, {0.005, -1, 1}})}, 5000},
      {"plane through a layer", {polygon({{0.0045, -1, -1}, {0.0045, 1, -1}, {0.0045, 1, 1}, {0.0045, -1, 1}})}, 5000},
      {"half plane ending at y = 5 mm", {polygon({{0.005, -1, -1}, {0.005, 0.005, -1}, {0.005, 0.005, 1}, {0.005, -1, 1}})}, 2000},
      {"tilted quadrilateral inside", {polygon({{0.002, 0.002, 0.003}, {0.008, 0.002, 0.006}, {0.008, 0.007, 0.0065}, {0.002, 0.007, 0.0035}})}, 1000},
      {"triangle with corners on nodes", {polygon({{0.0015, 0.0015, 0.0045}, {0.0085, 0.0015, 0.0045}, {0.0015, 0.0085, 0.0045}})}, 1000},
      {"hexagon and a crossing plane", {polygon({{0.003, 0.005, 0.001}, {0.007, 0.005, 0.001}, {0.009, 0.005, 0.005}, {0.007, 0.005, 0.009}, {0.003, 0.005, 0.009}, {0.001, 0.005, 0.005}}),
                                        polygon({{-1, -1, 0.0052}, {1, -1, 0.0052}, {1, 1, 0.0052}, {-1, 1, 0.0052}})}, 3000},
  };
  std::vector<Vec3> penny;  // 12 corners in the layer of nodes z = 4.5 mm
  for (int k = 0; k < 12; ++k)
    penny.push_back({0.005 + 0.0037 * std::cos(k * M_PI / 6), 0.005 + 0.0037 * std::sin(k * M_PI / 6), 0.0045});
  cases.push_back({"penny of 12 corners in a layer", {polygon(penny)}, 2000});
  for (const Case& c : cases) {
    std::int64_t broken, expected, wrong, asymmetric;
    block.compare(c.cracks, broken, expected, wrong, asymmetric);
    std::printf("%-32s %5lld bonds broken, %5lld meet the polygons\n", c.what, static_cast<long long>(broken),
                static_cast<long long>(expected));
    EXPECT_GT(expected, c.at_least) << c.what;
    EXPECT_EQ(broken, expected) << c.what;
    EXPECT_EQ(wrong, 0) << c.what << ": bonds broken that do not meet the polygon, or the reverse";
    EXPECT_EQ(asymmetric, 0) << c.what << ": the two ends of a bond disagree";
  }
}

// On a flat sheet at z = 0, a vertical rectangle through the slit's segment breaks the same bonds
// as the slit.
TEST(PolygonCrack, VerticalRectangleCutsASheetAsItsSlitDoes) {
  const Sheet sheet(kSheet);
  const std::vector<std::array<double, 4>> slits = {
      {0.0025, 0.0025, 0.006, 0.006}, {0.0021, 0.0033, 0.0063, 0.0075}, {0.001, 0.005, 0.005, 0.005}, {-1, 0.0051, 0.0043, 0.0051}};
  for (const auto& e : slits) {
    std::int64_t b1, e1, w1, a1, b2, e2, w2, a2;
    sheet.compare({crack(e[0], e[1], e[2], e[3])}, b1, e1, w1, a1);
    sheet.compare({polygon({{e[0], e[1], -0.001}, {e[2], e[3], -0.001}, {e[2], e[3], 0.001}, {e[0], e[1], 0.001}})}, b2, e2, w2, a2);
    EXPECT_GT(b1, 20);
    EXPECT_EQ(b1, b2);
    EXPECT_EQ(w1 + w2 + a1 + a2, 0);
  }
}

// Polygons of many corners test only the fan triangles about a bond's crossing of their plane
// (Crack::fan_low, crosses): the same answer as testing every triangle, on segments that pass
// through corners, along the fan's diagonals, in the plane, near the first corner, nearly
// parallel to the plane and far off, for polygons of 8 to 2000 corners at several scales,
// orientations and with corners nearly in line; and in either order of the ends.
TEST(PolygonCrack, FanSearchGivesTheAnswerOfEveryTriangle) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::int64_t tested = 0, meets = 0, near_corner = 0, in_plane = 0, bad = 0;
  const int sizes[] = {8, 9, 13, 64, 300, 2000};
  for (int trial = 0; trial < 24; ++trial) {
    const int n = sizes[trial % 6];
    const double scale = std::pow(10.0, -4 + (trial % 5)), stretch = 1.0 + 2.0 * (trial % 3);
    // An ellipse's points at increasing angles (some nearly in line: a short arc crowded with
    // corners), rotated into a random plane about a random centre.
    std::vector<double> theta(n);
    for (int k = 0; k < n; ++k)
      theta[k] = trial % 4 == 3 ? (k < n / 2 ? 1e-4 * k / n : M_PI + M_PI * (k - n / 2) / (n - n / 2)) : 2 * M_PI * k / n;
    Vec3 e1{U(rng), U(rng), U(rng)}, e2{U(rng), U(rng), U(rng)};
    auto norm = [](Vec3& x) {
      const double l = std::hypot(x[0], x[1], x[2]);
      for (double& c : x) c /= l;
    };
    norm(e1);
    const double d12 = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
    for (int d = 0; d < 3; ++d) e2[d] -= d12 * e1[d];
    norm(e2);
    const Vec3 centre{scale * U(rng), scale * U(rng), scale * U(rng)};
    std::vector<Vec3> corners(n);
    for (int k = 0; k < n; ++k)
      for (int d = 0; d < 3; ++d)
        corners[k][d] = centre[d] + scale * (stretch * std::cos(theta[k]) * e1[d] + std::sin(theta[k]) * e2[d]);
    const Crack fast = polygon(corners);
    ASSERT_EQ(fast.fan_low.size(), static_cast<std::size_t>(n - 2));
    Crack every = fast;
    every.fan_low.clear();
    every.fan_high.clear();
    const Vec3 normal = fast.plane_normal;
    auto on = [&](double s, double t) {  // a point of the polygon's plane, in its ellipse's frame
      Vec3 p;
      for (int d = 0; d < 3; ++d) p[d] = centre[d] + scale * (stretch * s * e1[d] + t * e2[d]);
      return p;
    };
    auto lerp = [](const Vec3& a, const Vec3& b, double t) {
      return Vec3{a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])};
    };
    auto lift = [&](const Vec3& p, double h) { return Vec3{p[0] + h * normal[0], p[1] + h * normal[1], p[2] + h * normal[2]}; };
    for (int s = 0; s < 4000; ++s) {
      Vec3 a, b;
      const int kind = s % 8;
      const Vec3 corner = corners[rng() % n], other = corners[rng() % n];
      const double h = scale * 0.1 * U(rng);
      switch (kind) {
        case 0:  // across the plane at a random point of it, maybe outside the polygon
          a = lift(on(1.3 * U(rng), 1.3 * U(rng)), h), b = lift(on(1.3 * U(rng), 1.3 * U(rng)), -h - 1e-3 * scale);
          break;
        case 1:  // through a corner (an end on it, or passing it)
          a = lift(corner, h), b = rng() % 2 ? corner : lift(corner, -h);
          break;
        case 2:  // through a point of a fan diagonal (first corner to another)
          a = lerp(corners[0], corner, 0.5 + 0.5 * U(rng)), b = lift(a, -h), a = lift(a, h);
          break;
        case 3:  // in the plane, from a corner to another or across the polygon
          a = corner, b = rng() % 2 ? other : on(1.5 * U(rng), 1.5 * U(rng));
          ++in_plane;
          break;
        case 4:  // near the first corner
          a = lift(lerp(corners[0], on(U(rng), U(rng)), 1e-6 * std::fabs(U(rng))), h), b = lift(corners[0], -h);
          ++near_corner;
          break;
        case 5:  // nearly parallel to the plane, within its tolerance
          a = lift(on(U(rng), U(rng)), 1e-12 * scale * U(rng)), b = lift(on(U(rng), U(rng)), 1e-12 * scale * U(rng));
          break;
        case 6:  // an edge's point, through it
          a = lerp(corner, corners[(&corner - &corners[0] + 1) % n], 0.5 * (1 + U(rng)));
          b = lift(a, -h), a = lift(a, h);
          break;
        default:  // short bonds about the polygon's rim
          a = lift(on(std::cos(6.3 * U(rng)), std::sin(6.3 * U(rng))), h);
          b = lift(a, -2 * h);
          for (int d = 0; d < 3; ++d) b[d] += 0.01 * scale * U(rng);
      }
      const bool want = crosses(a.data(), b.data(), every);
      const bool got = crosses(a.data(), b.data(), fast), back = crosses(b.data(), a.data(), fast);
      ++tested;
      meets += want;
      if (got != want || back != want) {
        ++bad;
        if (bad < 5)
          ADD_FAILURE() << "trial " << trial << " (" << n << " corners), kind " << kind << ": every triangle says " << want
                        << ", the search " << got << " and " << back;
      }
    }
  }
  std::printf("%lld segments, %lld meet (%lld in the plane, %lld near the first corner)\n", static_cast<long long>(tested),
              static_cast<long long>(meets), static_cast<long long>(in_plane), static_cast<long long>(near_corner));
  EXPECT_EQ(bad, 0);
  EXPECT_GT(meets, tested / 5);
}
