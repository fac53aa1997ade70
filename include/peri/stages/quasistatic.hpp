// Quasi-static loader: static equilibrium (internal bond forces + support reactions = 0) of the
// owned degrees of freedom by PETSc SNES (Newton with line search), with load stepping on the
// prescribed boundary displacements. Owns its PETSc objects (SNES, tangent Mat, work Vecs).
//
// Unknowns: all 3 components of every owned node, in the global order of the ghosted State.
// Constrained components (prescribed boundary components; out-of-plane components of membranes
// when the stage is in_plane) are kept at their prescribed values: their residual rows are
// s (u - u_prescribed) and their tangent rows s e_k (s: a stiffness scale), so every Newton step
// and line search leaves them in place, with or without an assembled matrix.
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
  /// Add K = -d(F V)/du at the current displacement to `J` (global block indices; ADD_VALUES).
  virtual void add_tangent(Mat J) = 0;
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
};

/// Called after each converged increment (bonds broken and re-equilibrated): the stage's figures
/// so far (the increment is stats.increments.back(); external_work is this rank's share) and the
/// support reaction on each owned component (3 per owned node: the force the supports apply to
/// the body [N], 0 on free components). Collective calls are allowed: every rank calls it.
using IncrementObserver = std::function<void(const QuasiStaticStats& stats, const double* reaction)>;

class QuasiStaticLoader {
 public:
  /// `d_nnz`/`o_nnz`: per owned node, the number of block columns owned by this rank / by others
  /// (the row itself included in d_nnz). `stiffness_scale` [N/m]: typical diagonal of the tangent.
  QuasiStaticLoader(MPI_Comm comm, std::int32_t owned, const std::vector<PetscInt>& d_nnz,
                    const std::vector<PetscInt>& o_nnz, double stiffness_scale, double length_scale,
                    const Stage& stage);
  ~QuasiStaticLoader();
  QuasiStaticLoader(const QuasiStaticLoader&) = delete;
  QuasiStaticLoader& operator=(const QuasiStaticLoader&) = delete;

  /// Load from the model's current displacement to it plus `increment` on the constrained
  /// components (`constrained[k] != 0`); free components follow. Throws RuntimeFailure when an
  /// increment cannot converge within the stage's limits. `observer` (if set) sees every converged
  /// increment.
  QuasiStaticStats run(EquilibriumModel& model, const std::vector<std::uint8_t>& constrained,
                       const std::vector<double>& increment, bool verbose, const IncrementObserver& observer = {});

  /// The near null space of the tangent for the multigrid preconditioner: the rigid motions of
  /// nodes at `x` (3 per owned node), zero on the `constrained` components, orthonormalized.
  /// Collective; without it GAMG assumes a scalar problem.
  void set_near_null_space(const std::vector<double>& x, const std::vector<std::uint8_t>& constrained);
  int near_null_modes() const { return near_null_modes_; }

  /// Residual and Jacobian at the model's current state (tests: finite-difference checks).
  void residual(EquilibriumModel& model, const std::vector<double>& u, std::vector<double>& r);
  Mat jacobian(EquilibriumModel& model, const std::vector<double>& u);

 private:
  static PetscErrorCode form_function(SNES, Vec x, Vec f, void* ctx);
  static PetscErrorCode form_jacobian(SNES, Vec x, Mat J, Mat P, void* ctx);
  void eval_residual(const double* x, double* f);
  void eval_jacobian(const double* x, Mat J);
  /// jacobian: mf_operator: whether the assembled tangent (the preconditioner) is kept for the
  /// coming Newton iteration, from the last linear solve's iterations.
  bool reuse_tangent(KSP ksp);
  int solve(Vec x);  // SNESConvergedReason

  MPI_Comm comm_;
  int rank_ = 0;
  std::int32_t owned_ = 0;
  Stage stage_;
  double stiffness_ = 1, length_ = 1;
  OwnedVec x_, r_;
  OwnedMat J_;
  OwnedSNES snes_;  // destroyed first: it holds J_, r_
  CallbackError callback_error_;  // an exception of form_function / form_jacobian, rethrown by solve
  EquilibriumModel* model_ = nullptr;
  const std::vector<std::uint8_t>* constrained_ = nullptr;
  std::vector<double> target_, force_;  // prescribed values; internal force work array
  std::vector<PetscInt> constrained_rows_;  // global point indices of constrained components
  int near_null_modes_ = 0;
  double residual_seconds_ = 0, tangent_seconds_ = 0;  // in eval_residual, eval_jacobian
  long tangent_assemblies_ = 0;
  // jacobian: mf_operator: a tangent is held (cleared by a new stage and by broken bonds), and the
  // linear iterations of the first solve after it was assembled (-1: that solve is still to come).
  bool have_tangent_ = false;
  PetscInt fresh_iterations_ = -1;
  PetscInt max_linear_iterations_ = 20000;  // the Krylov limit with a fresh tangent
};

}  // namespace peri
