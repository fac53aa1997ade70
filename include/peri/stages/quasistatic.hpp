// Quasi-static loader: static equilibrium (internal bond forces + support reactions = 0) of the
// owned degrees of freedom by PETSc SNES (Newton with line search), with load stepping on the
// prescribed boundary displacements. Owns its PETSc objects (SNES, tangent Mat, work Vecs).
//
// Unknowns (DofLayout): by default the components that are not prescribed. Nodes whose
// components are all prescribed (support bands) have none, and when every node's out-of-plane
// component is prescribed (flat membranes in an in_plane stage) each node has the two in-plane
// ones: block size 2, a tangent with 4/9 of the nonzeros of the 3-component one. Prescribed
// components of the nodes that keep unknowns (a roller holding one component) stay unknowns kept
// at their prescribed values: their residual rows are s (u - u_prescribed) and their tangent rows
// s e_k (s: a stiffness scale), so every Newton step and line search leaves them in place, with
// or without an assembled matrix. `prescribed: scaled_rows` keeps all 3 components of every node
// that way (the formulation before 2026-11-27).
//
// Bonds never break inside a Newton iteration: residuals and tangents use the intact laws. After
// each converged increment the model's breaking pass runs; if bonds broke, the same load is
// re-equilibrated (and checked again) before the next increment.
//
// Options: prefix "qs_": -qs_snes_*, -qs_ksp_*, -qs_pc_* (e.g. -qs_snes_monitor,
// -qs_snes_test_jacobian, -qs_ksp_type cg, -qs_pc_type gamg) pass straight to PETSc.
#pragma once
#include <mpi.h>
#include <petscmat.h>
#include <petscsnes.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "peri/core/petsc.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

/// The loader's unknowns: `components` per node that has any (3, or 2: x and y), in blocks.
struct DofLayout {
  int components = 3;
  std::vector<std::int32_t> nodes;  ///< owned nodes with unknowns, ascending
  /// Per local node (owned, then ghosts): the global block (node) index of its unknowns in the
  /// loader's vectors and tangent, -1 for a node without (PETSc ignores negative indices).
  std::vector<PetscInt> block;
  /// Per node of `nodes`: block columns of its tangent row owned here (itself included) and by
  /// other ranks (the matrix's preallocation).
  std::vector<PetscInt> d_nnz, o_nnz;
};

/// What the loader needs from the model of the run (implemented by Simulation).
class EquilibriumModel {
 public:
  virtual ~EquilibriumModel() = default;
  /// Make `u_owned` (3 per owned node) the current displacement and exchange halos. Collective.
  virtual void set_displacement(const double* u_owned) = 0;
  /// Current owned displacement.
  virtual void get_displacement(double* u_owned) = 0;
  /// Force (N, i.e. force density * measure) on each owned component at the current
  /// displacement: the bonds' with intact laws (no breaking), plus the loads that act in
  /// quasi-static stages (a balloon's pressure) at the current load level.
  virtual void internal_force(double* f_owned) = 0;
  /// Of the last internal_force, the loads' part (3 per owned node), from which the work they
  /// do is booked; false, with nothing written, when no load acts.
  virtual bool load_force(double* /*f_owned*/) { return false; }
  /// Make `level` in [0, 1] the loads' quasi-static level (set_quasistatic_level).
  virtual void set_load_level(double /*level*/) {}
  /// The loads at `level` in words, for messages (Load::quasistatic_text); empty if none.
  virtual std::string load_text(double /*level*/) const { return {}; }
  /// Add K = -d(F V)/du at the current displacement to `J` (ADD_VALUES): the rows and columns
  /// of the `layout`'s unknowns, in its block indices (the first `layout.components` components of
  /// each 3 x 3 node block).
  virtual void add_tangent(Mat J, const DofLayout& layout) = 0;
  /// Break the bonds that fail at the current displacement; returns the number broken on all
  /// ranks (bonds, not ordered bonds). Collective.
  virtual std::int64_t break_bonds() = 0;
};

/// One load increment, as printed and summarised.
struct LoadIncrement {
  double load_factor = 0;       ///< fraction of the stage's displacements reached
  int newton_iterations = 0;    ///< over all solves of the increment (re-equilibrations too)
  int linear_iterations = 0;
  int break_passes = 0;         ///< re-equilibrations after bonds broke
  std::int64_t broken = 0;      ///< bonds broken in this increment
  double residual = 0;          ///< final residual norm [N]
};

struct QuasiStaticStats {
  std::vector<LoadIncrement> increments;  ///< converged increments
  int cutbacks = 0;                       ///< diverged attempts (step halved)
  long newton_iterations = 0, linear_iterations = 0;
  std::int64_t broken = 0;
  double external_work = 0;  ///< this rank's share of the support reactions' work [J] (trapezoidal)
  double seconds = 0;
  double residual_seconds = 0;  ///< of which in residuals (internal forces)
  double tangent_seconds = 0;   ///< of which in tangents (assembly)
  long tangent_assemblies = 0;  ///< tangents assembled (jacobian: mf_operator reuses them across Newton iterations)
  int near_null_modes = 0;      ///< rigid motions given to the multigrid preconditioner
  long long unknowns = 0;       ///< the Newton system's size (all ranks)
  /// Energy scale of the prescribed moves: the stiffness scale times the sum of the squared
  /// prescribed increments (all ranks) [J]; the floor of the work error's denominator.
  double work_scale = 0;
};

