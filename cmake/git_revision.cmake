# Writes OUT, the definition of peri::git_revision(), from `git describe` of the source tree SRC.
# Run at every build (the peri_git_revision target) and once at configure time; OUT is rewritten
# only when the revision changed, so a build without a new commit or edit recompiles nothing.
#   cmake -DSRC=<source dir> -DOUT=<file> -P git_revision.cmake
execute_process(COMMAND git -C "${SRC}" describe --always --dirty --abbrev=12
                OUTPUT_VARIABLE revision OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
if(NOT revision)
  set(revision "unknown")  # not a git checkout (a source archive), or no git
endif()
set(text "// Generated at build time by cmake/git_revision.cmake from `git describe`.
#include \"peri/core/build_info.hpp\"

namespace peri {
const char* git_revision() { return \"${revision}\"; }
}  // namespace peri
")
set(old "")
if(EXISTS "${OUT}")
  file(READ "${OUT}" old)
endif()
if(NOT old STREQUAL text)
  file(WRITE "${OUT}" "${text}")
endif()
