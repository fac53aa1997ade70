// Crack tip tracker on synthetic damage fields with known tips (serial, pure module).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "peri/diagnostics/crack_tips.hpp"

namespace peri {
namespace {

constexpr double dx = 1e-3;

// Square grid of nx x ny nodes, spacing dx, centred on the origin (nodes between the axes).
struct Field {
  std::vector<double> X, damage;
};
Field grid(int nx, int ny) {
  Field f;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) f.X.insert(f.X.end(), {(i - nx / 2 + 0.5) * dx, (j - ny / 2 + 0.5) * dx, 0.0});
  f.damage.assign(nx * ny, 0.0);
  return f;
}

double segment_distance(const double* p, const double* a, const double* b) {
  const double ux = b[0] - a[0], uy = b[1] - a[1];
  const double t = std::clamp(((p[0] - a[0]) * ux + (p[1] - a[1]) * uy) / (ux * ux + uy * uy), 0.0, 1.0);
  return std::hypot(p[0] - a[0] - t * ux, p[1] - a[1] - t * uy);
}

// Crack along segments (a -> b): damage 0.45 within 0.75 dx, 0.2 (below threshold) out to 1.5 dx,
// plus background noise below the threshold and isolated damaged specks.
void add_crack(Field& f, std::vector<std::array<double, 2>> path) {
  for (std::size_t i = 0; i < f.damage.size(); ++i) {
    double e = 1e9;
    for (std::size_t k = 0; k + 1 < path.size(); ++k) e = std::min(e, segment_distance(&f.X[3 * i], path[k].data(), path[k + 1].data()));
    if (e < 0.75 * dx) f.damage[i] = std::max(f.damage[i], 0.45);
    else if (e < 1.5 * dx) f.damage[i] = std::max(f.damage[i], 0.2);
  }
}
void add_noise(Field& f, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 0.25);
  for (double& d : f.damage) d = std::max(d, u(rng));
  std::uniform_int_distribution<std::size_t> pick(0, f.damage.size() - 1);
  for (int k = 0; k < 5; ++k) f.damage[pick(rng)] = 0.5;  // isolated specks: no tip
}

CrackTipSettings settings() {
  CrackTipSettings s;
  s.damage_threshold = 0.3;
  s.link_distance = 2 * dx;
  s.tip_separation = 6 * dx;
  return s;
}

// Index of the tip nearest to p, and its distance.
std::pair<int, double> nearest(const std::vector<CrackTip>& tips, double x, double y) {
  int best = -1;
  double d = 1e9;
  for (std::size_t k = 0; k < tips.size(); ++k) {
    const double e = std::hypot(tips[k].position[0] - x, tips[k].position[1] - y);
    if (e < d) d = e, best = static_cast<int>(k);
  }
  return {best, d};
}

void print(const char* name, const std::vector<CrackTip>& tips) {
  std::printf("%s: %zu tips", name, tips.size());
  for (const auto& t : tips)
    std::printf("  (%.2f, %.2f) mm cluster %d path %.2f mm", t.position[0] * 1e3, t.position[1] * 1e3, t.cluster,
                t.path_length * 1e3);
  std::printf("\n");
}

TEST(CrackTips, StraightCrackWithSeedHasTwoTipsAtItsEnds) {
  Field f = grid(120, 60);
  add_crack(f, {{-0.020, 0.0005}, {0.031, 0.0005}});
  add_noise(f, 1);
  const auto tips = find_crack_tips_in_field(f.X, f.damage, {0.0055, 0.0005, 0}, settings());
  print("straight", tips);
  ASSERT_EQ(tips.size(), 2u);
  // Ends at x = -20 and 31 mm; the front centroid lies within a link distance behind the end.
  EXPECT_LT(nearest(tips, -0.020, 0.0005).second, 2 * dx);
  EXPECT_LT(nearest(tips, 0.031, 0.0005).second, 2 * dx);
  EXPECT_EQ(tips[0].cluster, tips[1].cluster);
  // Path lengths from the seed: 25.5 mm each way.
  for (const auto& t : tips) EXPECT_NEAR(t.path_length, 0.0255, 2 * dx);
}

