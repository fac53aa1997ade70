#include "peri/loads/contact.hpp"

#include <cmath>

#include "peri/models/laws/contact.hpp"

namespace peri {
namespace {

// Depth p of a point inside the tool at time t and the outward unit normal n (cylinders:
// n_z = 0); false if the point is outside (or on the axis or centre, where no direction is defined).
bool penetration(const RigidTool& tool, double time, const double* xi, double& p, double n[3]) {
  double d[3];
  for (int c = 0; c < 3; ++c) d[c] = xi[c] - (tool.center[c] + tool.velocity[c] * (time - tool.t0));
  if (!tool.sphere) d[2] = 0;
  const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  if (!(r2 < tool.radius * tool.radius) || r2 == 0) return false;
  const double r = std::sqrt(r2);
  p = tool.radius - r;
  for (int c = 0; c < 3; ++c) n[c] = d[c] / r;
  return true;
}

}  // namespace

void cylinder_contact(const RigidCylinder& tool, double time, double dt, const double* x, std::int64_t x_stride,
                      const double* v, const double* volume, const double* inv_density, std::int32_t n,
                      double* force, ContactTally& tally, const std::vector<NodeFriction>* given) {
  const PenaltyContact law{tool.stiffness, tool.friction};
  std::size_t next_given = 0;
  for (std::int32_t i = 0; i < n; ++i) {
    double p, nrm[3];
    const double xi[3] = {x[i], x[x_stride + i], tool.sphere ? x[2 * x_stride + i] : 0.0};
    if (!penetration(tool, time, xi, p, nrm)) continue;
    const double rho = 1.0 / inv_density[i];
    const double fn = law.normal(rho, p);  // normal force density
    tally.energy += law.energy(rho, p) * volume[i];
    tally.mass += rho * volume[i];
    double f[3] = {fn * nrm[0], fn * nrm[1], fn * nrm[2]};
    if (given) {
      while (next_given < given->size() && (*given)[next_given].node < i) ++next_given;
      if (next_given < given->size() && (*given)[next_given].node == i) {
        const NodeFriction& nf = (*given)[next_given];
        for (int c = 0; c < 3; ++c) f[c] += nf.force[c];
        tally.friction.push_back(nf);
      }
    } else if (tool.friction > 0) {
      // Velocity relative to the tool, and its part tangential to the surface.
      const double* vi = v + 3 * static_cast<std::size_t>(i);
      const double rel[3] = {vi[0] - tool.velocity[0], vi[1] - tool.velocity[1], vi[2] - tool.velocity[2]};
      const double vn = rel[0] * nrm[0] + rel[1] * nrm[1] + rel[2] * nrm[2];
      const double t[3] = {rel[0] - vn * nrm[0], rel[1] - vn * nrm[1], rel[2] - vn * nrm[2]};
      const double speed = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
      if (speed > 0) {
        const double ft = law.friction_force(fn, rho, speed, dt);
        NodeFriction nf{i, {-ft * t[0] / speed, -ft * t[1] / speed, -ft * t[2] / speed}};
        for (int c = 0; c < 3; ++c) f[c] += nf.force[c];
        tally.friction.push_back(nf);
      }
    }
    for (int c = 0; c < 3; ++c) {
      force[3 * static_cast<std::size_t>(i) + c] += f[c];
      tally.force[c] += f[c] * volume[i];
    }
    if (tally.per_node) tally.node_forces.push_back({i, {f[0] * volume[i], f[1] * volume[i], f[2] * volume[i]}});
    ++tally.nodes;
  }
}

double friction_work(const RigidCylinder& tool, const ContactTally& tally, double dt, const double* v,
                     const double* volume) {
  double work = 0;
  for (const NodeFriction& nf : tally.friction) {
    const double* vi = v + 3 * static_cast<std::size_t>(nf.node);
    const double rel[3] = {vi[0] - tool.velocity[0], vi[1] - tool.velocity[1], vi[2] - tool.velocity[2]};
    work += dt * volume[nf.node] * (nf.force[0] * rel[0] + nf.force[1] * rel[1] + nf.force[2] * rel[2]);
  }
  return work;
}

}  // namespace peri
