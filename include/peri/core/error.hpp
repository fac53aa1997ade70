// Error types of the library. Pure C++ layers throw; PETSc return codes are turned into
// peri::PetscError by PERI_PETSC so that one mechanism (exceptions) reaches the driver.
#pragma once
#include <stdexcept>
#include <string>

namespace peri {

/// Where a value came from: a scene file and line, or a --set override.
struct SourceLoc {
  std::string file;  ///< scene file path, or "--set"
  int line = 0;      ///< 1-based line; 0 when unknown
  std::string str() const {
    return line > 0 ? file + ":" + std::to_string(line) : file;
  }
};

/// Base of all peridrive errors. what() is the complete one-line message for the user.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Invalid user input: scene files, command-line options, checkpoints. Raised identically on
/// every rank (every rank reads and validates the same input), so no rank waits in a collective.
class InputError : public Error {
 public:
  using Error::Error;
};

/// A failure inside a numerical stage (instability, solver divergence).
class RuntimeFailure : public Error {
 public:
  using Error::Error;
};

/// A stop request (SIGTERM/SIGINT) honoured before the run began: while the scene was read or
/// the run was set up. Nothing was written.
class StopRequested : public Error {
 public:
  using Error::Error;
};

/// A non-zero PETSc/MPI/HDF5 return code.
class PetscError : public Error {
 public:
  PetscError(int code, const char* call, const char* file, int line);
  int code;
};

}  // namespace peri

/// Call a PETSc function and throw peri::PetscError on failure.
#define PERI_PETSC(call)                                                   \
  do {                                                                     \
    PetscErrorCode peri_ierr_ = (call);                                    \
    if (peri_ierr_) throw ::peri::PetscError(peri_ierr_, #call, __FILE__, __LINE__); \
  } while (0)
