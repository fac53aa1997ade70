// Rigid-tool contact kernel (include/peri/contact.hpp): penalty normal force, capped Coulomb
// friction, their work and energy.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "peri/loads/contact.hpp"

namespace peri {
namespace {

RigidCylinder tool(double friction) {
  RigidCylinder t;
  t.radius = 1e-3;
  t.center[0] = 0.0;
  t.center[1] = 0.0;
  t.velocity[0] = 2.0;  // at t = 1e-4 s the axis is at x = 2e-4
  t.velocity[1] = 0.0;
  t.friction = friction;
  t.stiffness = 1e12;
  return t;
}

// Three nodes at t = 1e-4: inside at radius 0.5 mm (+x of the axis), inside at 0.8 mm (+y), outside.
struct Nodes {
  // Positions as planes (x of the three nodes, then y, then z: current_positions' layout).
  std::vector<double> x{2e-4 + 5e-4, 2e-4, 2e-4 + 1.5e-3, 0, 8e-4, 0, 0, 1e-5, 0};
  std::vector<double> v{2.0, 3.0, -1.0, 2.0, 0.0, 0.0, 9.0, 9.0, 9.0};  // node 0 slides along y and z
  std::vector<double> volume{2e-10, 3e-10, 4e-10};
  std::vector<double> inv_density{1.0 / 1200, 1.0 / 1000, 1.0 / 1200};
};

TEST(Contact, PenaltyNormalForceAndEnergy) {
  const RigidCylinder t = tool(0.0);
  Nodes n;
  std::vector<double> f(9, 0.0);
  ContactTally tally;
  cylinder_contact(t, 1e-4, 1e-7, n.x.data(), 3, n.v.data(), n.volume.data(), n.inv_density.data(), 3, f.data(), tally);
  EXPECT_EQ(tally.nodes, 2);
  // Node 0: depth 0.5 mm along +x: rho k p = 1200 * 1e12 * 5e-4.
  EXPECT_NEAR(f[0], 1200 * 1e12 * 5e-4, 1e-9 * 1200 * 1e12 * 5e-4);
  EXPECT_EQ(f[1], 0.0);
  EXPECT_EQ(f[2], 0.0);
  // Node 1: depth 0.2 mm along +y (its x is the axis' x).
  EXPECT_NEAR(f[4], 1000 * 1e12 * 2e-4, 1e-9 * 1000 * 1e12 * 2e-4);
  EXPECT_NEAR(f[3], 0.0, 1e-6);
  for (int c = 6; c < 9; ++c) EXPECT_EQ(f[c], 0.0);  // outside
  EXPECT_NEAR(tally.force[0], f[0] * 2e-10 + f[3] * 3e-10, 1e-12 * std::fabs(f[0] * 2e-10));
  EXPECT_TRUE(tally.friction.empty());
  const double energy = tally.energy;
  const double expected = 0.5 * 1e12 * (1200 * 5e-4 * 5e-4 * 2e-10 + 1000 * 2e-4 * 2e-4 * 3e-10);
  EXPECT_NEAR(energy, expected, 1e-12 * expected);
  std::printf("normal force densities %.6e %.6e N/m^3, penalty energy %.6e J\n", f[0], f[4], energy);
}

TEST(Contact, CoulombFrictionOpposesTangentialSlidingAndIsCapped) {
  Nodes n;
  const double dt = 1e-7;
  for (double mu : {0.01, 1e6}) {
    const RigidCylinder t = tool(mu);
    std::vector<double> f(9, 0.0);
    ContactTally tally;
    cylinder_contact(t, 1e-4, dt, n.x.data(), 3, n.v.data(), n.volume.data(), n.inv_density.data(), 3, f.data(), tally);
    ASSERT_EQ(tally.friction.size(), 1u);  // node 1 does not move relative to the tool's surface
    const NodeFriction& nf = tally.friction[0];
    EXPECT_EQ(nf.node, 0);
    // Node 0: normal +x; velocity relative to the tool (0, 3, -1): tangential (0, 3, -1).
    const double fn = 1200 * 1e12 * 5e-4, speed = std::sqrt(10.0);
    const double magnitude = std::min(mu * fn, 0.5 * 1200 * speed / dt);
    EXPECT_NEAR(nf.force[0], 0.0, 1e-12 * magnitude);
    EXPECT_NEAR(nf.force[1], -magnitude * 3 / speed, 1e-12 * magnitude);
    EXPECT_NEAR(nf.force[2], magnitude / speed, 1e-12 * magnitude);
    EXPECT_NEAR(f[1], nf.force[1], 1e-12 * magnitude);  // added to the node's force density
    // Work over a step with the end-of-step velocity: dt V f . (v - V_tool), negative.
    const double work = friction_work(t, tally, dt, n.v.data(), n.volume.data());
    EXPECT_NEAR(work, -dt * 2e-10 * magnitude * speed, 1e-12 * dt * 2e-10 * magnitude * speed);
    EXPECT_LT(work, 0.0);
    std::printf("mu %g: friction force density %.6e N/m^3 (%s), work per step %.6e J\n", mu, magnitude,
                mu * fn < 0.5 * 1200 * speed / dt ? "Coulomb" : "capped at rho |v_t| / (2 dt)", work);
    // The same friction given back (a resumed run) gives the same forces, bit for bit.
    std::vector<double> g(9, 0.0);
    ContactTally again;
    cylinder_contact(t, 1e-4, dt, n.x.data(), 3, n.v.data(), n.volume.data(), n.inv_density.data(), 3, g.data(), again,
                     &tally.friction);
    EXPECT_EQ(f, g);
    EXPECT_EQ(again.force[0], tally.force[0]);
    EXPECT_EQ(again.force[1], tally.force[1]);
    EXPECT_EQ(again.force[2], tally.force[2]);
  }
}

}  // namespace
}  // namespace peri
