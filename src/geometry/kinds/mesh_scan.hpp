// What a mesh body reads of its file itself, before and after Gmsh does. Gmsh takes a file it
// does not recognise as a mesh for a script and runs it (shell commands included), runs a
// `<file>.opt` beside the file it opens, drops an element of another order mixed into an entity
// of a mesh file, and drops STL facets with non-number or coinciding corners, all without a word.
// Private to src/geometry/kinds/.
#pragma once
#include <cstddef>
#include <string>
#include <vector>

namespace peri::kinds {

/// A mesh file as its bytes say: a Gmsh .msh (text or binary) or an STL (text or binary).
struct MeshFileScan {
  bool stl = false;
  bool binary = false;
  /// STL: its facets (every one checked: three corners, finite and below 1e100 m after scale,
  /// no two alike). Text .msh: the elements its $Elements section lists.
  std::size_t elements = 0;
  /// Text .msh: the first element whose Gmsh type is not among `accepted` (0: none), its type
  /// and the file's line.
  std::size_t unaccepted_tag = 0;
  int unaccepted_type = 0;
  std::size_t unaccepted_line = 0;
};

/// Reads `path` (named by `key` in messages) and refuses with an InputError naming the file and
/// the line, facet or element: content that is neither a Gmsh .msh ($MeshFormat, version 2 or 4)
/// nor an STL, and STL facets that Gmsh would drop. `accepted`: the element types the body takes.
MeshFileScan scan_mesh_file(const std::string& path, const std::string& key, double scale,
                            const std::vector<int>& accepted);

/// A text .msh's first element whose tag is not in `tags_read` (sorted): its tag, type and line
/// (tag 0: every element of the file was read).
struct MissingElement {
  std::size_t tag = 0;
  int type = 0;
  std::size_t line = 0;
};
MissingElement first_element_not_read(const std::string& path, const std::vector<std::size_t>& tags_read);

/// A private directory (removed with its contents when the object goes) holding one link to the
/// mesh file, named mesh.msh or mesh.stl after what the scan found: Gmsh opens the link, so that
/// no `<file>.opt` of the user's folder is run and the format is the one the bytes say.
class MeshLink {
 public:
  MeshLink(const std::string& path, bool stl);
  ~MeshLink();
  MeshLink(const MeshLink&) = delete;
  MeshLink& operator=(const MeshLink&) = delete;
  const std::string& path() const { return link_; }

 private:
  std::string dir_, link_;
};

}  // namespace peri::kinds
