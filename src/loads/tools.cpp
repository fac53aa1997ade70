#include "peri/loads/tools.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <unordered_map>

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
    names_.push_back(t.name);
    stiffest_ = std::max(stiffest_, t.stiffness);
  }
  contact_.assign(tools_.size(), ContactTally{});
}

bool Tools::friction() const {
  return std::any_of(tools_.begin(), tools_.end(), [](const RigidTool& t) { return t.friction > 0; });
}

double Tools::stable_step(double dt_bound) const { return dt_bound / std::sqrt(1.0 + stiffest_); }

void Tools::add_forces(double t, const LoadTarget& target, bool book, EnergyLedger& ledger) {
  const VecArrayRead v(state_.velocity());
  for (std::size_t k = 0; k < tools_.size(); ++k) {
    const RigidTool& tool = tools_[k];
    ContactTally c;
    cylinder_contact(tool, t, target.dt, target.x, target.x_stride, v.data(), domain_.volume.data(),
                     inv_density_.data(), domain_.owned, target.force, c,
                     resumed_friction_ ? &(*resumed_friction_)[k] : nullptr);
    ledger.bonds.strain_energy += c.energy;
    // Work of the tool, whose motion is prescribed: F . V_tool, trapezoidal over the step.
    if (book)
      for (int d = 0; d < 3; ++d)
        ledger.external_work += 0.5 * target.dt * (contact_[k].force[d] + c.force[d]) * tool.velocity[d];
    contact_[k] = std::move(c);
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
    for (const char* c : {"_x", "_y", tools_[k].sphere ? "_z" : nullptr, "_force_x", "_force_y", "_force_z"})
      if (c) columns += (columns.empty() ? "" : ",") + names_[k] + c;
  return columns;
}

std::string Tools::series_values(double time, bool leading_comma) const {
  std::vector<double> local(3 * tools_.size()), total(3 * tools_.size());
  for (std::size_t k = 0; k < tools_.size(); ++k)
    for (int d = 0; d < 3; ++d) local[3 * k + d] = contact_[k].force[d];
  MPI_Allreduce(local.data(), total.data(), static_cast<int>(total.size()), MPI_DOUBLE, MPI_SUM, comm_);
  std::ostringstream values;
  values << std::setprecision(12);
  for (std::size_t k = 0; k < tools_.size(); ++k) {
    const RigidTool& t = tools_[k];
    values << (!leading_comma && k == 0 ? "" : ",") << t.center[0] + t.velocity[0] * time << ','
           << t.center[1] + t.velocity[1] * time << ',';
    if (t.sphere) values << t.center[2] + t.velocity[2] * time << ',';
    values << total[3 * k] << ',' << total[3 * k + 1] << ',' << total[3 * k + 2];
  }
  return values.str();
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
