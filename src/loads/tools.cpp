#include "peri/loads/tools.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <unordered_map>

#include "peri/core/error.hpp"
#include "peri/core/petsc.hpp"

namespace peri {

Tools::Tools(const Scene& scene, double dt_bound, const State& state, const Domain& domain,
             const std::vector<double>& inv_density, MPI_Comm comm)
    : state_(state), domain_(domain), inv_density_(inv_density), comm_(comm) {
  for (const Tool& t : scene.tools) {
    RigidTool c;
    c.sphere = t.sphere;
    c.radius = t.radius;
    for (int d = 0; d < 3; ++d) {  // a cylinder's z components are 0
      c.center[d] = t.center[d];
      c.velocity[d] = t.velocity[d];
    }
    c.friction = t.friction;
    c.stiffness = t.stiffness * 2.0 / (dt_bound * dt_bound);
    tools_.push_back(c);
    mass_.push_back(t.mass);
    where_.push_back(t.where.str());
    names_.push_back(t.name);
    stiffest_ = std::max(stiffest_, t.stiffness);
  }
  contact_.assign(tools_.size(), ContactTally{});
  accel_.assign(tools_.size(), {0.0, 0.0, 0.0});
  reaction_.assign(tools_.size(), {0.0, 0.0, 0.0});
}

bool Tools::free() const {
  return std::any_of(mass_.begin(), mass_.end(), [](double m) { return m > 0; });
}

void Tools::reaction(std::size_t k, double out[3]) const {
  std::vector<double> local;
  local.reserve(4 * contact_[k].node_forces.size());
  for (const NodeFriction& nf : contact_[k].node_forces)
    local.insert(local.end(), {double(domain_.natural[nf.node]), nf.force[0], nf.force[1], nf.force[2]});
  int ranks = 1;
  MPI_Comm_size(comm_, &ranks);
  const int n = static_cast<int>(local.size());
  std::vector<int> counts(ranks), displs(ranks, 0);
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
  for (int r = 1; r < ranks; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(displs.back() + counts.back());
  MPI_Allgatherv(local.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, comm_);
  std::vector<std::size_t> order(all.size() / 4);
  for (std::size_t e = 0; e < order.size(); ++e) order[e] = e;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return all[4 * a] < all[4 * b]; });
  out[0] = out[1] = out[2] = 0.0;
  for (std::size_t e : order)
    for (int d = 0; d < 3; ++d) out[d] -= all[4 * e + 1 + d];
}

bool Tools::friction() const {
  return std::any_of(tools_.begin(), tools_.end(), [](const RigidTool& t) { return t.friction > 0; });
}

double Tools::stable_step(double dt_bound) const { return dt_bound / std::sqrt(1.0 + stiffest_); }

