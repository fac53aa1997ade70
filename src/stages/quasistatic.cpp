#include "peri/stages/quasistatic.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "peri/core/error.hpp"

namespace peri {
namespace {

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

}  // namespace

QuasiStaticLoader::QuasiStaticLoader(MPI_Comm comm, std::int32_t owned, const std::vector<PetscInt>& d_nnz,
                                     const std::vector<PetscInt>& o_nnz, double stiffness_scale,
                                     double length_scale, const Stage& stage)
    : comm_(comm), owned_(owned), stage_(stage), stiffness_(stiffness_scale > 0 ? stiffness_scale : 1.0),
      length_(length_scale) {
  MPI_Comm_rank(comm_, &rank_);
  const PetscInt n = 3 * static_cast<PetscInt>(owned);
  PERI_PETSC(VecCreateMPI(comm_, n, PETSC_DETERMINE, x_.out()));
  PERI_PETSC(VecSetBlockSize(x_, 3));
  PERI_PETSC(VecDuplicate(x_, r_.out()));
  PERI_PETSC(SNESCreate(comm_, snes_.out()));
  PERI_PETSC(SNESSetOptionsPrefix(snes_, "qs_"));
  PERI_PETSC(SNESSetFunction(snes_, r_, &QuasiStaticLoader::form_function, this));
  if (stage_.matrix_free) {
    PERI_PETSC(SNESSetUseMatrixFree(snes_, PETSC_TRUE, PETSC_FALSE));
  } else {
    // Block sparse (bs = 3) by default; -qs_mat_type aij for preconditioners that need AIJ (gamg).
    PERI_PETSC(MatCreate(comm_, J_.out()));
    PERI_PETSC(MatSetSizes(J_, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
    PERI_PETSC(MatSetBlockSize(J_, 3));
    PERI_PETSC(MatSetType(J_, MATBAIJ));
    PERI_PETSC(MatSetOptionsPrefix(J_, "qs_"));
    PERI_PETSC(MatSetFromOptions(J_));
    PERI_PETSC(MatXAIJSetPreallocation(J_, 3, d_nnz.data(), o_nnz.data(), nullptr, nullptr));
    PERI_PETSC(MatSetOption(J_, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
    PERI_PETSC(MatSetOption(J_, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
    PERI_PETSC(SNESSetJacobian(snes_, J_, J_, &QuasiStaticLoader::form_jacobian, this));
  }
  // Defaults (any -qs_snes_* option overrides): an absolute residual of 1e-10 of a node's
  // stiffness times its spacing, 1e-9 relative, at most 50 Newton iterations per solve.
  PERI_PETSC(SNESSetTolerances(snes_, 1e-10 * stiffness_ * length_, 1e-9, 1e-12, 50, -1));
  KSP ksp;
  PERI_PETSC(SNESGetKSP(snes_, &ksp));
  PERI_PETSC(KSPSetTolerances(ksp, 1e-6, PETSC_DEFAULT, PETSC_DEFAULT, 20000));
  PERI_PETSC(SNESSetFromOptions(snes_));
}

QuasiStaticLoader::~QuasiStaticLoader() = default;

void QuasiStaticLoader::eval_residual(const double* x, double* f) {
  const std::size_t n = 3 * static_cast<std::size_t>(owned_);
  model_->set_displacement(x);
  force_.resize(n);
  model_->internal_force(force_.data());
  const std::vector<std::uint8_t>& fixed = *constrained_;
  for (std::size_t k = 0; k < n; ++k) f[k] = fixed[k] ? stiffness_ * (x[k] - target_[k]) : -force_[k];
}

void QuasiStaticLoader::eval_jacobian(const double* x, Mat J) {
  model_->set_displacement(x);
  PERI_PETSC(MatZeroEntries(J));
  model_->add_tangent(J);
  PERI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  PERI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  // Regularization of the tangent only (the residual is untouched, so the converged state is the
  // exact equilibrium): a flat membrane has no out-of-plane stiffness at zero in-plane tension.
  if (stage_.jacobian_shift > 0) PERI_PETSC(MatShift(J, stage_.jacobian_shift * stiffness_));
  PERI_PETSC(MatZeroRows(J, static_cast<PetscInt>(constrained_rows_.size()), constrained_rows_.data(), stiffness_,
                         nullptr, nullptr));
}

PetscErrorCode QuasiStaticLoader::form_function(SNES, Vec x, Vec f, void* ctx) {
  auto* self = static_cast<QuasiStaticLoader*>(ctx);
  return self->callback_error_.run([&] {
    const VecArrayRead xa(x);
    const VecArray fa(f);
    self->eval_residual(xa.data(), fa.data());
  });
}

PetscErrorCode QuasiStaticLoader::form_jacobian(SNES, Vec x, Mat J, Mat, void* ctx) {
  auto* self = static_cast<QuasiStaticLoader*>(ctx);
  return self->callback_error_.run([&] {
    const VecArrayRead xa(x);
    self->eval_jacobian(xa.data(), J);
  });
}

int QuasiStaticLoader::solve(Vec x) {
  // An exception in a callback comes back as an error code through SNESSolve: PETSc's handler
  // stays quiet meanwhile, and the exception itself (its message) is rethrown here.
  PERI_PETSC(PetscPushErrorHandler(PetscIgnoreErrorHandler, nullptr));
  const PetscErrorCode error = SNESSolve(snes_, nullptr, x);
  PERI_PETSC(PetscPopErrorHandler());
  callback_error_.rethrow();
  PERI_PETSC(error);
  SNESConvergedReason reason;
  PERI_PETSC(SNESGetConvergedReason(snes_, &reason));
  return static_cast<int>(reason);
}

QuasiStaticStats QuasiStaticLoader::run(EquilibriumModel& model, const std::vector<std::uint8_t>& constrained,
                                        const std::vector<double>& increment, bool verbose) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = 3 * static_cast<std::size_t>(owned_);
  model_ = &model;
  constrained_ = &constrained;
  PetscInt rstart;
  PERI_PETSC(VecGetOwnershipRange(x_, &rstart, nullptr));
  constrained_rows_.clear();
  for (std::size_t k = 0; k < n; ++k)
    if (constrained[k]) constrained_rows_.push_back(rstart + static_cast<PetscInt>(k));

  std::vector<double> u0(n), u_conv(n), u_prev(n), reaction(n, 0.0), reaction_new(n), f(n);
  model.get_displacement(u0.data());
  u_conv = u0;
  auto reactions = [&](const double* u, std::vector<double>& out) {
    model.set_displacement(u);
    model.internal_force(f.data());
    for (std::size_t k = 0; k < n; ++k) out[k] = constrained[k] ? -f[k] : 0.0;  // support force on the body
  };
  reactions(u0.data(), reaction);

  QuasiStaticStats stats;
  double load = 0, load_prev = -1, step = 1.0 / static_cast<double>(stage_.load_steps);
  long attempts = 0;
  target_.resize(n);
  while (load < 1.0) {
    if (++attempts > stage_.max_load_steps) {
      std::ostringstream msg;
      msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "' reached load factor " << fmt(load)
          << " after " << stage_.max_load_steps << " increments (max_load_steps, cut-backs included); "
          << "likely cause: a limit point (snap-through, or fracture that the loading cannot hold) or "
             "too tight solver tolerances; try more load_steps or a dynamic stage";
      throw RuntimeFailure(msg.str());
    }
    const double next = std::min(1.0, load + step);
    // Predictor: constrained components at their prescribed values, free ones extrapolated
    // along the last converged increment (secant).
    {
      const VecArray x(x_);
      const double ratio = load_prev >= 0 ? (next - load) / (load - load_prev) : 0.0;
      for (std::size_t k = 0; k < n; ++k) {
        target_[k] = constrained[k] ? u0[k] + next * increment[k] : 0.0;
        x[k] = constrained[k] ? target_[k] : u_conv[k] + ratio * (u_conv[k] - u_prev[k]);
      }
    }
    LoadIncrement inc;
    inc.load_factor = next;
    int reason = solve(x_);
    PetscInt its, lits;
    PERI_PETSC(SNESGetIterationNumber(snes_, &its));
    PERI_PETSC(SNESGetLinearSolveIterations(snes_, &lits));
    stats.newton_iterations += its;
    stats.linear_iterations += lits;
    if (reason <= 0) {
      ++stats.cutbacks;
      step *= 0.5;
      if (verbose && rank_ == 0) {
        std::printf("[peridrive] quasistatic '%s': load %.4g did not converge (%s); step halved to %.4g\n",
                    stage_.name.c_str(), next, SNESConvergedReasons[reason], step);
        std::fflush(stdout);
      }
      if (step < 1e-9) {
        std::ostringstream msg;
        msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "' cannot pass load factor "
            << fmt(load) << ": Newton diverged (" << SNESConvergedReasons[reason]
            << ") with a load step of " << fmt(step * 2) << "; likely cause: a limit point or a loss of "
            << "stiffness (e.g. all bonds of a region broken); see -qs_snes_monitor";
        throw RuntimeFailure(msg.str());
      }
      model.set_displacement(u_conv.data());
      continue;
    }
    inc.newton_iterations = static_cast<int>(its);
    inc.linear_iterations = static_cast<int>(lits);
    // Bonds break only between converged solves; re-equilibrate at the same load until none do.
    for (;;) {
      model.set_displacement(VecArrayRead(x_).data());
      const std::int64_t broke = model.break_bonds();
      if (broke == 0) break;
      inc.broken += broke;
      if (++inc.break_passes > stage_.max_break_passes) {
        std::ostringstream msg;
        msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "': bonds still breaking after "
            << stage_.max_break_passes << " re-equilibrations at load factor " << fmt(next)
            << " (max_break_passes): the crack is running unstably; continue with a dynamic stage";
        throw RuntimeFailure(msg.str());
      }
      reason = solve(x_);
      PERI_PETSC(SNESGetIterationNumber(snes_, &its));
      PERI_PETSC(SNESGetLinearSolveIterations(snes_, &lits));
      stats.newton_iterations += its;
      stats.linear_iterations += lits;
      inc.newton_iterations += static_cast<int>(its);
      inc.linear_iterations += static_cast<int>(lits);
      if (reason <= 0) {
        std::ostringstream msg;
        msg << stage_.where.str() << ": quasi-static stage '" << stage_.name << "': no equilibrium after "
            << inc.broken << " bonds broke at load factor " << fmt(next) << " (" << SNESConvergedReasons[reason]
            << "): the crack is running unstably; continue with a dynamic stage";
        throw RuntimeFailure(msg.str());
      }
    }
    PetscReal fnorm;
    PERI_PETSC(SNESGetFunctionNorm(snes_, &fnorm));
    inc.residual = fnorm;
    // Work of the support reactions over the increment (trapezoidal rule).
    std::vector<double> x_new(n);
    {
      const VecArrayRead xa(x_);
      std::copy(xa.data(), xa.data() + n, x_new.begin());
    }
    reactions(x_new.data(), reaction_new);
    for (std::size_t k = 0; k < n; ++k)
      if (constrained[k]) stats.external_work += 0.5 * (reaction[k] + reaction_new[k]) * (x_new[k] - u_conv[k]);
    reaction.swap(reaction_new);
    u_prev.swap(u_conv);
    u_conv = std::move(x_new);
    load_prev = load;
    load = next;
    stats.broken += inc.broken;
    stats.increments.push_back(inc);
    if (verbose && rank_ == 0) {
      std::printf("[peridrive] quasistatic '%s': load %.4g  Newton %d  linear %d  |R| %.3g N  broken %lld\n",
                  stage_.name.c_str(), load, inc.newton_iterations, inc.linear_iterations, inc.residual,
                  static_cast<long long>(inc.broken));
      std::fflush(stdout);
    }
    // Easy convergence: grow the step.
    if (inc.break_passes == 0 && inc.newton_iterations <= 4) step *= 1.5;
  }
  model.set_displacement(u_conv.data());
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  model_ = nullptr;
  constrained_ = nullptr;
  return stats;
}

void QuasiStaticLoader::residual(EquilibriumModel& model, const std::vector<double>& u, std::vector<double>& r) {
  std::vector<std::uint8_t> free_all(u.size(), 0);
  model_ = &model;
  constrained_ = &free_all;
  target_.assign(u.size(), 0.0);
  r.resize(u.size());
  eval_residual(u.data(), r.data());
  model_ = nullptr;
  constrained_ = nullptr;
}

Mat QuasiStaticLoader::jacobian(EquilibriumModel& model, const std::vector<double>& u) {
  if (!J_) throw Error("QuasiStaticLoader::jacobian: matrix-free stage has no assembled tangent");
  model_ = &model;
  constrained_rows_.clear();
  const double shift = stage_.jacobian_shift;
  stage_.jacobian_shift = 0;
  eval_jacobian(u.data(), J_);
  stage_.jacobian_shift = shift;
  model_ = nullptr;
  return J_;
}

}  // namespace peri