TEST(CrackTips, BranchingCrackHasOneTipPerBranch) {
  Field f = grid(120, 80);
  // Stem from an edge notch at x = -40 mm to the branch point, then two branches at +-30 degrees.
  const double bx = -0.005, L = 0.030, a = 30 * 3.14159265358979 / 180;
  add_crack(f, {{-0.040, 0.0005}, {bx, 0.0005}, {bx + L * std::cos(a), 0.0005 + L * std::sin(a)}});
  add_crack(f, {{bx, 0.0005}, {bx + L * std::cos(a), 0.0005 - L * std::sin(a)}});
  add_noise(f, 2);
  // A short side stub (2 mm) must not count as a tip.
  add_crack(f, {{-0.025, 0.0005}, {-0.025, 0.0025}});
  const auto tips = find_crack_tips_in_field(f.X, f.damage, {-0.040, 0.0005, 0}, settings());
  print("branching", tips);
  ASSERT_EQ(tips.size(), 2u);
  EXPECT_LT(nearest(tips, bx + L * std::cos(a), 0.0005 + L * std::sin(a)).second, 2 * dx);
  EXPECT_LT(nearest(tips, bx + L * std::cos(a), 0.0005 - L * std::sin(a)).second, 2 * dx);
  // Path length through the links (at most 2 dx long) overestimates an oblique path: the stem is
  // 35 mm and each branch 30 mm at 30 degrees to the grid.
  for (const auto& t : tips) EXPECT_NEAR(t.path_length / (0.035 + L), 1.0, 0.08);
}

TEST(CrackTips, TwoSeparateCracksWithoutSeedsHaveFourTips) {
  Field f = grid(120, 80);
  add_crack(f, {{-0.040, -0.0195}, {-0.010, -0.0195}});
  add_crack(f, {{0.000, 0.0105}, {0.020, 0.0205}});
  add_noise(f, 3);
  const auto tips = find_crack_tips_in_field(f.X, f.damage, {}, settings());
  print("two cracks", tips);
  ASSERT_EQ(tips.size(), 4u);
  for (auto [x, y] : {std::pair{-0.040, -0.0195}, {-0.010, -0.0195}, {0.000, 0.0105}, {0.020, 0.0205}})
    EXPECT_LT(nearest(tips, x, y).second, 2 * dx) << x << ", " << y;
  EXPECT_EQ(tips[0].cluster, tips[1].cluster);
  EXPECT_EQ(tips[2].cluster, tips[3].cluster);
  EXPECT_NE(tips[0].cluster, tips[2].cluster);
}

TEST(CrackTips, ResultDoesNotDependOnWhichUndamagedNodesArePresent) {
  // The parallel driver passes only the damaged nodes (natural ids); the whole-field call must agree.
  Field f = grid(100, 50);
  add_crack(f, {{-0.02, 0.0005}, {0.02, 0.0005}});
  add_noise(f, 4);
  const auto all = find_crack_tips_in_field(f.X, f.damage, {0, 0.0005, 0}, settings());
  std::vector<std::int64_t> ids;
  std::vector<double> X;
  for (std::size_t i = 0; i < f.damage.size(); ++i)
    if (f.damage[i] >= 0.3) ids.push_back(i), X.insert(X.end(), &f.X[3 * i], &f.X[3 * i] + 3);
  const auto some = find_crack_tips(ids, X, {0, 0.0005, 0}, settings());
  ASSERT_EQ(all.size(), some.size());
  for (std::size_t k = 0; k < all.size(); ++k) {
    EXPECT_EQ(all[k].node, some[k].node);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(all[k].position[c], some[k].position[c]);
  }
}