/// Called after each converged increment (bonds broken and re-equilibrated): the stage's figures
/// so far (the increment is stats.increments.back(); external_work is this rank's share) and the
/// support reaction on each owned component (3 per owned node: the force the supports apply to
/// the body [N], 0 on free components). Collective calls are allowed: every rank calls it.
using IncrementObserver = std::function<void(const QuasiStaticStats& stats, const double* reaction)>;

class QuasiStaticLoader {
 public:
  /// `owned`: the model's owned nodes (3 components each); `layout`: the unknowns among them.
  /// `stiffness_scale` [N/m]: typical diagonal of the tangent.
  QuasiStaticLoader(MPI_Comm comm, std::int32_t owned, DofLayout layout, double stiffness_scale,
                    double length_scale, const Stage& stage);
  ~QuasiStaticLoader();
  QuasiStaticLoader(const QuasiStaticLoader&) = delete;
  /// Throws InputError, naming the stage, when PETSc refuses the -qs_* options (an unknown
  /// preconditioner type, a bad value). Collective; before anything is written.
  static void check_options(MPI_Comm comm, const Stage& stage);
  QuasiStaticLoader& operator=(const QuasiStaticLoader&) = delete;

  /// Load from the model's current displacement to it plus `increment` on the constrained
  /// components (`constrained[k] != 0`, 3 per owned node); free components follow. Every component
  /// that is no unknown of the layout must be constrained. Throws RuntimeFailure when an
  /// increment cannot converge within the stage's limits. `observer` (if set) sees every converged
  /// increment.
  QuasiStaticStats run(EquilibriumModel& model, const std::vector<std::uint8_t>& constrained,
                       const std::vector<double>& increment, bool verbose, const IncrementObserver& observer = {});

  /// The near null space of the tangent for the multigrid preconditioner: the rigid motions of
  /// nodes at `x` (3 per owned node) on the unknowns, zero on the `constrained` ones, orthonormalized.
  /// Collective; without it GAMG assumes a scalar problem.
  void set_near_null_space(const std::vector<double>& x, const std::vector<std::uint8_t>& constrained);
  int near_null_modes() const { return near_null_modes_; }

  /// Residual and Jacobian at `u` (3 per owned node) with nothing constrained (tests:
  /// finite-difference checks); the layout must hold every component of every owned node.
  void residual(EquilibriumModel& model, const std::vector<double>& u, std::vector<double>& r);
  Mat jacobian(EquilibriumModel& model, const std::vector<double>& u);

 private:
  static PetscErrorCode form_function(SNES, Vec x, Vec f, void* ctx);
  static PetscErrorCode form_jacobian(SNES, Vec x, Mat J, Mat P, void* ctx);
  static PetscErrorCode converged_or_stagnated(SNES, PetscInt it, PetscReal xnorm, PetscReal snorm, PetscReal fnorm,
                                               SNESConvergedReason* reason, void* ctx);
  std::string reason_text(int reason) const;  // SNESConvergedReasons, or the stagnation's
  /// Prescribed values (3 per owned node; components that are no unknowns take theirs in full_).
  void set_targets(const std::vector<double>& target);
  /// The model's displacement (3 per owned node) with the unknowns from `x` and the other
  /// components at their targets, in full_.
  void expand(const double* x);
  void eval_residual(const double* x, double* f);
  void eval_jacobian(const double* x, Mat J);
  /// jacobian: mf_operator: whether the assembled tangent (the preconditioner) is kept for the
  /// coming Newton iteration, from the last linear solve's iterations.
  bool reuse_tangent(KSP ksp);
  int solve(Vec x);  // SNESConvergedReason
  double residual_norm();  // |R(x_)|, into r_
  // The residual a solve PETSc calls converged left; RuntimeFailure where it is above the guard's.
  double check_converged(double load, int reason, double start_norm);

  MPI_Comm comm_;
  int rank_ = 0;
  std::int32_t owned_ = 0;
  DofLayout layout_;
  std::vector<std::size_t> dof_;  // per local unknown: its index among the 3 per owned node
  long long unknowns_ = 0;        // all ranks
  Stage stage_;
  double stiffness_ = 1, length_ = 1;
  OwnedVec x_, r_;
  OwnedMat J_;
  OwnedSNES snes_;  // destroyed first: it holds J_, r_
  CallbackError callback_error_;  // an exception of form_function / form_jacobian, rethrown by solve
  EquilibriumModel* model_ = nullptr;
  const std::vector<std::uint8_t>* constrained_ = nullptr;
  std::vector<double> target_, force_, full_;  // prescribed values; internal force; displacement (3 per node)
  std::vector<PetscInt> constrained_rows_;  // global point indices of constrained components
  int near_null_modes_ = 0;
  double residual_seconds_ = 0, tangent_seconds_ = 0;  // in eval_residual, eval_jacobian
  long tangent_assemblies_ = 0;
  // jacobian: mf_operator: a tangent is held (cleared by a new stage and by broken bonds), and the
  // linear iterations of the first solve after it was assembled (-1: that solve is still to come).
  bool have_tangent_ = false;
  bool reuse_allowed_ = true;  // cleared for the rest of a stage by a failed solve that kept a tangent
  bool reused_ = false;        // the last solve kept a tangent for some Newton iteration
  bool stagnated_ = false;     // the last solve stopped by converged_or_stagnated
  bool stagnation_test_ = true;  // converged_or_stagnated may stop a solve (not after bonds broke)
  std::vector<PetscReal> norms_;  // the residual norms of the current solve's Newton iterations
  PetscInt fresh_iterations_ = -1;
  PetscInt max_linear_iterations_ = 1000;  // the Krylov limit with a fresh tangent
};

}  // namespace peri
