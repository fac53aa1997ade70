// A body kind, as one module: what a scene's `kind:` of a body names. Each kind is one file of
// src/geometry/kinds/ that fills a BodyKind: the keys it takes with their documentation, its
// reader and emitter, its size estimate and its discretization, and the traits the rest of the
// program asks of its nodes (their dimension, whether they sit on a grid, ...). The registry of
// kinds by name (src/geometry/body_kinds.cpp, and register_body_kind for a test's own kind) is
// the only list of body kinds: no other code branches on a kind, only on its traits.
//
// The scene layer reads, emits and documents a body through its kind; the geometry hooks take
// types of geometry/ (declared here, never called by the scene layer).
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "peri/scene/keys.hpp"

namespace peri {

struct Body;
struct Material;
struct BodyGeometry;
class NodeSink;
namespace scene_detail {
class Map;
class Writer;
}  // namespace scene_detail

/// What the program downstream of the discretization asks of a body's nodes.
struct BodyTraits {
  /// 1: nodes along paths, measure A ds (a bar: E and its wave speed; the 1D calibration);
  /// 2: a sheet, measure area x thickness (the in-plane calibration, eq. 19); 3: a volume.
  int dimension = 2;
  /// Nodes on a regular grid in raster order (square, hexagonal or cubic): reference offsets are
  /// snapped to the grid's units and rows share family patterns (bonds/).
  bool grid = true;
  /// A plane sheet normal to z: quasi-static `in_plane` stages hold its nodes' z (no out-of-plane
  /// stiffness at the flat state); crack tips are tracked in its plane; pre-cracks cut it.
  bool flat = false;
  /// Marder's lattice: six nearest neighbours and the lattice's own law (marder materials only).
  bool lattice = false;
  /// Its nodes take part in long-range pairs (the `long_range` section, eqs. 32-36).
  bool long_range = false;
  /// Its nodes are always an irregular set (a geodesic sphere): BodyGeometry::irregular whatever
  /// the body's keys. (A membrane or solid from a mesh or points file is irregular per body.)
  bool irregular = false;
  /// Pre-cracks (straight segments) cut its bonds: sheets and fibers, not volumes.
  bool cut_by_cracks() const { return dimension < 3; }
};

/// One body kind. Every function receives a body the kind's reader made.
struct BodyKind {
  std::string name;     ///< the scene's `kind:` value
  std::string summary;  ///< a few words on its nodes, for messages and --describe-keys
  BodyTraits traits;
  /// The body keys it takes besides kind and material, documented (--describe-keys), in the
  /// order the emitter writes them. A key no kind lists is unknown to the reader.
  scene_detail::Keys keys;
  /// Maps nested in its keys, documented as sections: (key, its keys), e.g. ("network", ...).
  std::vector<std::pair<std::string, const scene_detail::Keys*>> nested;
  /// Reads the kind's keys of `m` into `b` (the reader has refused the keys the kind does not
  /// take and set b.name, b.where, b.kind and b.material). Throws InputError via the Map/Value.
  void (*read)(const scene_detail::Map& m, Body& b, const Material& material) = nullptr;
  /// Writes the kind's keys, resolved (defaults filled in), at indent 4, in the order of `keys`.
  void (*emit)(scene_detail::Writer& w, const Body& b) = nullptr;
  /// The keys that set a node's measure, with their values, for messages
  /// ("bodies.sheet.spacing 0.001 m, bodies.sheet.thickness 0.0005 m").
  std::string (*measure_keys)(const Body& b) = nullptr;
  // Geometry (src/geometry/):
  /// About how many nodes the body has, before any is made (--dry-run, the memory check).
  double (*node_estimate)(const Body& b) = nullptr;
  /// About how many bonds a node has (before the cap at the body's other nodes).
  double (*family_estimate)(const Body& b) = nullptr;
  /// Appends the body's nodes to `sink` in its natural order and completes `g` (whose material,
  /// traits, spacing, horizon, quadrature and first node the caller has set from the body).
  void (*discretize)(const Body& b, BodyGeometry& g, NodeSink& sink) = nullptr;
};

/// The kind of that name, or nullptr (the registry: src/geometry/body_kinds.cpp).
const BodyKind* find_body_kind(const std::string& name);
/// Every kind, the built-in ones first (membrane, solid, lattice, fiber, sphere).
std::vector<const BodyKind*> body_kinds();
/// Adds a kind (a test's own); Error if the name is taken. Not thread-safe: register before
/// scenes are read.
void register_body_kind(const BodyKind& kind);

}  // namespace peri