TEST(CrackTipTracker, SmoothedSpeedAndSteadyMeanOfARunningCrack) {
  // A slit growing both ways at 300 and 450 m/s on the grid; tips quantised to the nodes.
  const double v1 = 300, v2 = 450, dt = 5e-7, window = 2.5e-5;  // 7.5-11 dx per window
  CrackTipTracker tracker(settings(), window, 6 * dx + 2 * 1000 * dt);
  double vmax = 0;
  for (int k = 0; k <= 200; ++k) {  // 100 us
    const double t = k * dt;
    Field f = grid(200, 20);
    add_crack(f, {{-0.005 - v1 * t, 0.0005}, {0.005 + v2 * t, 0.0005}});
    if (-0.005 - v1 * t < -0.098 || 0.005 + v2 * t > 0.098) break;
    const auto tips = find_crack_tips_in_field(f.X, f.damage, {0, 0.0005, 0}, settings());
    tracker.update(t, tips);
  }
  ASSERT_EQ(tracker.tracks().size(), 2u);
  for (const CrackTrack& tr : tracker.tracks()) {
    const double expected = tr.position.back()[0] < 0 ? v1 : v2;
    int defined = 0;
    double worst = 0;
    for (double v : tr.speed)
      if (std::isfinite(v)) ++defined, worst = std::max(worst, std::fabs(v / expected - 1)), vmax = std::max(vmax, v);
    std::printf("track %d: %d speeds defined, worst relative error %.3f\n", tr.id, defined, worst);
    EXPECT_GT(defined, 50);
    EXPECT_LT(worst, 0.08);  // grid quantisation (1 mm steps) over the window
  }
  EXPECT_NEAR(tracker.max_speed(), vmax, 1e-9);
  EXPECT_NEAR(tracker.max_speed() / v2, 1.0, 0.05);
  // Both tips run at constant speed, so the steady mean is the travel-weighted mean of the two.
  const double t_end = tracker.tracks()[0].time.back();
  const double expected_mean = (0.5 * v1 * t_end + 0.5 * v2 * t_end) / (0.5 * t_end + 0.5 * t_end);
  std::printf("mean speed over the steady part %.1f m/s (expected %.1f)\n", tracker.mean_speed(), expected_mean);
  EXPECT_NEAR(tracker.mean_speed() / expected_mean, 1.0, 0.03);
}

TEST(CrackTipTracker, BranchStartsANewTrack) {
  CrackTipTracker tracker(settings(), 1e-6, 0.004);
  auto tip = [](double x, double y) {
    CrackTip t;
    t.position = {x, y, 0};
    return t;
  };
  tracker.update(0, {tip(0, 0)});
  tracker.update(1e-6, {tip(0.001, 0)});
  tracker.update(2e-6, {tip(0.002, 0.0005), tip(0.002, -0.0005)});  // branch
  tracker.update(3e-6, {tip(0.003, 0.001), tip(0.003, -0.001)});
  tracker.update(4e-6, {tip(0.004, 0.001)});  // the lower branch is gone
  ASSERT_EQ(tracker.tracks().size(), 2u);
  EXPECT_EQ(tracker.tracks()[0].time.size(), 5u);
  EXPECT_EQ(tracker.tracks()[1].time.size(), 2u);
  EXPECT_FALSE(tracker.tracks()[1].active);
  EXPECT_TRUE(tracker.tracks()[0].active);
  EXPECT_DOUBLE_EQ(tracker.tracks()[0].position[2][1], 0.0005);  // equal distances: lower tip index wins
  EXPECT_DOUBLE_EQ(tracker.tracks()[1].position.front()[1], -0.0005);
}

TEST(CrackTipTracker, LeastSquaresSlope) {
  const double t[] = {0, 1, 2, 3}, y[] = {1, 3.1, 4.9, 7};
  EXPECT_NEAR(least_squares_slope(t, y, 4), 1.98, 1e-12);
  EXPECT_TRUE(std::isnan(least_squares_slope(t, y, 1)));
}

}  // namespace
}  // namespace peri
