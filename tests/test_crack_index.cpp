// The pre-crack index (peri/bonds/crack_index.hpp): for bonds no longer than its reach, it finds a
// crossing exactly when testing every crack does, for short and long cracks in any direction and
// bonds that end on a crack, and a sheet's pre-cracked bonds are the same as with every crack
// tested.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "peri/bonds/bonds.hpp"
#include "peri/bonds/crack_index.hpp"
#include "peri/partition/domain.hpp"

namespace peri {
namespace {

bool brute_force(const std::vector<Crack>& cracks, const double* a, const double* b) {
  for (const Crack& c : cracks)
    if (crosses(a, b, c)) return true;
  return false;
}

std::vector<const Crack*> pointers(const std::vector<Crack>& cracks) {
  std::vector<const Crack*> out;
  for (const Crack& c : cracks) out.push_back(&c);
  return out;
}

TEST(CrackIndex, FindsExactlyTheCrossingsOfEveryCrack) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-0.05, 0.05), unit(0, 1);
  const double reach = 0.002;
  std::vector<Crack> cracks;
  for (int k = 0; k < 3000; ++k) {
    Crack c;
    c.from = {u(rng), u(rng), 0};
    // Short cracks in any direction, long ones across the box, some along the axes.
    const double length = k % 10 == 0 ? 0.08 * unit(rng) : 0.003 * unit(rng) + 1e-5;
    const double angle = k % 7 == 0 ? 0.0 : k % 7 == 1 ? M_PI / 2 : 2 * M_PI * unit(rng);
    c.to = {c.from[0] + length * std::cos(angle), c.from[1] + length * std::sin(angle), 0};
    cracks.push_back(c);
  }
  const CrackIndex index(pointers(cracks), reach);
  std::int64_t crossing = 0;
  for (int k = 0; k < 200000; ++k) {
    const double a[3] = {u(rng), u(rng), 0};
    const double r = reach * unit(rng), t = 2 * M_PI * unit(rng);
    const double b[3] = {a[0] + r * std::cos(t), a[1] + r * std::sin(t), 0};
    const bool expected = brute_force(cracks, a, b);
    crossing += expected;
    ASSERT_EQ(index.crosses_any(a, b, 2), expected) << "bond (" << a[0] << ", " << a[1] << ") - (" << b[0] << ", " << b[1] << ")";
  }
  std::printf("3000 cracks, 200000 bonds: %lld cross a crack, the index agrees on every one\n",
              static_cast<long long>(crossing));
  EXPECT_GT(crossing, 1000);
}

TEST(CrackIndex, BondsEndingOnACrackAndCoordinatesBeyondAGrid) {
  // A bond whose end lies on the crack, and one that touches the crack's end point.
  const std::vector<Crack> cracks = {Crack{"c", {}, {0, 0, 0}, {1, 0, 0}}};
  const CrackIndex index(pointers(cracks), 0.1);
  const double on[3] = {0.5, 0, 0}, above[3] = {0.5, 0.05, 0}, end[3] = {1, 0, 0}, beyond[3] = {1.05, 0.05, 0};
  EXPECT_EQ(index.crosses_any(on, above, 2), brute_force(cracks, on, above));
  EXPECT_EQ(index.crosses_any(end, beyond, 2), brute_force(cracks, end, beyond));
  // Cracks spanning 1e300 m: one cell holding every crack, the same answers.
  const std::vector<Crack> wide = {Crack{"w", {}, {-1e300, -1, 0}, {1e300, 1, 0}}, Crack{"s", {}, {0, 5, 0}, {1, 5, 0}}};
  const CrackIndex all(pointers(wide), 0.1);
  const double a[3] = {0.5, -0.05, 0}, b[3] = {0.5, 0.05, 0}, c[3] = {0.5, 4.95, 0}, d[3] = {0.5, 5.05, 0};
  EXPECT_EQ(all.crosses_any(a, b, 2), brute_force(wide, a, b));
  EXPECT_EQ(all.crosses_any(c, d, 2), brute_force(wide, c, d));
  EXPECT_TRUE(all.crosses_any(c, d, 2));
}

TEST(CrackIndex, ManyCracksOnASheetBreakTheSameBonds) {
  // 5,000 short cracks on a 200 x 200 sheet (about 1.1 million ordered bonds): the domain's
  // pre-cracked bonds are those every crack tested finds.
  Scene scene = parse_scene(R"(
name: cracked
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2}
bodies:
  sheet: {material: rubber, origin: [0, 0, 0], size: [0.05, 0.05], thickness: 0.0005, spacing: 0.00025}
stages:
  - {steps: 1}
)", "cracked");
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 0.05), unit(0, 1);
  for (int k = 0; k < 5000; ++k) {
    Crack c;
    c.name = "c" + std::to_string(k);
    c.from = {u(rng), u(rng), 0};
    const double t = 2 * M_PI * unit(rng);
    c.to = {c.from[0] + 0.0004 * std::cos(t), c.from[1] + 0.0004 * std::sin(t), 0};
    scene.cracks.push_back(c);
  }
  const Nodes nodes = discretize(scene);
  const CellList cells(nodes, reach(nodes.bodies[0]));
  const Partition part = partition_from_parts(nodes, std::vector<int>(nodes.size(), 0), 1);
  const auto t0 = std::chrono::steady_clock::now();
  const Domain d = build_domain(scene, nodes, cells, part, 0);
  const double indexed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::int64_t differ = 0, broken = 0, checked = 0;
  for (std::int32_t r = 0; r < d.owned; r += 3) {  // every third row: the brute force is slow
    const std::int64_t i = d.natural[r];
    for (std::int64_t b = d.bonds.offsets[r]; b < d.bonds.offsets[r + 1]; ++b) {
      const std::int64_t j = d.natural[d.bonds.neighbor[b]];
      const bool expected = brute_force(scene.cracks, &nodes.X[3 * std::min(i, j)], &nodes.X[3 * std::max(i, j)]);
      differ += expected != (d.bonds.broken[b] != 0);
      broken += expected;
      ++checked;
    }
  }
  std::printf("5000 cracks: domain built in %.2f s; %lld of %lld bonds checked against every crack are broken, "
              "%lld differ\n", indexed, static_cast<long long>(broken), static_cast<long long>(checked),
              static_cast<long long>(differ));
  EXPECT_EQ(differ, 0);
  EXPECT_GT(broken, 10000);
  EXPECT_LT(broken, checked / 2);
}

}  // namespace
}  // namespace peri
