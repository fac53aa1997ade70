// A quasi-static stage of the run: the problem as the quasi-static loader sees it (its
// displacement, the force model's intact laws and tangent, its breaking pass), the loader sized
// for the problem's bonds, and the stage itself: the constrained components moved to their
// targets, the rest to equilibrium, then the body at rest.
#pragma once
#include <memory>
#include <vector>

#include "peri/diagnostics/energies.hpp"
#include "peri/stages/problem.hpp"
#include "peri/stages/quasistatic.hpp"

namespace peri {

/// The problem as an EquilibriumModel; the breaking pass books its breaks in the ledger.
class ProblemEquilibrium final : public EquilibriumModel {
 public:
  ProblemEquilibrium(Problem& p, EnergyLedger& ledger) : p_(p), ledger_(ledger) {}
  void set_displacement(const double* u_owned) override;
  void get_displacement(double* u_owned) override;
  void internal_force(double* f_owned) override;
  bool load_force(double* f_owned) override;
  void set_load_level(double level) override;
  std::string load_text(double level) const override;
  void add_tangent(Mat J, const DofLayout& layout) override;
  std::int64_t break_bonds() override;

 private:
  bool loaded() const;  // whether some load acts in quasi-static stages
  Problem& p_;
  EnergyLedger& ledger_;
  std::vector<double> load_force_;  // the loads' part of the last internal_force [N]
  bool ghosts_current_ = true;      // the ghosts' displacement is that of the last set_displacement
};

/// The unknowns of a loader: with `held` (3 per owned node: components held where they are),
/// the components that are not (nodes with all held have none; 2 per node where every node's
/// out-of-plane component is held); without, all 3 components of every owned node. Collective.
DofLayout dof_layout(const Problem& p, const std::vector<std::uint8_t>* held);

/// A loader for `stage`, sized for the problem's bonds (its stiffness scale the mean reference
/// stiffness of a row, its length scale the finest spacing), on dof_layout(p, held).
/// Collective.
std::unique_ptr<QuasiStaticLoader> make_loader(const Problem& p, const Stage& stage,
                                               const std::vector<std::uint8_t>* held = nullptr);

/// Runs quasi-static `stage` on `model` (the problem's): the boundaries' prescribed components
/// and, for an in-plane stage, the flat membranes' out-of-plane components are constrained; the
/// body ends at rest. This rank's support work goes to the ledger; the figures returned hold
/// the work of all ranks. `t`: the time of the stage (the loads' level 0 is their value then).
/// `observer` (if set) sees every converged increment. Collective.
QuasiStaticStats run_quasistatic(Problem& p, const Stage& stage, double t, EquilibriumModel& model,
                                 EnergyLedger& ledger, bool verbose, const IncrementObserver& observer = {});

}  // namespace peri
