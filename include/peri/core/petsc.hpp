// RAII for PETSc: owners of PETSc objects (destroyed when the owner goes, also when a call
// between create and destroy throws), guards of the arrays of a Vec or IS (restored when the
// guard goes), a session (PetscInitialize / PetscFinalize) for main, and the checked call
// (PERI_PETSC, core/error.hpp) that turns a PETSc error code into an exception.
#pragma once
#include <petscis.h>
#include <petscmat.h>
#include <petscsnes.h>
#include <petscvec.h>

#include <exception>
#include <utility>

#include "peri/core/error.hpp"

namespace peri {

/// Owner of one PETSc object of type T, destroyed by Destroy.
template <class T, PetscErrorCode (*Destroy)(T*)>
class PetscOwner {
 public:
  PetscOwner() = default;
  explicit PetscOwner(T object) : object_(object) {}
  PetscOwner(const PetscOwner&) = delete;
  PetscOwner& operator=(const PetscOwner&) = delete;
  PetscOwner(PetscOwner&& o) noexcept : object_(std::exchange(o.object_, nullptr)) {}
  PetscOwner& operator=(PetscOwner&& o) noexcept {
    std::swap(object_, o.object_);
    return *this;
  }
  ~PetscOwner() { reset(); }
  T get() const { return object_; }
  operator T() const { return object_; }  // NOLINT: passes to PETSc calls as the object
  /// For PETSc's create functions: PERI_PETSC(VecCreate(comm, owner.out())).
  T* out() {
    reset();
    return &object_;
  }
  void reset() {
    if (object_) Destroy(&object_);
    object_ = nullptr;
  }

 private:
  T object_ = nullptr;
};

using OwnedVec = PetscOwner<Vec, VecDestroy>;
using OwnedMat = PetscOwner<Mat, MatDestroy>;
using OwnedIS = PetscOwner<IS, ISDestroy>;
using OwnedSNES = PetscOwner<SNES, SNESDestroy>;
using OwnedScatter = PetscOwner<VecScatter, VecScatterDestroy>;
using OwnedPartitioning = PetscOwner<MatPartitioning, MatPartitioningDestroy>;
using OwnedNullSpace = PetscOwner<MatNullSpace, MatNullSpaceDestroy>;

/// The array of a Vec (its local part), writable, for the lifetime of the guard.
class VecArray {
 public:
  explicit VecArray(Vec v) : v_(v) { PERI_PETSC(VecGetArray(v_, &a_)); }
  ~VecArray() { VecRestoreArray(v_, &a_); }
  VecArray(const VecArray&) = delete;
  VecArray& operator=(const VecArray&) = delete;
  double* data() const { return a_; }
  double& operator[](std::size_t k) const { return a_[k]; }

 private:
  Vec v_;
  double* a_ = nullptr;
};

/// The array of a Vec (its local part), read-only, for the lifetime of the guard.
class VecArrayRead {
 public:
  explicit VecArrayRead(Vec v) : v_(v) { PERI_PETSC(VecGetArrayRead(v_, &a_)); }
  ~VecArrayRead() { VecRestoreArrayRead(v_, &a_); }
  VecArrayRead(const VecArrayRead&) = delete;
  VecArrayRead& operator=(const VecArrayRead&) = delete;
  const double* data() const { return a_; }
  const double& operator[](std::size_t k) const { return a_[k]; }

 private:
  Vec v_;
  const double* a_ = nullptr;
};

/// The indices of an IS for the lifetime of the guard.
class ISIndices {
 public:
  explicit ISIndices(IS is) : is_(is) { PERI_PETSC(ISGetIndices(is_, &p_)); }
  ~ISIndices() { ISRestoreIndices(is_, &p_); }
  ISIndices(const ISIndices&) = delete;
  ISIndices& operator=(const ISIndices&) = delete;
  const PetscInt* data() const { return p_; }

 private:
  IS is_;
  const PetscInt* p_ = nullptr;
};

/// PETSc for the lifetime of main's session: PetscInitialize, and PetscFinalize at the end
/// (after every owner above has gone: declare the session first).
class PetscSession {
 public:
  PetscSession(int* argc, char*** argv) { ok_ = PetscInitialize(argc, argv, nullptr, nullptr) == 0; }
  ~PetscSession() {
    if (ok_) PetscFinalize();
  }
  PetscSession(const PetscSession&) = delete;
  PetscSession& operator=(const PetscSession&) = delete;
  bool ok() const { return ok_; }

 private:
  bool ok_ = false;
};

/// A PETSc callback's body: runs f and returns 0, or keeps the exception f threw (its message
/// reaches the user: the caller rethrows it after PETSc returns, keep.rethrow()) and returns an
/// error code, so no exception crosses PETSc's C frames.
class CallbackError {
 public:
  template <class F>
  PetscErrorCode run(F&& f) noexcept {
    try {
      f();
      return 0;
    } catch (...) {
      if (!error_) error_ = std::current_exception();
      return PETSC_ERR_LIB;
    }
  }
  /// Rethrows the kept exception, if any (and forgets it).
  void rethrow() {
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }
  bool failed() const { return error_ != nullptr; }

 private:
  std::exception_ptr error_;
};

}  // namespace peri
