#include "gmsh_library.hpp"

#include <dlfcn.h>

#include <stdexcept>

namespace peri::kinds {
namespace {

// PERI_GMSH_LIBRARY: the library CMake found (its real path); PERI_GMSH_SONAME: its soname, for
// a binary run where that path is gone but the loader finds the same library.
const char* const kCandidates[] = {PERI_GMSH_LIBRARY, PERI_GMSH_SONAME};

template <class F>
void resolve(void* handle, const char* name, F& f) {
  void* p = dlsym(handle, name);
  if (!p) throw std::runtime_error(std::string("the Gmsh library has no ") + name + " (Gmsh 4.8 or later is needed)");
  f = reinterpret_cast<F>(p);
}

GmshLibrary load() {
  void* handle = nullptr;
  std::string errors;
  for (const char* path : kCandidates) {
    if (!*path) continue;
    if ((handle = dlopen(path, RTLD_NOW | RTLD_LOCAL))) break;
    const char* e = dlerror();
    errors += std::string(errors.empty() ? "" : "; ") + (e ? e : path);
  }
  if (!handle)
    throw std::runtime_error("mesh bodies need the Gmsh library, which cannot be loaded (" + errors +
                             "); install it (Debian: libgmsh4.8)");
  GmshLibrary g;
  resolve(handle, "gmshFree", g.free);
  resolve(handle, "gmshInitialize", g.initialize);
  resolve(handle, "gmshFinalize", g.finalize);
  resolve(handle, "gmshOpen", g.open);
  resolve(handle, "gmshOptionSetNumber", g.option_set_number);
  resolve(handle, "gmshLoggerStart", g.logger_start);
  resolve(handle, "gmshLoggerStop", g.logger_stop);
  resolve(handle, "gmshLoggerGetLastError", g.logger_get_last_error);
  resolve(handle, "gmshModelMeshGetNodes", g.get_nodes);
  resolve(handle, "gmshModelMeshGetElements", g.get_elements);
  resolve(handle, "gmshModelMeshGetElementProperties", g.get_element_properties);
  resolve(handle, "gmshModelGetPhysicalGroups", g.get_physical_groups);
  resolve(handle, "gmshModelGetPhysicalName", g.get_physical_name);
  resolve(handle, "gmshModelMeshGetNodesForPhysicalGroup", g.get_nodes_for_physical_group);
  return g;
}

}  // namespace

const GmshLibrary& GmshLibrary::get() {
  static const GmshLibrary g = load();  // a failed load throws, and the next call tries again
  return g;
}

std::string GmshLibrary::take(char* s) const {
  std::string out = s ? s : "";
  free(s);
  return out;
}

void GmshLibrary::check(int ierr, const char* what) const {
  if (!ierr) return;
  char* e = nullptr;
  int ignored = 0;
  logger_get_last_error(&e, &ignored);
  std::string message = take(e);
  throw message.empty() ? std::string(what) : message;
}

}  // namespace peri::kinds
