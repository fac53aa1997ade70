#include "peri/core/error.hpp"

namespace peri {

PetscError::PetscError(int code_, const char* call, const char* file, int line)
    : Error("PETSc/MPI call failed with code " + std::to_string(code_) + ": " + call + " (" +
            file + ":" + std::to_string(line) + ")"),
      code(code_) {}

}  // namespace peri
