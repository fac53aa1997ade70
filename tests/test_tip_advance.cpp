// The incremental crack-tip advance (kernels/tip_advance.hpp) on a PMB membrane grid (20 x 15
// nodes, spacing 1 mm, horizon 3 mm): which nodes are crack tips, which may break, and that an
// overstretched bond breaks near a crack tip but not far from any damage (where it breaks
// without the rule).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "law_checks.hpp"
#include "peri/kernels/tip_advance.hpp"

namespace peri {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Grid {
  law_checks::Body body{"model: pmb, density: 1200, bulk_modulus: 3.0e8, critical_stretch: 0.01", false};
  std::vector<double> x;
  std::vector<std::uint8_t> flags;
  Grid() : x(3 * static_cast<std::size_t>(body.d.local())), flags(body.d.bonds.broken.size(), 0) {}
  const Domain& d() const { return body.d; }
  /// The node nearest to (px, py) [m].
  std::int32_t node(double px, double py) const {
    std::int32_t best = 0;
    double best2 = kInf;
    for (std::int32_t i = 0; i < d().owned; ++i) {
      const double dx = d().X[3 * i] - px, dy = d().X[3 * i + 1] - py, r2 = dx * dx + dy * dy;
      if (r2 < best2) best2 = r2, best = i;
    }
    return best;
  }
  BondView view() { return body.view(x.data(), flags.data()); }
  /// Positions X + u with node k moved by (0, dy).
  void positions(std::int32_t k, double dy) {
    std::vector<double> u(3 * static_cast<std::size_t>(d().local()), 0.0);
    if (k >= 0) u[3 * k + 1] = dy;
    current_positions(d().X.data(), u.data(), 0, d().local(), d().local(), x.data());
  }
  /// Breaks the bonds crossing y = 7 mm left of x = xt (a pre-crack from the edge x = 0).
  void precrack(double xt) {
    for (std::int32_t i = 0; i < d().owned; ++i)
      for (std::int64_t b = d().bonds.offsets[i]; b < d().bonds.offsets[i + 1]; ++b) {
        const std::int32_t j = d().bonds.neighbor[b];
        const double yi = d().X[3 * i + 1] - 0.007, yj = d().X[3 * j + 1] - 0.007;
        if (yi * yj >= 0) continue;
        const double s = yi / (yi - yj), xc = d().X[3 * i] + s * (d().X[3 * j] - d().X[3 * i]);
        if (xc < xt) flags[b] = kBrokenFlag;
      }
  }
  std::int64_t broken_bonds_of(std::int32_t i) const {
    std::int64_t n = 0;
    for (std::int64_t b = d().bonds.offsets[i]; b < d().bonds.offsets[i + 1]; ++b) n += flags[b] & kBrokenFlag;
    return n;
  }
  std::vector<std::int32_t> all_rows() const { return body.rows; }
};

// Tips are the newest damage within a family; break times at or after `now` do not count yet.
TEST(TipAdvance, TipsAreTheNewestDamageOfAFamily) {
  Grid g;
  const std::size_t n = static_cast<std::size_t>(g.d().local());
  std::vector<double> stamp(n, -kInf);
  std::vector<std::int32_t> damaged;
  // A crack along y = 7.5 mm, its nodes damaged in order of x (x = 0.5 .. 9.5 mm at times 1 .. 10).
  for (int k = 0; k < 10; ++k) {
    const std::int32_t i = g.node(0.0005 + 0.001 * k, 0.0075);
    stamp[i] = 1.0 + k;
    damaged.push_back(i);
  }
  std::vector<std::uint8_t> tip(n, 0);
  mark_crack_tips(g.view(), damaged, stamp.data(), 100.0, tip.data());
  for (int k = 0; k < 10; ++k) EXPECT_EQ(tip[g.node(0.0005 + 0.001 * k, 0.0075)], k == 9 ? 1 : 0) << "node " << k;
  // At now = 10 the node stamped at 10 is not damaged yet: its predecessor is the tip.
  std::fill(tip.begin(), tip.end(), 0);
  mark_crack_tips(g.view(), damaged, stamp.data(), 10.0, tip.data());
  for (int k = 0; k < 10; ++k) EXPECT_EQ(tip[g.node(0.0005 + 0.001 * k, 0.0075)], k == 8 ? 1 : 0) << "node " << k;
  // Nodes within r = 1.5 mm of the tip (9.5, 7.5) mm may break: its own, 4 and 4 diagonal neighbours.
  std::fill(tip.begin(), tip.end(), 0);
  mark_crack_tips(g.view(), damaged, stamp.data(), 100.0, tip.data());
  std::vector<std::uint8_t> allowed(n, 0);
  mark_within(g.view(), g.d().owned, g.d().body.data(), damaged, {}, tip.data(), {0.0015 * 0.0015}, allowed.data());
  int count = 0;
  for (std::int32_t i = 0; i < g.d().owned; ++i) {
    const double dx = g.d().X[3 * i] - 0.0095, dy = g.d().X[3 * i + 1] - 0.0075;
    EXPECT_EQ(allowed[i], std::hypot(dx, dy) <= 0.0015 ? 1 : 0) << "node at " << g.d().X[3 * i] << ", " << g.d().X[3 * i + 1];
    count += allowed[i];
  }
  EXPECT_EQ(count, 9);
}

// tip_advance_tips: body. Two cracks, one along y = 7.5 mm (x = 0.5 .. 4.5 mm, times 1 .. 5)
// and one along y = 12.5 mm (x = 10.5 .. 14.5 mm, times 2 .. 6): by family each crack has its
// tip; by body only the later crack's newest node is one, and nothing near the other crack may
// break. Nodes broken in the same evaluation are all tips.
TEST(TipAdvance, OneTipForTheBody) {
  Grid g;
  const std::size_t n = static_cast<std::size_t>(g.d().local());
  std::vector<double> stamp(n, -kInf);
  std::vector<std::int32_t> damaged;
  auto at = [&](int crack, int k) { return g.node(0.0005 + 0.01 * crack + 0.001 * k, 0.0075 + 0.005 * crack); };
  for (int crack = 0; crack < 2; ++crack)
    for (int k = 0; k < 5; ++k) {
      stamp[at(crack, k)] = 1.0 + crack + k;
      damaged.push_back(at(crack, k));
    }
  const std::vector<std::uint8_t> by_body{1};
  auto tips = [&](double now, bool body_scope) {
    std::vector<std::uint8_t> tip(n, 0);
    mark_crack_tips(g.view(), damaged, stamp.data(), now, tip.data());
    if (body_scope) {
      std::vector<double> latest(1, -kInf);
      latest_breaks(damaged, g.d().body.data(), stamp.data(), now, by_body, latest);
      mark_latest_tips(damaged, g.d().body.data(), stamp.data(), by_body, latest, tip.data());
    }
    return tip;
  };
  std::vector<std::uint8_t> tip = tips(100.0, false);
  for (int crack = 0; crack < 2; ++crack)
    for (int k = 0; k < 5; ++k) EXPECT_EQ(tip[at(crack, k)], k == 4 ? 1 : 0) << "family: crack " << crack << " node " << k;
  tip = tips(100.0, true);
  for (int crack = 0; crack < 2; ++crack)
    for (int k = 0; k < 5; ++k)
      EXPECT_EQ(tip[at(crack, k)], crack == 1 && k == 4 ? 1 : 0) << "body: crack " << crack << " node " << k;
  // Before time 6 the first crack's tip (time 5) and the second's node at time 5 are both latest.
  tip = tips(6.0, true);
  for (int crack = 0; crack < 2; ++crack)
    for (int k = 0; k < 5; ++k)
      EXPECT_EQ(tip[at(crack, k)], (crack == 0 && k == 4) || (crack == 1 && k == 3) ? 1 : 0)
          << "body, before 6: crack " << crack << " node " << k;
  // Within r = 1.5 mm of the body's tip (14.5, 12.5) mm only: the first crack's tip (4.5, 7.5) mm
  // may not break a bond.
  tip = tips(100.0, true);
  std::vector<std::uint8_t> allowed(n, 0);
  mark_within(g.view(), g.d().owned, g.d().body.data(), damaged, {}, tip.data(), {0.0015 * 0.0015}, allowed.data());
  int count = 0;
  for (std::int32_t i = 0; i < g.d().owned; ++i) count += allowed[i];
  EXPECT_EQ(count, 9);
  EXPECT_EQ(allowed[at(1, 4)], 1);
  EXPECT_EQ(allowed[at(0, 4)], 0);
  // A body without the scope is left to the family rule.
  const std::vector<std::uint8_t> family{0};
  std::vector<double> latest(1, -kInf);
  latest_breaks(damaged, g.d().body.data(), stamp.data(), 100.0, family, latest);
  EXPECT_EQ(latest[0], -kInf);
  tip = tips(100.0, false);
  mark_latest_tips(damaged, g.d().body.data(), stamp.data(), family, latest, tip.data());
  EXPECT_EQ(tip[at(0, 4)], 1);
}

// A pre-crack from the edge to x = 6 mm: a node pulled 0.2 mm off the line (bond strains up to
// 20 times s_0) breaks bonds just ahead of the tip, not 10 mm ahead of it; without the rule it
// breaks there too. A bond held intact acts as an intact bond.
TEST(TipAdvance, BreaksNearTheTipOnly) {
  Grid g;
  g.precrack(0.006);
  const std::size_t n = static_cast<std::size_t>(g.d().local());
  std::vector<double> stamp(n, -kInf);
  std::vector<std::int32_t> count(n, 0), damaged;
  std::vector<std::int32_t> rows = g.all_rows();
  g.positions(-1, 0.0);
  BondView v = g.view();
  std::vector<std::uint8_t> row_broken(n, 1);
  v.row_broken = row_broken.data();
  stamp_breaks(v, rows.data(), rows.size(), count.data(), stamp.data(), damaged, 0.0);
  ASSERT_GT(damaged.size(), 0u);
  std::vector<std::uint8_t> tip(n, 0), allowed(n, 0);
  mark_crack_tips(v, damaged, stamp.data(), 1.0, tip.data());
  mark_within(v, g.d().owned, g.d().body.data(), damaged, {}, tip.data(), {0.0015 * 0.0015}, allowed.data());

  const BondLaw& law = g.body.law;
  const RowBlocks plan = plan_rows(v, rows.data(), rows.size());
  auto pull = [&](std::int32_t k, bool rule, std::vector<double>& f) {
    std::fill(g.flags.begin(), g.flags.end(), 0);
    g.precrack(0.006);
    g.positions(k, 2e-4);
    BondView w = g.view();
    if (rule) w.may_break = allowed.data();
    BondTally t;
    f.assign(3 * n, 0.0);
    law.entry().portable_forces(law.constants(), w, plan, f.data(), false, t);
    return g.broken_bonds_of(k);
  };
  const std::int32_t near = g.node(0.0065, 0.0075), far = g.node(0.0165, 0.0075);
  ASSERT_TRUE(allowed[near]);
  ASSERT_FALSE(allowed[far]);
  std::vector<double> f, f_off, f_intact;
  const std::int64_t precut = [&] {
    std::fill(g.flags.begin(), g.flags.end(), 0);
    g.precrack(0.006);
    return g.broken_bonds_of(near);
  }();
  EXPECT_GT(pull(near, true, f), precut) << "near the tip the rule lets the overstretched bonds break";
  EXPECT_EQ(pull(near, true, f), pull(near, false, f_off)) << "where every bond may break the rule changes nothing";
  EXPECT_EQ(pull(far, true, f), 0) << "far from damage nothing breaks";
  EXPECT_GT(pull(far, false, f_off), 0) << "without the rule the far node's bonds break";
  // The held bonds act as intact ones: the far node's force is the intact law's.
  {
    std::fill(g.flags.begin(), g.flags.end(), 0);
    g.precrack(0.006);
    g.positions(far, 2e-4);
    const BondLaw intact = law.intact();
    BondTally t;
    f_intact.assign(3 * n, 0.0);
    intact.entry().portable_forces(intact.constants(), g.view(), plan, f_intact.data(), false, t);
  }
  pull(far, true, f);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(f[3 * far + c], f_intact[3 * far + c]);
  EXPECT_LT(f[3 * far + 1], 0.0);
  EXPECT_LT(std::abs(f_off[3 * far + 1]), 0.5 * std::abs(f_intact[3 * far + 1]))
      << "without the rule the stretched bonds are cut (the compressed ones remain)";
}

}  // namespace
}  // namespace peri
