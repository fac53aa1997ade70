// Gmsh's C API (gmshc.h), loaded when a scene first names a mesh and not before: libgmsh brings
// about 70 shared libraries (OpenCASCADE, FLTK, ...) whose relocations cost every process
// about 0.15-0.2 s of start-up, mesh or no mesh. Private to src/geometry/kinds/.
#pragma once
#include <gmshc.h>

#include <cstddef>
#include <string>

namespace peri::kinds {

/// The functions of Gmsh's C API that mesh bodies use, resolved from the library on first use.
/// Every call reports failure through its `ierr`; `check` turns that into Gmsh's last error
/// message, thrown as a std::string (as Gmsh's own C++ API does).
struct GmshLibrary {
  decltype(&gmshFree) free = nullptr;
  decltype(&gmshInitialize) initialize = nullptr;
  decltype(&gmshFinalize) finalize = nullptr;
  decltype(&gmshOpen) open = nullptr;
  decltype(&gmshOptionSetNumber) option_set_number = nullptr;
  decltype(&gmshLoggerStart) logger_start = nullptr;
  decltype(&gmshLoggerStop) logger_stop = nullptr;
  decltype(&gmshLoggerGetLastError) logger_get_last_error = nullptr;
  decltype(&gmshModelMeshGetNodes) get_nodes = nullptr;
  decltype(&gmshModelMeshGetElements) get_elements = nullptr;
  decltype(&gmshModelMeshGetElementProperties) get_element_properties = nullptr;
  decltype(&gmshModelGetPhysicalGroups) get_physical_groups = nullptr;
  decltype(&gmshModelGetPhysicalName) get_physical_name = nullptr;
  decltype(&gmshModelMeshGetNodesForPhysicalGroup) get_nodes_for_physical_group = nullptr;

  /// The library, loaded once per process (kept until it exits: Gmsh is not made to be
  /// unloaded). Throws std::runtime_error naming the library and the loader's message when it
  /// cannot be loaded.
  static const GmshLibrary& get();

  /// Throws Gmsh's last error (or `what` when it logged none) as a std::string if ierr != 0.
  void check(int ierr, const char* what) const;
  /// A string Gmsh allocated, copied and freed.
  std::string take(char* s) const;
};

/// An array Gmsh allocated (gmshMalloc), freed with gmshFree.
template <class T>
struct GmshArray {
  T* data = nullptr;
  std::size_t size = 0;
  const GmshLibrary* lib;
  explicit GmshArray(const GmshLibrary& l) : lib(&l) {}
  ~GmshArray() { lib->free(data); }
  GmshArray(const GmshArray&) = delete;
  GmshArray& operator=(const GmshArray&) = delete;
  const T* begin() const { return data; }
  const T* end() const { return data + size; }
};

}  // namespace peri::kinds
