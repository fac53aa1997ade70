#include "peri/stages/quasistatic.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "peri/core/error.hpp"
#include "peri/io/restart.hpp"

namespace peri {
namespace {

std::string fmt(double v, int digits = 4) {
  std::ostringstream s;
  s.precision(digits);
  s << v;
  return s.str();
}

}  // namespace

QuasiStaticLoader::QuasiStaticLoader(MPI_Comm comm, std::int32_t owned, DofLayout layout, double stiffness_scale,
                                     double length_scale, const Stage& stage)
    : comm_(comm), owned_(owned), layout_(std::move(layout)), stage_(stage),
      stiffness_(stiffness_scale > 0 ? stiffness_scale : 1.0), length_(length_scale) {
  MPI_Comm_rank(comm_, &rank_);
  const int bs = layout_.components;
  if ((bs != 2 && bs != 3) || layout_.d_nnz.size() != layout_.nodes.size() ||
      layout_.o_nnz.size() != layout_.nodes.size() || layout_.block.size() < static_cast<std::size_t>(owned))
    throw Error("QuasiStaticLoader: inconsistent unknowns layout");
  for (const std::int32_t i : layout_.nodes)
    for (int c = 0; c < bs; ++c) dof_.push_back(3 * static_cast<std::size_t>(i) + c);
  const PetscInt n = static_cast<PetscInt>(dof_.size());
  PERI_PETSC(VecCreateMPI(comm_, n, PETSC_DETERMINE, x_.out()));
  PERI_PETSC(VecSetBlockSize(x_, bs));
  PetscInt size;
  PERI_PETSC(VecGetSize(x_, &size));
  unknowns_ = size;
  PERI_PETSC(VecDuplicate(x_, r_.out()));
  PERI_PETSC(SNESCreate(comm_, snes_.out()));
  PERI_PETSC(SNESSetOptionsPrefix(snes_, "qs_"));
  PERI_PETSC(SNESSetFunction(snes_, r_, &QuasiStaticLoader::form_function, this));
  if (stage_.jacobian == Stage::Jacobian::MatrixFree) {
    PERI_PETSC(SNESSetUseMatrixFree(snes_, PETSC_FALSE, PETSC_TRUE));
  } else {
    // AIJ with the unknowns' block size, which algebraic multigrid (the default preconditioner)
    // needs; -qs_mat_type baij for block preconditioners.
    PERI_PETSC(MatCreate(comm_, J_.out()));
    PERI_PETSC(MatSetSizes(J_, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
    PERI_PETSC(MatSetBlockSize(J_, bs));
    PERI_PETSC(MatSetType(J_, MATAIJ));
    PERI_PETSC(MatSetOptionsPrefix(J_, "qs_"));
    PERI_PETSC(MatSetFromOptions(J_));
    {
      // The tangent is preallocated row by row (MatXAIJSetPreallocation): AIJ and BAIJ only. Any
      // other -qs_mat_type (dense: an unallocated matrix, a segmentation fault in the assembly)
      // is refused here, at setup.
      MatType type;
      PERI_PETSC(MatGetType(J_, &type));
      const std::string t = type ? type : "";
      if (t != MATAIJ && t != MATSEQAIJ && t != MATMPIAIJ && t != MATBAIJ && t != MATSEQBAIJ && t != MATMPIBAIJ)
        throw InputError(stage_.where.str() + ": quasi-static stage '" + stage_.name + "': -qs_mat_type " + t +
                         ": expected aij or baij (the assembled tangent is sparse, preallocated per row; "
                         "docs/user/quasistatic.md#solver-options)");
    }
    PERI_PETSC(MatXAIJSetPreallocation(J_, bs, layout_.d_nnz.data(), layout_.o_nnz.data(), nullptr, nullptr));
    PERI_PETSC(MatSetOption(J_, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
    PERI_PETSC(MatSetOption(J_, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
    PERI_PETSC(SNESSetJacobian(snes_, J_, J_, &QuasiStaticLoader::form_jacobian, this));
    // The operator as differences of the residual (one residual, a bond loop, per product) and
    // the assembled tangent as the preconditioner's matrix only: on example 7.1's sheet (25.6k
    // nodes) a Krylov product through the assembled tangent (about 400 nonzeros per row) cost
    // seven times a residual, and the tangent's assembly and the multigrid set-up at every
    // Newton iteration half of the preload (docs/user/quasistatic.md).
    if (stage_.jacobian == Stage::Jacobian::MfOperator) {
      PERI_PETSC(SNESSetUseMatrixFree(snes_, PETSC_TRUE, PETSC_FALSE));
      PERI_PETSC(SNESSetMaxLinearSolveFailures(snes_, 1000000));
    }
  }
  // Defaults (any -qs_snes_* option overrides): an absolute residual of 1e-10 of a node's
  // stiffness times its spacing, 1e-9 relative, at most 50 Newton iterations per solve.
  PERI_PETSC(SNESSetTolerances(snes_, 1e-10 * stiffness_ * length_, 1e-9, 1e-12, 50, -1));
  // PETSc's tests, and a stagnation test (converged_or_stagnated); -qs_snes_convergence_test
  // overrides both.
  PERI_PETSC(SNESSetConvergenceTest(snes_, &QuasiStaticLoader::converged_or_stagnated, this, nullptr));
  KSP ksp;
  PERI_PETSC(SNESGetKSP(snes_, &ksp));
  // At most 1000 Krylov iterations per Newton step (-qs_ksp_max_it): the multigrid needs 10 to 60
  // where it works, and an unfinished direction still goes to the line search
  // (SNESSetMaxLinearSolveFailures); a tangent that stalls GMRES (a sheet just torn) cost up to
  // 20000 iterations per step with a larger limit.
  PERI_PETSC(KSPSetTolerances(ksp, 1e-6, PETSC_DEFAULT, PETSC_DEFAULT, 1000));
  if (stage_.jacobian != Stage::Jacobian::MatrixFree) {
    // Smoothed-aggregation algebraic multigrid on the assembled tangent, with the bodies' rigid
    // motions as its near null space (set_near_null_space): linear iterations per Newton step
    // that do not grow with the node count. The tangent couples every node to its whole family
    // (~30 neighbours), so the graph is not squared and each level smooths once: measured on
    // example 7.1's sheet, 21 and 101 s to preload 25k and 102k nodes against 30 and 136 s with
    // GAMG's defaults and 50 and 516 s with block Jacobi (docs/user/quasistatic.md). Any -qs_pc_*
    // or -qs_mg_levels_* option overrides these.
    PC pc;
    PERI_PETSC(KSPGetPC(ksp, &pc));
    PERI_PETSC(PCSetType(pc, PCGAMG));
    const std::pair<const char*, const char*> defaults[] = {{"-qs_pc_gamg_square_graph", "0"},
                                                            {"-qs_mg_levels_ksp_max_it", "1"}};
    for (const auto& [name, value] : defaults) {
      PetscBool given = PETSC_FALSE;
      PERI_PETSC(PetscOptionsHasName(nullptr, nullptr, name, &given));
      if (!given) PERI_PETSC(PetscOptionsSetValue(nullptr, name, value));
    }
  }
  // A -qs_* option PETSc refuses (an unknown type, a bad value) is the user's input: one message.
  PERI_PETSC(PetscPushErrorHandler(PetscIgnoreErrorHandler, nullptr));
  const PetscErrorCode refused = SNESSetFromOptions(snes_);
  PERI_PETSC(PetscPopErrorHandler());
  if (refused) {
    const char* text = nullptr;
    char* specific = nullptr;
    PetscErrorMessage(refused, &text, &specific);
    throw InputError(stage_.where.str() + ": quasi-static stage '" + stage_.name +
                     "': PETSc refused the solver's -qs_* options: " + (specific && *specific ? specific : text ? text : "") +
                     " (docs/user/quasistatic.md#solver-options)");
  }
  PERI_PETSC(KSPGetTolerances(ksp, nullptr, nullptr, nullptr, &max_linear_iterations_));  // -qs_ksp_max_it
}

QuasiStaticLoader::~QuasiStaticLoader() = default;

void QuasiStaticLoader::check_options(MPI_Comm comm, const Stage& stage) {
  const QuasiStaticLoader probe(comm, 0, DofLayout{}, 1.0, 1.0, stage);  // (its constructor reads them)
}

void QuasiStaticLoader::set_near_null_space(const std::vector<double>& x, const std::vector<std::uint8_t>& constrained) {
  if (!J_) return;
  // Centre and size of the nodes (all ranks), so that the rotations are well scaled.
  double local[4] = {0, 0, 0, static_cast<double>(layout_.nodes.size())}, sum[4];
  for (const std::int32_t i : layout_.nodes)
    for (int c = 0; c < 3; ++c) local[c] += x[3 * static_cast<std::size_t>(i) + c];
  MPI_Allreduce(local, sum, 4, MPI_DOUBLE, MPI_SUM, comm_);
  const double count = std::max(sum[3], 1.0), centre[3] = {sum[0] / count, sum[1] / count, sum[2] / count};
  double reach = 0, all_reach = 0;
  for (const std::int32_t i : layout_.nodes)
    for (int c = 0; c < 3; ++c) reach = std::max(reach, std::fabs(x[3 * static_cast<std::size_t>(i) + c] - centre[c]));
  MPI_Allreduce(&reach, &all_reach, 1, MPI_DOUBLE, MPI_MAX, comm_);
  const double scale = all_reach > 0 ? 1.0 / all_reach : 1.0;
  // The six rigid motions on the unknowns, zero on the constrained ones (whose rows hold them in
  // place): for a flat sheet held out of its plane the three in-plane ones remain. A motion that the
  // constraints leave only a trace of (a rotation out of the plane of a sheet with a small
  // out-of-plane seed: 1e-4 of a translation) is no near null vector and is dropped.
  std::vector<OwnedVec> raw(6);
  std::vector<PetscReal> size(6);
  PetscReal largest = 0;
  for (int m = 0; m < 6; ++m) {
    PERI_PETSC(VecDuplicate(x_, raw[m].out()));
    {
      VecArray a(raw[m]);
      const int bs = layout_.components;
      for (std::size_t node = 0; node < layout_.nodes.size(); ++node) {
        const std::size_t i = static_cast<std::size_t>(layout_.nodes[node]);
        const double r[3] = {(x[3 * i] - centre[0]) * scale, (x[3 * i + 1] - centre[1]) * scale,
                             (x[3 * i + 2] - centre[2]) * scale};
        double u[3] = {0, 0, 0};
        if (m < 3) {
          u[m] = 1;
        } else {  // rotation about axis m - 3: e_axis x r
          const int a0 = m - 3, a1 = (a0 + 1) % 3, a2 = (a0 + 2) % 3;
          u[a1] = -r[a2];
          u[a2] = r[a1];
        }
        for (int c = 0; c < bs; ++c) a[bs * node + c] = constrained[3 * i + c] ? 0.0 : u[c];
      }
    }
    PERI_PETSC(VecNorm(raw[m], NORM_2, &size[m]));
    largest = std::max(largest, size[m]);
  }
  std::vector<OwnedVec> modes;
  for (int m = 0; m < 6; ++m) {
    if (!(size[m] > 1e-3 * largest)) continue;
    OwnedVec v = std::move(raw[m]);
    for (int pass = 0; pass < 2; ++pass)  // orthonormal to the modes kept (Gram-Schmidt, twice)
      for (const OwnedVec& w : modes) {
        PetscScalar d;
        PERI_PETSC(VecDot(v, w, &d));
        PERI_PETSC(VecAXPY(v, -d, w));
      }
    PetscReal after;
    PERI_PETSC(VecNorm(v, NORM_2, &after));
    if (after < 1e-8 * size[m]) continue;  // dependent on the modes before
    PERI_PETSC(VecScale(v, 1.0 / after));
    modes.push_back(std::move(v));
  }
  near_null_modes_ = static_cast<int>(modes.size());
  // No unknown free (every component prescribed: the tangent is the scaled rows' diagonal): no
  // near null space; GAMG fails on an empty one.
  if (modes.empty()) return;
  std::vector<Vec> vecs;
  for (const OwnedVec& v : modes) vecs.push_back(v);
  OwnedNullSpace space;
  PERI_PETSC(MatNullSpaceCreate(comm_, PETSC_FALSE, static_cast<PetscInt>(vecs.size()), vecs.data(), space.out()));
  PERI_PETSC(MatSetNearNullSpace(J_, space));
  // Nothing held (a balloon under pressure alone): the rigid motions are the tangent's null
  // space, not only near it; the Krylov solver then keeps them out of the Newton steps.
  long held = std::count(constrained.begin(), constrained.end(), std::uint8_t{1}), all_held = 0;
  MPI_Allreduce(&held, &all_held, 1, MPI_LONG, MPI_SUM, comm_);
  if (all_held == 0) PERI_PETSC(MatSetNullSpace(J_, space));
}

void QuasiStaticLoader::set_targets(const std::vector<double>& target) {
  target_ = target;
  full_ = target_;  // the components that are no unknowns are constrained: at their targets
}

void QuasiStaticLoader::expand(const double* x) {
  for (std::size_t k = 0; k < dof_.size(); ++k) full_[dof_[k]] = x[k];
}

void QuasiStaticLoader::eval_residual(const double* x, double* f) {
  const auto t0 = std::chrono::steady_clock::now();
  expand(x);
  model_->set_displacement(full_.data());
  force_.resize(full_.size());
  model_->internal_force(force_.data());
  const std::vector<std::uint8_t>& fixed = *constrained_;
  for (std::size_t k = 0; k < dof_.size(); ++k) {
    const std::size_t d = dof_[k];
    f[k] = fixed[d] ? stiffness_ * (x[k] - target_[d]) : -force_[d];
  }
  residual_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void QuasiStaticLoader::eval_jacobian(const double* x, Mat J) {
  const auto t0 = std::chrono::steady_clock::now();
  expand(x);
  model_->set_displacement(full_.data());
  PERI_PETSC(MatZeroEntries(J));
  model_->add_tangent(J, layout_);
  PERI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  PERI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  // Regularization of the tangent only (the residual is untouched, so the converged state is the
  // exact equilibrium): a flat membrane has no out-of-plane stiffness at zero in-plane tension.
  if (stage_.jacobian_shift > 0) PERI_PETSC(MatShift(J, stage_.jacobian_shift * stiffness_));
  PERI_PETSC(MatZeroRows(J, static_cast<PetscInt>(constrained_rows_.size()), constrained_rows_.data(), stiffness_,
                         nullptr, nullptr));
  ++tangent_assemblies_;
  tangent_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

PetscErrorCode QuasiStaticLoader::converged_or_stagnated(SNES snes, PetscInt it, PetscReal xnorm, PetscReal snorm,
                                                         PetscReal fnorm, SNESConvergedReason* reason, void* ctx) {
  auto* self = static_cast<QuasiStaticLoader*>(ctx);
  if (const PetscErrorCode e = SNESConvergedDefault(snes, it, xnorm, snorm, fnorm, reason, nullptr)) return e;
  if (it == 0) self->norms_.clear();
  self->norms_.push_back(fnorm);
  // Newton that takes line-search steps of a few percent without end: past a limit point of the
  // loading (a balloon's pressure beyond its maximum) it creeps towards the least residual, not
  // to zero. Measured on example 7.2's balloon at 6 mm and 6 MPa: |R| from 986.372 to 986.355
  // over 40 iterations of up to 1000 Krylov products each, in an increment that cannot
  // converge. Less than a tenth gained over the last 5 iterations (after 8), or less than a
  // thousandth over the last 3 (after 4: the same balloon's failed increments hold |R| to 6
  // digits from the third), is taken as divergence: the step is halved as for any
  // other. Not while bonds broke at the load (stagnation_test_): a failure there ends the stage.
  const std::size_t n = self->norms_.size();
  const auto gained_less = [&](std::size_t back, double ratio) {
    return n > back && !(fnorm < ratio * self->norms_[n - 1 - back]);
  };
  if (*reason == SNES_CONVERGED_ITERATING && self->stagnation_test_ &&
      ((it >= 8 && gained_less(5, 0.9)) || (it >= 4 && gained_less(3, 0.999)))) {
    self->stagnated_ = true;
    *reason = SNES_DIVERGED_LOCAL_MIN;
  }
  return 0;
}

std::string QuasiStaticLoader::reason_text(int reason) const {
  if (stagnated_) return "Newton stagnated: |R| fell less than 10% over 5 iterations or 0.1% over 3";
  return SNESConvergedReasons[reason];
}

PetscErrorCode QuasiStaticLoader::form_function(SNES, Vec x, Vec f, void* ctx) {
  auto* self = static_cast<QuasiStaticLoader*>(ctx);
  return self->callback_error_.run([&] {
    const VecArrayRead xa(x);
    const VecArray fa(f);
    self->eval_residual(xa.data(), fa.data());
  });
}

PetscErrorCode QuasiStaticLoader::form_jacobian(SNES, Vec x, Mat A, Mat P, void* ctx) {
  auto* self = static_cast<QuasiStaticLoader*>(ctx);
  return self->callback_error_.run([&] {
    const VecArrayRead xa(x);
    // The assembled tangent is the preconditioner's matrix; the operator is the same matrix, or
    // a matrix-free one (jacobian: mf_operator), which only needs to learn the new base point.
    KSP ksp;
    PERI_PETSC(SNESGetKSP(self->snes_, &ksp));
    const bool reuse = A != P && self->reuse_allowed_ && self->reuse_tangent(ksp);
    self->reused_ = self->reused_ || reuse;
    PERI_PETSC(KSPSetReusePreconditioner(ksp, reuse ? PETSC_TRUE : PETSC_FALSE));
    // A kept tangent gets the iterations that would have it reassembled, no more: a tangent far
    // from the current one (the first Newton step of a large increment) can stall the Krylov
    // solver for thousands of iterations. The unfinished direction still goes to the line
    // search (SNESSetMaxLinearSolveFailures), and the next iteration assembles anew.
    PERI_PETSC(KSPSetTolerances(ksp, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT,
                                reuse ? 2 * self->fresh_iterations_ + 3 : self->max_linear_iterations_));
    if (!reuse) self->eval_jacobian(xa.data(), P);
    if (A != P) {
      PERI_PETSC(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
      PERI_PETSC(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
    }
  });
}

bool QuasiStaticLoader::reuse_tangent(KSP ksp) {
  PetscInt last = 0;
  KSPConvergedReason reason;
  PERI_PETSC(KSPGetIterationNumber(ksp, &last));
  PERI_PETSC(KSPGetConvergedReason(ksp, &reason));
  if (have_tangent_ && fresh_iterations_ < 0) fresh_iterations_ = last;  // the solve after an assembly
  // Keep the tangent while the solves it preconditions converge within twice the first one's
  // iterations (+2: small counts vary by one or two); bonds that broke since clear it (run). A
  // tangent whose first solve did not converge is no yardstick: assemble anew.
  if (have_tangent_ && reason > 0 && last <= 2 * fresh_iterations_ + 2) return true;
  have_tangent_ = true;
  fresh_iterations_ = -1;
  return false;
}

double QuasiStaticLoader::residual_norm() {
  PERI_PETSC(PetscPushErrorHandler(PetscIgnoreErrorHandler, nullptr));
  const PetscErrorCode error = SNESComputeFunction(snes_, x_, r_);
  PERI_PETSC(PetscPopErrorHandler());
  callback_error_.rethrow();  // (an exception in the residual: its own message)
  PERI_PETSC(error);
  PetscReal norm;
  PERI_PETSC(VecNorm(r_, NORM_2, &norm));
  return norm;
}

double QuasiStaticLoader::check_converged(double load, int reason, double start_norm) {
  // PETSc's verdict is taken only where the residual is small: 1e-6 of the increment's starting
  // residual or of a node's force scale (the default tolerances reach 1e-9 and 1e-10 of them),
  // so that options that stop Newton early (-qs_snes_atol 1e10, -qs_snes_type ksponly on a
  // nonlinear step) cannot pass a state that is not in equilibrium.
  const double norm = residual_norm(), allowed = std::max(1e-6 * start_norm, 1e-6 * stiffness_ * length_);
  if (!(norm <= allowed)) {
    std::ostringstream msg;
    msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "': at load factor " << fmt(load)
        << " PETSc reported convergence (" << SNESConvergedReasons[reason] << ") with a residual of " << fmt(norm)
        << " N, more than " << fmt(allowed) << " N (1e-6 of the increment's starting residual " << fmt(start_norm)
        << " N or of a node's force scale): not an equilibrium; likely cause: -qs_* options that stop Newton "
           "early (docs/user/quasistatic.md#solver-options)";
    throw RuntimeFailure(msg.str());
  }
  return norm;
}

int QuasiStaticLoader::solve(Vec x) {
  // An exception in a callback comes back as an error code through SNESSolve: PETSc's handler
  // stays quiet meanwhile, and the exception itself (its message) is rethrown here.
  reused_ = false;
  stagnated_ = false;
  PERI_PETSC(PetscPushErrorHandler(PetscIgnoreErrorHandler, nullptr));
  const PetscErrorCode error = SNESSolve(snes_, nullptr, x);
  PERI_PETSC(PetscPopErrorHandler());
  callback_error_.rethrow();
  if (error) {
    // PETSc's own failure in the solve (a preconditioner or factorization that this build or this
    // number of ranks cannot set up, chosen by -qs_* options): the stage fails with PETSc's words.
    const char* text = nullptr;
    char* specific = nullptr;
    PetscErrorMessage(error, &text, &specific);
    throw RuntimeFailure(stage_.where.str() + ": quasi-static stage '" + stage_.name + "': PETSc failed in the " +
                         "solve: " + (specific && *specific ? specific : text ? text : "unknown error") +
                         "; where -qs_* options choose the solver, they are the likely cause "
                         "(docs/user/quasistatic.md#solver-options)");
  }
  SNESConvergedReason reason;
  PERI_PETSC(SNESGetConvergedReason(snes_, &reason));
  return static_cast<int>(reason);
}

QuasiStaticStats QuasiStaticLoader::run(EquilibriumModel& model, const std::vector<std::uint8_t>& constrained,
                                        const std::vector<double>& increment, bool verbose,
                                        const IncrementObserver& observer) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = 3 * static_cast<std::size_t>(owned_);
  model_ = &model;
  constrained_ = &constrained;
  have_tangent_ = false;
  reuse_allowed_ = true;
  {
    std::vector<std::uint8_t> unknown(n, 0);
    for (const std::size_t d : dof_) unknown[d] = 1;
    for (std::size_t k = 0; k < n; ++k)
      if (!unknown[k] && !constrained[k])
        throw Error("QuasiStaticLoader::run: a free component (node " + std::to_string(k / 3) + ", component " +
                    std::to_string(k % 3) + ") is no unknown of the layout");
  }
  PetscInt rstart;
  PERI_PETSC(VecGetOwnershipRange(x_, &rstart, nullptr));
  constrained_rows_.clear();
  for (std::size_t k = 0; k < dof_.size(); ++k)
    if (constrained[dof_[k]]) constrained_rows_.push_back(rstart + static_cast<PetscInt>(k));

  std::vector<double> u0(n), u_conv(n), u_prev(n), reaction(n, 0.0), reaction_new(n), f(n);
  model.get_displacement(u0.data());
  u_conv = u0;
  // The supports' forces on the body (constrained components) and the loads' (all components).
  std::vector<double> load_force(n, 0.0), load_force_new(n, 0.0);
  auto reactions = [&](const double* u, std::vector<double>& out, std::vector<double>& loads) {
    model.set_displacement(u);
    model.internal_force(f.data());
    for (std::size_t k = 0; k < n; ++k) out[k] = constrained[k] ? -f[k] : 0.0;
    model.load_force(loads.data());
  };
  model.set_load_level(0.0);
  reactions(u0.data(), reaction, load_force);

  QuasiStaticStats stats;
  double load = 0, load_prev = -1;
  double step = std::min(1.0 / static_cast<double>(stage_.load_steps), stage_.max_load_step);
  long attempts = 0;
  std::vector<double> target(n, 0.0), predicted(n);
  while (load < 1.0) {
    // A stop signal (SIGTERM, SIGINT) on any rank ends the stage between solves, all ranks
    // together: the stage has no checkpoint part-way, and a scheduler's SIGKILL follows soon.
    {
      int mine = stop_signal(), any = 0;
      MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, comm_);
      if (any != 0) {
        std::ostringstream msg;
        msg << "stopped by signal " << any << " in quasi-static stage '" << stage_.name << "' at load factor "
            << fmt(load) << " (" << stats.increments.size() << " increments converged); a quasi-static stage is "
            << "not checkpointed part-way: resume from a checkpoint written before it, or run again";
        throw StopRequested(msg.str());
      }
    }
    if (++attempts > stage_.max_load_steps) {
      std::ostringstream msg;
      msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "' reached load factor " << fmt(load)
          << " after " << stage_.max_load_steps << " increments (max_load_steps, cut-backs included); "
          << "likely cause: a limit point (snap-through, or fracture that the loading cannot hold) or "
             "too tight solver tolerances; try more load_steps or a dynamic stage";
      throw RuntimeFailure(msg.str());
    }
    const double next = std::min(1.0, load + step);
    // Predictor: after a converged increment, constrained components at their prescribed values
    // and free ones extrapolated along it (secant). Before any, everything where it is: the
    // first Newton step is then the tangent predictor (the prescribed move's linear response at
    // equilibrium); starting from the supports' jump with the free nodes left behind took the
    // 102k-node sheet of docs/user/quasistatic.md 21 Newton iterations (13 line-search cuts) where
    // this takes 3.
    {
      const double ratio = load_prev >= 0 ? (next - load) / (load - load_prev) : 0.0;
      for (std::size_t k = 0; k < n; ++k) {
        target[k] = constrained[k] ? u0[k] + next * increment[k] : 0.0;
        predicted[k] =
            constrained[k] ? (load_prev >= 0 ? target[k] : u_conv[k]) : u_conv[k] + ratio * (u_conv[k] - u_prev[k]);
      }
      set_targets(target);
      const VecArray x(x_);
      for (std::size_t k = 0; k < dof_.size(); ++k) x[k] = predicted[dof_[k]];
    }
    LoadIncrement inc;
    inc.load_factor = next;
    model.set_load_level(next);
    const double start_norm = residual_norm();  // (the predictor's: the guard below)
    stagnation_test_ = true;
    int reason = solve(x_);
    // The converged state's residual, computed by the stage (some -qs_snes_type, ksponly, report
    // none): checked, and the increment's figure.
    double residual = reason > 0 ? check_converged(next, reason, start_norm) : 0.0;
    PetscInt its, lits;
    PERI_PETSC(SNESGetIterationNumber(snes_, &its));
    PERI_PETSC(SNESGetLinearSolveIterations(snes_, &lits));
    stats.newton_iterations += its;
    stats.linear_iterations += lits;
    if (reason <= 0 && reused_) {
      // A kept tangent preconditions GMRES by its own (left-preconditioned) residual: where it is
      // far from the current one, a direction that GMRES calls converged can leave most of the
      // Newton system's true residual, and the line search stalls. Measured on the free balloon
      // of docs/user/quasistatic.md at 6 MPa: every cut-back stalled again, down to a load step
      // of 1e-9, where a tangent assembled at every Newton iteration reaches the full load in 8
      // increments. So the same increment is tried again, and the rest of the stage assembles
      // the tangent at every Newton iteration.
      reuse_allowed_ = false;
      if (verbose && rank_ == 0) {
        std::printf("[peridrive] quasistatic '%s': load %.4g did not converge with a kept tangent (%s); trying "
                    "it again with the tangent assembled at every Newton iteration, for the rest of the stage\n",
                    stage_.name.c_str(), next, reason_text(reason).c_str());
        std::fflush(stdout);
      }
      model.set_displacement(u_conv.data());
      continue;
    }
    if (reason <= 0) {
      ++stats.cutbacks;
      step *= 0.5;
      if (verbose && rank_ == 0) {
        std::printf("[peridrive] quasistatic '%s': load %.4g did not converge (%s); step halved to %.4g\n",
                    stage_.name.c_str(), next, reason_text(reason).c_str(), step);
        std::fflush(stdout);
      }
      // A millionth of the stage's load: the load factor a stage cannot pass is then known to
      // 1e-6, and an increment that small does not converge where a larger one failed but
      // for a state with no equilibrium near it. Measured on example 7.2's balloon at 6 mm and
      // 6 MPa, past the discrete sphere's pressure maximum at load factor 0.9676: 52 attempts in
      // 231 s to a floor of 1e-9 without the stagnation test, 37 in 85 s to this one with it.
      if (step < 1e-6) {
        std::ostringstream msg;
        const std::string loads = model.load_text(load);
        msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "' cannot pass load factor "
            << fmt(load, 7) << (loads.empty() ? "" : " (" + loads + ")") << ": Newton diverged ("
            << reason_text(reason) << ") at every load step down to " << fmt(step * 2) << " of the stage's load; likely cause: a limit point (the largest load the "
            << "body holds on this path, e.g. an inflated membrane's pressure maximum: past it there is no "
            << "equilibrium; a dynamic stage shows what follows) or a loss of stiffness (e.g. all bonds of "
            << "a region broken); see -qs_snes_monitor";
        throw RuntimeFailure(msg.str());
      }
      model.set_displacement(u_conv.data());
      continue;
    }
    inc.newton_iterations = static_cast<int>(its);
    inc.linear_iterations = static_cast<int>(lits);
    // Bonds break only between converged solves; re-equilibrate at the same load until none do.
    for (;;) {
      expand(VecArrayRead(x_).data());
      model.set_displacement(full_.data());
      const std::int64_t broke = model.break_bonds();
      if (broke == 0) break;
      have_tangent_ = false;  // the tangent of the intact bonds: assemble it anew
      inc.broken += broke;
      if (++inc.break_passes > stage_.max_break_passes) {
        std::ostringstream msg;
        msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "': bonds still breaking after "
            << stage_.max_break_passes << " re-equilibrations at load factor " << fmt(next)
            << " (max_break_passes): the crack is running unstably; continue with a dynamic stage";
        throw RuntimeFailure(msg.str());
      }
      const double restart_norm = residual_norm();
      stagnation_test_ = false;  // no smaller step to fall back on: let Newton run its course
      reason = solve(x_);
      if (reason > 0) residual = check_converged(next, reason, restart_norm);
      PERI_PETSC(SNESGetIterationNumber(snes_, &its));
      PERI_PETSC(SNESGetLinearSolveIterations(snes_, &lits));
      stats.newton_iterations += its;
      stats.linear_iterations += lits;
      inc.newton_iterations += static_cast<int>(its);
      inc.linear_iterations += static_cast<int>(lits);
      if (reason <= 0) {
        std::ostringstream msg;
        msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "': no equilibrium after "
            << inc.broken << " bonds broke at load factor " << fmt(next) << " (" << reason_text(reason)
            << "): the crack is running unstably; continue with a dynamic stage";
        throw RuntimeFailure(msg.str());
      }
    }
    inc.residual = residual;
    // Work of the support reactions and the loads over the increment (trapezoidal rule).
    expand(VecArrayRead(x_).data());
    std::vector<double> x_new = full_;
    reactions(x_new.data(), reaction_new, load_force_new);
    for (std::size_t k = 0; k < n; ++k)
      stats.external_work += 0.5 * (reaction[k] + reaction_new[k] + load_force[k] + load_force_new[k]) *
                             (x_new[k] - u_conv[k]);
    reaction.swap(reaction_new);
    load_force.swap(load_force_new);
    u_prev.swap(u_conv);
    u_conv = std::move(x_new);
    load_prev = load;
    load = next;
    stats.broken += inc.broken;
    stats.increments.push_back(inc);
    if (observer) observer(stats, reaction.data());
    if (verbose && rank_ == 0) {
      std::printf("[peridrive] quasistatic '%s': load %.4g  Newton %d  linear %d  |R| %.3g N  broken %lld\n",
                  stage_.name.c_str(), load, inc.newton_iterations, inc.linear_iterations, inc.residual,
                  static_cast<long long>(inc.broken));
      std::fflush(stdout);
    }
    // Easy convergence: grow the step.
    if (inc.break_passes == 0 && inc.newton_iterations <= 4) step = std::min(1.5 * step, stage_.max_load_step);
  }
  model.set_displacement(u_conv.data());
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stats.residual_seconds = residual_seconds_;
  stats.tangent_seconds = tangent_seconds_;
  stats.tangent_assemblies = tangent_assemblies_;
  stats.near_null_modes = near_null_modes_;
  stats.unknowns = unknowns_;
  double moved = 0;
  for (std::size_t k = 0; k < n; ++k)
    if (constrained[k]) moved += increment[k] * increment[k];
  MPI_Allreduce(MPI_IN_PLACE, &moved, 1, MPI_DOUBLE, MPI_SUM, comm_);
  stats.work_scale = stiffness_ * moved;
  model_ = nullptr;
  constrained_ = nullptr;
  return stats;
}

void QuasiStaticLoader::residual(EquilibriumModel& model, const std::vector<double>& u, std::vector<double>& r) {
  if (u.size() != dof_.size() || u.size() != 3 * static_cast<std::size_t>(owned_))
    throw Error("QuasiStaticLoader::residual: needs a layout with every component of every owned node");
  std::vector<std::uint8_t> free_all(u.size(), 0);
  model_ = &model;
  constrained_ = &free_all;
  set_targets(std::vector<double>(u.size(), 0.0));
  r.resize(u.size());
  eval_residual(u.data(), r.data());
  model_ = nullptr;
  constrained_ = nullptr;
}

Mat QuasiStaticLoader::jacobian(EquilibriumModel& model, const std::vector<double>& u) {
  if (!J_) throw Error("QuasiStaticLoader::jacobian: matrix-free stage has no assembled tangent");
  if (u.size() != dof_.size() || u.size() != 3 * static_cast<std::size_t>(owned_))
    throw Error("QuasiStaticLoader::jacobian: needs a layout with every component of every owned node");
  model_ = &model;
  set_targets(std::vector<double>(u.size(), 0.0));
  constrained_rows_.clear();
  const double shift = stage_.jacobian_shift;
  stage_.jacobian_shift = 0;
  eval_jacobian(u.data(), J_);
  stage_.jacobian_shift = shift;
  model_ = nullptr;
  return J_;
}

}  // namespace peri
