#include "peri/diagnostics/health.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "peri/core/error.hpp"
#include "peri/core/format.hpp"

namespace peri {
HealthCheck::HealthCheck(const Scene& scene, const Domain& domain, const std::vector<BondLaw>& laws, MPI_Comm comm)
    : scene_(scene), domain_(domain), laws_(laws), comm_(comm) {
  for (const Body& body : scene.bodies) {
    const double limit = scene.stability.motion_per_step * body.spacing;
    motion_limit2_.push_back(limit > 0 ? limit * limit : INFINITY);
  }
  contact_ = pair_contact_steps(scene);
}

std::string HealthCheck::contact_note(double dt, double dt_stable) const {
  std::string out;
  for (const PairContactStep& c : contact_)
    if (c.exceeded_by(dt, dt_stable))
      out += "the contact of long_range.pairs." + std::to_string(c.rule) + " (its stiffness at the potential's zero " +
             "with the bonds' allows about " + number_text(c.with_bonds(dt_stable)) + " s: see the warning at setup), ";
  return out;
}

std::array<double, 3> HealthCheck::reference_position(std::int64_t natural) const {
  double local[3] = {0, 0, 0}, x[3];
  for (std::int32_t i = 0; i < domain_.owned; ++i)
    if (domain_.natural[i] == natural)
      for (int c = 0; c < 3; ++c) local[c] = domain_.X[3 * static_cast<std::size_t>(i) + c];
  MPI_Allreduce(local, x, 3, MPI_DOUBLE, MPI_SUM, comm_);  // one rank owns it
  return {x[0], x[1], x[2]};
}

void HealthCheck::check(std::int64_t step, double time, const double* u, const double* v, double dt,
                        double dt_stable) const {
  // Collective: first non-finite node (natural id), and the node that moved too far.
  long long bad = std::numeric_limits<long long>::max();
  for (std::int32_t i = 0; i < domain_.owned; ++i) {
    bool ok = true;
    for (int c = 0; c < 3; ++c) ok &= std::isfinite(u[3 * i + c]) && std::isfinite(v[3 * i + c]);
    if (!ok) bad = std::min<long long>(bad, domain_.natural[i]);
  }
  const long long none = std::numeric_limits<long long>::max();
  long long local[2] = {bad, unstable_node_ >= 0 ? unstable_node_ : none}, global[2];
  MPI_Allreduce(local, global, 2, MPI_LONG_LONG, MPI_MIN, comm_);
  const long long bad_global = global[0];
  if (global[1] != none && bad_global == none) {
    const long long node = global[1];
    double moved = node == unstable_node_ ? unstable_motion_ : 0, moved_max = 0;
    MPI_Allreduce(&moved, &moved_max, 1, MPI_DOUBLE, MPI_MAX, comm_);
    const std::array<double, 3> X = reference_position(node);
    const int body_any = body_of(node);
    std::ostringstream msg;
    msg << "unstable explicit integration detected by step " << step << " (t = " << number_text(time) << " s): node "
        << node << " at reference position (" << number_text(X[0]) << ", " << number_text(X[1]) << ", " << number_text(X[2])
        << ") moved " << number_text(moved_max) << " m in one step, more than stability.motion_per_step = "
        << number_text(scene_.stability.motion_per_step) << " of the grid spacing; likely cause: ";
    if (dt > dt_stable)
      msg << "the time step " << number_text(dt) << " s is above the stable bound " << number_text(dt_stable)
          << " s (accepted because of allow_unstable_dt)";
    else
      msg << contact_note(dt, dt_stable) << "the time step " << number_text(dt)
          << " s is too large for the current state (stable bound " << number_text(dt_stable)
          << " s at the reference state; " << law_note(body_any)
          << "), or a boundary velocity too violent for the resolution";
    msg << ". Positions and velocities are still finite; nothing non-finite was written";
    throw RuntimeFailure(msg.str());
  }
  if (bad_global != none) {
    const std::array<double, 3> X = reference_position(bad_global);
    const int body = body_of(bad_global);
    std::ostringstream msg;
    msg << "non-finite displacement or velocity at step " << step << " (t = " << number_text(time)
        << " s), node " << bad_global << " at reference position (" << number_text(X[0]) << ", " << number_text(X[1])
        << ", " << number_text(X[2]) << "); likely cause: ";
    if (dt > dt_stable)
      msg << "the time step " << number_text(dt) << " s is above the stable bound " << number_text(dt_stable)
          << " s (accepted because of allow_unstable_dt)";
    else
      msg << "the time step " << number_text(dt) << " s is too large for the current state (stable bound "
          << number_text(dt_stable) << " s at the reference state; " << law_note(body)
          << "), a material law that overflows at this state (its parameters), or a boundary velocity too violent "
             "for the resolution";
    throw RuntimeFailure(msg.str());
  }
}

void HealthCheck::check_energy(const EnergyRow& row, double error, double e0, double dt, double dt_stable,
                               bool run_end) {
  const double tolerance = scene_.stability.energy_error;
  if (!(tolerance > 0) || error <= tolerance) {
    energy_over_since_ = -1;
    return;
  }
  if (energy_over_since_ < 0) energy_over_since_ = row.step;
  // (At the run's last step the grace for transients has no steps left to show one.)
  if (row.step - energy_over_since_ < kEnergyErrorSteps && !run_end) return;
  std::ostringstream msg;
  msg << "energy balance error " << number_text(error) << " at step " << row.step << " (t = " << number_text(row.time)
      << " s" << (run_end ? ", the run's last" : "") << ") exceeds stability.energy_error = " << number_text(tolerance)
      << " since step " << energy_over_since_ << " (total energy " << number_text(row.total())
      << " J, " << number_text(e0) << " J at the start); likely cause: " << contact_note(dt, dt_stable)
      << tip_advance_note();
  if (dt > dt_stable)
    msg << "an unstable time step (dt = " << number_text(dt) << " s, above the stable bound " << number_text(dt_stable)
        << " s: accepted because of allow_unstable_dt)";
  else
    // Within the bound, velocity Verlet's own energy error (second order in dt) reaches a good part of
    // the energy of the highest modes, at the default safety factor; it matters where they hold much
    // of the energy: a free body of a few nodes released from a stretch errs by 16% (4 x 4 nodes).
    msg << "the explicit step's own error, second order in dt (with dt "
        << (std::isfinite(dt_stable) && dt_stable > 0 ? number_text(dt / dt_stable) + " of the stable bound, it" : "it")
        << " is large where much of the energy sits in the highest modes, as in a body of few nodes or after a "
        << "sudden load; halving safety_factor cuts it about fourfold), "
        << "an unstable time step (dt = " << number_text(dt) << " s, stable bound " << number_text(dt_stable)
        << " s at the reference state; " << law_note(-1) << ")";
  msg << ", or boundary motion too violent for the resolution";
  throw RuntimeFailure(msg.str());
}

void HealthCheck::restore(const std::vector<double>* saved) {
  energy_over_since_ = -1;
  if (saved && saved->size() == 1 && (*saved)[0] >= 0 && (*saved)[0] < 9.0e15 && (*saved)[0] == std::floor((*saved)[0]))
    energy_over_since_ = static_cast<std::int64_t>((*saved)[0]);
}

std::string HealthCheck::tip_advance_note() const {
  std::string materials;
  for (const Material& m : scene_.materials)
    if (m.tip_advance) materials += (materials.empty() ? "" : ", ") + m.name;
  if (materials.empty()) return "";
  return "the crack-tip rule (tip_advance of material " + materials +
         "): a bond held past its failure test breaks later with a jump in its force, which the explicit step books "
         "with an error of first order in dt (a smaller safety_factor lowers it), ";
}

int HealthCheck::body_of(long long node) const {
  int body = -1, body_any = -1;  // from the rank that owns the node
  for (std::int32_t i = 0; i < domain_.owned && body < 0; ++i)
    if (domain_.natural[i] == node) body = domain_.body[i];
  MPI_Allreduce(&body, &body_any, 1, MPI_INT, MPI_MAX, comm_);
  return body_any;
}

std::string HealthCheck::law_note(int body) const {
  // Each law once, with the bodies that use it (in the order first met).
  std::vector<std::pair<std::string, std::vector<std::string>>> laws;  // law name, bodies
  for (std::size_t b = 0; b < scene_.bodies.size(); ++b) {
    if (body >= 0 && static_cast<int>(b) != body) continue;
    const std::string name = laws_[b].empty() ? "marder" : laws_[b].name();  // (lattices: the lattice's own law)
    auto it = std::find_if(laws.begin(), laws.end(), [&](const auto& l) { return l.first == name; });
    if (it == laws.end()) it = laws.insert(laws.end(), {name, {}});
    it->second.push_back("'" + scene_.bodies[b].name + "'");
  }
  std::string out;
  for (const auto& [law, names] : laws) {
    std::string bodies = names[0];
    for (std::size_t k = 1; k < names.size(); ++k) bodies += ", " + names[k];
    if (!out.empty()) out += "; ";
    if (law == "marder")
      out += "the marder lattice law (body " + bodies +
             ") has its bound from the two- and three-body stiffness over the bond lengths it allows; a lattice "
             "driven beyond them (bonds compressed past the cutoff u_s, dashpots on fast motion) needs a smaller "
             "safety_factor";
    else
      out += "the " + law + " law (body " + bodies + ") " + find_law(law)->stability_note;
  }
  return out;
}

}  // namespace peri