void Tools::add_forces(double t, const LoadTarget& target, bool book, EnergyLedger& ledger) {
  const VecArrayRead v(state_.velocity());
  const double dt = target.dt;
  for (std::size_t k = 0; k < tools_.size(); ++k) {
    RigidTool& tool = tools_[k];
    const bool free = mass_[k] > 0;
    double velocity_before[3] = {0, 0, 0};  // a free tool's velocity and reaction at the step's start
    const std::array<double, 3> reaction_before = reaction_[k];
    if (free) {
      // Velocity Verlet: half kick with the last acceleration and drift to t (a step), or just
      // the position at t (the forces at a stage's start or after a restart).
      if (book) {
        for (int d = 0; d < 3; ++d) velocity_before[d] = tool.velocity[d];
        for (int d = 0; d < 3; ++d) {
          tool.velocity[d] += 0.5 * dt * accel_[k][d];
          tool.center[d] += dt * tool.velocity[d];
        }
      }
      tool.t0 = t;
    }
    ContactTally c;
    c.per_node = true;  // (a free tool's motion and every tool's force in series.csv: summed in natural order)
    cylinder_contact(tool, t, dt, target.x, target.x_stride, v.data(), domain_.volume.data(),
                     inv_density_.data(), domain_.owned, target.force, c,
                     resumed_friction_ ? &(*resumed_friction_)[k] : nullptr);
    ledger.bonds.strain_energy += c.energy;
    if (!free) {
      // Work of the tool, whose motion is prescribed: F . V_tool, trapezoidal over the step.
      if (book)
        for (int d = 0; d < 3; ++d)
          ledger.external_work += 0.5 * dt * (contact_[k].force[d] + c.force[d]) * tool.velocity[d];
      contact_[k] = std::move(c);
      continue;
    }
    // The tool on the nodes' penalty springs: omega^2 = k m_contact / M; velocity Verlet needs
    // omega dt < 2, the bound the nodes' own step keeps for them.
    double contact_mass = 0;
    MPI_Allreduce(&c.mass, &contact_mass, 1, MPI_DOUBLE, MPI_SUM, comm_);
    if (tool.stiffness * contact_mass / mass_[k] * dt * dt >= 4.0) {
      std::ostringstream why;
      why << where_[k] << ": tools." << k << ".mass: " << mass_[k] << " kg is too light for the step: at t = "
          << t << " s the nodes in contact weigh " << contact_mass << " kg, and the tool on their penalty springs "
          << "needs a step below " << 2.0 * std::sqrt(mass_[k] / (tool.stiffness * contact_mass)) << " s (dt = " << dt
          << " s); give it at least the mass it touches, " << contact_mass
          << " kg (a lighter tool within this bound still beats against the nodes faster than their step "
             "follows: docs/theory/contact.md), or a smaller stiffness";
      throw RuntimeFailure(why.str());
    }
    contact_[k] = std::move(c);
    double r[3];
    reaction(k, r);
    if (!tool.sphere) r[2] = 0;  // a cylinder moves in the plane
    for (int d = 0; d < 3; ++d) {
      reaction_[k][d] = r[d];
      accel_[k][d] = r[d] / mass_[k];
    }
    if (book) {
      // Second half kick; the kinetic energy the tool lost is the work it did on the bodies (its
      // share of friction included: friction_work books the relative motion's loss). The two half
      // kicks give the impulse J = M (V1 - V0) = dt/2 (R0 + R1), and
      //   1/2 M (V0^2 - V1^2) = -J . (V0 + V1) / 2,
      // booked in that form: the difference of the two kinetic energies cancels to round-off for
      // a heavy tool (M V^2 eps against F V dt), whose velocity change is then below V's last digits.
      double work = 0;
      for (int d = 0; d < 3; ++d) {
        tool.velocity[d] += 0.5 * dt * accel_[k][d];
        work -= 0.5 * dt * (reaction_before[d] + reaction_[k][d]) * 0.5 * (velocity_before[d] + tool.velocity[d]);
      }
      // Booked on rank 0 only: the ledger is summed over the ranks.
      int rank = 0;
      MPI_Comm_rank(comm_, &rank);
      if (rank == 0) ledger.external_work += work;
    }
  }
  resumed_friction_.reset();
}

std::string Tools::touching() const {
  for (std::size_t k = 0; k < tools_.size(); ++k) {
    long long local = contact_[k].nodes, all = 0;
    MPI_Allreduce(&local, &all, 1, MPI_LONG_LONG, MPI_SUM, comm_);
    if (all > 0) return names_[k];
  }
  return "";
}

void Tools::end_step(double dt, const double* v, EnergyLedger& ledger) {
  for (std::size_t k = 0; k < tools_.size(); ++k)
    ledger.damping_work -= friction_work(tools_[k], contact_[k], dt, v, domain_.volume.data());
}

std::string Tools::series_columns() const {
  std::string columns;
  for (std::size_t k = 0; k < tools_.size(); ++k)  // a sphere's centre moves in z too
    for (const char* c : {"_x", "_y", tools_[k].sphere ? "_z" : nullptr, mass_[k] > 0 ? "_vx" : nullptr,
                          mass_[k] > 0 ? "_vy" : nullptr, mass_[k] > 0 && tools_[k].sphere ? "_vz" : nullptr,
                          "_force_x", "_force_y", "_force_z"})
      if (c) columns += (columns.empty() ? "" : ",") + names_[k] + c;
  return columns;
}

std::string Tools::series_values(double time, bool leading_comma) const {
  // The force on the body, summed over the nodes in natural order (reaction): the same bits on
  // any number of ranks (a reduction of the ranks' sums differed in the last bits).
  std::vector<double> total(3 * tools_.size());
  for (std::size_t k = 0; k < tools_.size(); ++k) {
    double on_tool[3];
    reaction(k, on_tool);
    for (int d = 0; d < 3; ++d) total[3 * k + d] = -on_tool[d];
  }
  std::ostringstream values;
  values << std::setprecision(12);
  for (std::size_t k = 0; k < tools_.size(); ++k) {
    const RigidTool& t = tools_[k];
    values << (!leading_comma && k == 0 ? "" : ",") << t.center[0] + t.velocity[0] * (time - t.t0) << ','
           << t.center[1] + t.velocity[1] * (time - t.t0) << ',';
    if (t.sphere) values << t.center[2] + t.velocity[2] * (time - t.t0) << ',';
    if (mass_[k] > 0) {  // a free tool's velocity
      values << t.velocity[0] << ',' << t.velocity[1] << ',';
      if (t.sphere) values << t.velocity[2] << ',';
    }
    values << total[3 * k] << ',' << total[3 * k + 1] << ',' << total[3 * k + 2];
  }
  return values.str();
}

std::vector<double> Tools::save_free() const {
  std::vector<double> flat;
  for (std::size_t k = 0; k < tools_.size(); ++k)
    if (mass_[k] > 0)
      for (const double* a : {tools_[k].center, tools_[k].velocity}) flat.insert(flat.end(), a, a + 3);
  return flat;
}

void Tools::restore_free(const std::vector<double>* flat) {
  if (!flat) return;
  std::size_t e = 0;
  for (std::size_t k = 0; k < tools_.size(); ++k)
    if (mass_[k] > 0 && e + 6 <= flat->size()) {
      for (int d = 0; d < 3; ++d) {
        tools_[k].center[d] = (*flat)[e + d];
        tools_[k].velocity[d] = (*flat)[e + 3 + d];
      }
      e += 6;
    }
}

std::vector<double> Tools::save_friction() const {
  std::vector<double> local;
  for (std::size_t k = 0; k < contact_.size(); ++k)
    for (const NodeFriction& nf : contact_[k].friction)
      local.insert(local.end(), {double(domain_.natural[nf.node]), double(k), nf.force[0], nf.force[1], nf.force[2]});
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm_, &rank);
  MPI_Comm_size(comm_, &ranks);
  const int n = static_cast<int>(local.size());
  std::vector<int> counts(ranks), displs(ranks, 0);
  MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_);
  for (int r = 1; r < ranks; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(rank == 0 ? displs.back() + counts.back() : 0);
  MPI_Gatherv(local.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, 0, comm_);
  return all;
}

void Tools::restore_friction(const std::vector<double>* flat) {
  if (!flat) return;
  std::unordered_map<std::int64_t, std::int32_t> local;
  for (std::int32_t i = 0; i < domain_.owned; ++i) local.emplace(domain_.natural[i], i);
  resumed_friction_.emplace(tools_.size());
  for (std::size_t e = 0; e + 5 <= flat->size(); e += 5) {
    const auto it = local.find(static_cast<std::int64_t>((*flat)[e]));
    const auto k = static_cast<std::size_t>((*flat)[e + 1]);
    if (it == local.end() || k >= tools_.size()) continue;
    (*resumed_friction_)[k].push_back({it->second, {(*flat)[e + 2], (*flat)[e + 3], (*flat)[e + 4]}});
  }
  for (auto& list : *resumed_friction_)
    std::sort(list.begin(), list.end(), [](const NodeFriction& a, const NodeFriction& b) { return a.node < b.node; });
}

}  // namespace peri
