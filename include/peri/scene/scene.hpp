// Scene: the validated, SI-unit description of one run (bodies, materials, pre-cracks,
// boundary regions, initial conditions, stages, output). Read from YAML; every key is checked.
// Nothing downstream reads YAML: the rest of the program sees only these structs.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "peri/core/error.hpp"
#include "peri/models/laws/marder.hpp"
#include "peri/scene/body_kind.hpp"

namespace peri {

using Vec3 = std::array<double, 3>;

/// Which damaged nodes are crack tips under the incremental crack-tip advance (tip_advance).
enum class TipScope {
  Family,  ///< each damaged node whose family holds no node damaged later (a tip per crack)
  Body,    ///< the body's nodes damaged at its latest break time (one tip for the whole body)
};

/// Influence function g(|xi|) of eq. (13).
enum class Influence {
  Constant,  ///< g = 1
  Conical,   ///< g = 1 - |xi|/delta
};

/// How a neighbour's measure is weighted inside the horizon (the quadrature of eq. (12)).
enum class Quadrature {
  Full,         ///< weight 1 for |xi| <= delta, 0 beyond
  PartialArea,  ///< exact fraction of the neighbour's cell (square of side dx) inside the disc
  Taper,        ///< 1 inside, falling linearly to 1/2 at |xi| = delta over the last dx/2 (Parks et al.)
};

enum class Grid { Square, Hexagonal };

/// Power-law hardening of eq. (16): the bond energy gains c' (lambda^n - n lambda + n - 1) g, i.e.
/// (16) with the affine terms that keep the reference state stress-free.
struct Hardening {
  double coefficient = 0.0;  ///< c' [same unit as the micromodulus c]
  double exponent = 2.0;     ///< n > 1
};

/// Constants of Marder's lattice law (Marder paper eqs. 6, 27, 31-33).
struct MarderParams {
  double a = 0;                    ///< Mooney-Rivlin a of W/rho = a [J1 + b J2] [J/kg]
  double b = 0;                    ///< Mooney-Rivlin b [-]
  double cutoff = 0;               ///< u_s, short-distance cutoff [m]
  double fracture_separation = 0;  ///< u_c, separation at which a bond fails [m]
  bool reversible = false;         ///< bonds heal below u_c (default: irreversible)
  MarderOptions options;           ///< dashpots, stiffening, break separation (0: none)
};

struct Material {
  std::string name;
  SourceLoc where;
  std::string model = "membrane";  ///< a material model of the catalog (scene/models.hpp): membrane, pmb, marder, ...
  double density = 0.0;  ///< rho [kg/m^3], > 0
  // Stiffness: exactly one of the four is given in the scene; the others stay empty.
  std::optional<double> wave_speed;      ///< small-strain longitudinal wave speed c_l [m/s]
  std::optional<double> bulk_modulus;    ///< K [Pa]: in-plane K = lambda+mu for membranes, 3D for solids
  std::optional<double> youngs_modulus;  ///< E [Pa]
  std::optional<double> micromodulus;    ///< c itself [SI unit of the model's c]
  Influence influence = Influence::Constant;
  /// Critical stretch for bond failure. Membrane model: lambda_0 > 1 (eq. 22).
  /// PMB: critical bond strain s_0 > 0 (the papers' "critical stretch" 0.1, 0.03, 0.3).
  /// Empty: bonds never break.
  std::optional<double> critical_stretch;
  /// Optional Lambda_delta of eq. (29): the critical value at |xi| = delta (then critical_stretch
  /// is Lambda_0, the value at |xi| = 0). Same meaning (stretch or strain) as critical_stretch.
  std::optional<double> critical_stretch_at_horizon;
  /// The incremental crack-tip advance of section 7.4 (kernels/tip_advance.hpp): a bond may break
  /// only where one of its ends lies within this distance [m] of a crack-tip node. Empty: off.
  std::optional<double> tip_advance;
  /// Which damaged nodes are its crack tips (tip_advance_tips).
  TipScope tip_advance_tips = TipScope::Family;
  /// Kinematic viscosity nu [m^2/s] of the peridynamic laws' bond dashpots
  /// (kernels/dashpots.hpp); 0: none. (The marder model keeps its own in MarderParams.)
  double kelvin_viscosity = 0;
  std::optional<Hardening> hardening;  ///< membrane model only
  std::optional<MarderParams> marder;  ///< model marder only
};

/// A network of fibers (example 7.6) generated in a box: per family, `count` fibers start at
/// uniformly random points within `start_band` of the box face normal to the family's direction
/// (and anywhere across the other two) and walk across the box in steps of `step`, each step's
/// direction deviating from the family's by Gaussian angles of standard deviation `deviation`
/// in the plane and out of it (mirrored back at the box's side faces), until they leave the far
/// face. Deterministic for a seed (its own generator: the same paths on every rank).
struct FiberFamily {
  SourceLoc where;
  int axis = 0;    ///< 0: fibers along x, 1: along y
  long count = 0;  ///< >= 1
};
struct FiberNetwork {
  SourceLoc where;
  Vec3 min{0, 0, 0}, max{0, 0, 0};  ///< the box [m]
  std::vector<FiberFamily> families;
  double deviation = 0.15;   ///< sigma of the direction noise [rad], >= 0
  double step = 0.0;         ///< path length between direction draws [m] (> 0)
  double start_band = 0.0;   ///< [m] (>= 0)
  long seed = 1;
};

/// A region whose nodes a body drops before bonds are built (a hole, a notch, a slot): nodes
/// removed by a cutout do not exist at all (no detached plug, no zero-mass node).
enum class CutoutShape {
  Circle,    ///< |(x, y) - center| <= radius in the xy plane (through a solid along z)
  Box,       ///< min <= x <= max in every component
  Polygon,   ///< (x, y) inside the polygon `vertices` (even-odd rule; through a solid along z)
  Sphere,    ///< |x - center| <= radius (solids)
  Cylinder,  ///< distance to the line through center along `axis` <= radius, unbounded (solids)
};

struct Cutout {
  SourceLoc where;
  CutoutShape shape = CutoutShape::Circle;
  Vec3 center{0, 0, 0};  ///< circle (z unused), sphere, cylinder (a point on its axis) [m]
  double radius = 0.0;   ///< circle, sphere, cylinder [m] (> 0)
  Vec3 min{0, 0, 0}, max{0, 0, 0};                  ///< box [m]
  std::vector<std::array<double, 2>> vertices;      ///< polygon, in the xy plane [m]
  int axis = 2;                                     ///< cylinder: 0, 1, 2 for x, y, z
  /// True when the reference position x lies in the cutout (its boundary included; a polygon's
  /// edges may fall either way).
  bool contains(const Vec3& x) const;
};

/// One point of a point-cloud body (a solid's `points` file): position [m] and volume [m^3].
struct CloudPoint {
  Vec3 x{0, 0, 0};
  double volume = 0.0;
};

/// A physical group of a mesh file: its name and the body's nodes it holds (indices into
/// MeshData::nodes, ascending), over every dimension the name is given to.
struct MeshGroup {
  std::string name;
  std::vector<std::int64_t> nodes;
};

/// A triangle mesh is a flat sheet when its nodes' z spread no more than this fraction of its
/// size (the largest of its x and y extents and its coordinates' magnitude).
inline constexpr double kFlatMeshTolerance = 1e-6;

/// A body's mesh (`mesh: file`), read with the scene through Gmsh's API (kinds/mesh_file.cpp):
/// the nodes its triangles (membranes) or tetrahedra (solids) use, in ascending order of their
/// tags in the file (nodes no such element uses are not the body's), positions times `scale`.
struct MeshData {
  std::vector<Vec3> nodes;                              ///< [m]
  std::vector<std::size_t> tags;                        ///< each node's tag in the file
  std::vector<std::array<std::int64_t, 3>> triangles;   ///< membranes: corners, the file's order
  std::vector<std::array<std::int64_t, 4>> tets;        ///< solids: corners, positive volume
  std::vector<std::size_t> element_tags;                ///< each triangle's or tet's tag in the file
  std::vector<double> measure;                          ///< each node's area (a third of its
                                                        ///< triangles') or volume (a quarter of its tets')
  std::vector<MeshGroup> groups;                        ///< named physical groups, in the file's order
  double mean_edge = 0.0;  ///< mean length of the elements' edges, each edge once [m]
  double total = 0.0;      ///< the elements' total area [m^2] or volume [m^3]
  bool planar = false;     ///< every node at the same z (a flat sheet)
  /// A triangle mesh whose nodes' z spread no more than kFlatMeshTolerance of its size (round-off
  /// of a flat sheet, e.g. an STL's float32 coordinates) is made planar: every z set to the middle
  /// of the spread, this spread [m] kept to say so (0: none).
  double flattened = 0.0;
  /// A triangle mesh that is a plane sheet whose normal is not along z (within the same
  /// tolerance): the unit normal; zeros otherwise. It runs as a curved sheet (setup warns).
  Vec3 tilted_normal{0, 0, 0};
  const MeshGroup* group(const std::string& name) const {
    for (const MeshGroup& g : groups)
      if (g.name == name) return &g;
    return nullptr;
  }
};

struct Body {
  std::string name;
  SourceLoc where;
  const BodyKind* kind = nullptr;  ///< its kind (scene/body_kind.hpp): membrane, solid, lattice, fiber, sphere, ...
  std::string material;       ///< name of an entry of Scene::materials
  Vec3 origin{0, 0, 0};       ///< lower corner [m]
  Vec3 size{0, 0, 0};         ///< extent [m]; membranes use x, y (z must be 0)
  double thickness = 0.0;     ///< h [m], membranes only (> 0)
  double spacing = 0.0;       ///< dx [m] (> 0)
  Grid grid = Grid::Square;
  double horizon_factor = 3.0;          ///< m in delta = m*dx (>= 1); ignored when horizon set
  std::optional<double> horizon;        ///< delta [m] (>= spacing)
  Quadrature quadrature = Quadrature::PartialArea;
  /// Lattice bodies: only bonds with both ends inside this box [min, max] (reference positions)
  /// may break; empty = every bond (Marder's simulations often let bonds break only along the
  /// crack line, so that the crack neither branches nor tears the clamped edges).
  std::optional<std::array<Vec3, 2>> breakable;
  // Fibers (eq. 31): nodes at equal arc-length steps along the polyline `path`, cross-section
  // A = pi diameter^2 / 4; `segment_length` > 0 numbers the stretches of that length along the
  // fiber (segments) that long-range rules tell apart (0: the whole fiber is one segment).
  std::vector<Vec3> path;
  std::string polyline;  ///< the file the path was read from (`polyline: file`, resolved), or empty
  std::optional<FiberNetwork> network;  ///< instead of path: many fibers in one body (cross-linked
                                        ///< where they pass within the horizon)
  double diameter = 0.0;        ///< [m] (> 0)
  double segment_length = 0.0;  ///< [m] (>= 0)
  // Spherical membranes (kind sphere, example 7.2): nodes on a geodesic sphere of `radius` about
  // `center` (origin holds the center), thickness h; an internal follower pressure that rises
  // linearly to `pressure` over `pressure_ramp_time`.
  double radius = 0.0;              ///< [m] (> 0)
  double pressure = 0.0;            ///< [Pa] (>= 0)
  double pressure_ramp_time = 0.0;  ///< [s] (>= 0)
  /// Grid bodies (membranes, solids, lattices): regions whose nodes are removed, in scene order.
  std::vector<Cutout> cutouts;
  /// Solids from a point cloud (`points: file`): the file's path, resolved against the scene
  /// file's folder (empty: a box of simple-cubic points), and its rows this body takes, in file
  /// order (those whose material column names the body's material, or all of them).
  std::string points;
  std::vector<CloudPoint> cloud;
  /// The materials the file's material column (dataset) names, each with the place it first
  /// appears at ("file:line"; HDF5: "file: point k").
  std::vector<std::pair<std::string, std::string>> cloud_materials;
  /// Membranes and solids from a mesh file (`mesh: file`): its path, resolved against the scene
  /// file's folder (empty: a grid body), the factor on its coordinates, whether the scene gave
  /// `spacing` (else spacing is the mesh's mean edge length), and what was read.
  std::string mesh;
  double scale = 1.0;
  bool spacing_given = true;
  std::shared_ptr<const MeshData> mesh_data;
  double horizon_value() const { return horizon ? *horizon : horizon_factor * spacing; }
  /// True when one of the cutouts holds the reference position x.
  bool cut_out(const Vec3& x) const {
    return std::any_of(cutouts.begin(), cutouts.end(), [&](const Cutout& c) { return c.contains(x); });
  }
};

/// Axis-aligned box [min, max] (inclusive) selecting nodes by reference position; or a physical
/// group of a mesh body's file (`group`, with `body`: the group's nodes, no box).
struct Region {
  SourceLoc where;
  Vec3 min{0, 0, 0};
  Vec3 max{0, 0, 0};
  std::string body;  ///< restrict to one body; empty = all bodies
  std::string group;  ///< a physical group of body's mesh; empty = the box
  bool contains(const Vec3& x) const {
    for (int d = 0; d < 3; ++d)
      if (x[d] < min[d] || x[d] > max[d]) return false;
    return true;
  }
};

/// Polygons with at least this many corners keep their fan's wedges (Crack::fan_low): a bond
/// tests only the fan triangles about its crossing of the plane, not all n - 2.
inline constexpr std::size_t kFanSearchCorners = 8;

/// Pre-crack: every bond whose reference segment meets it is broken at the start (Silling &
/// Bobaru 7.1: "breaking all the peridynamic bonds that intersect the slit"). A slit, the segment
/// [from, to] taken in the xy plane, cuts sheets and fibers; a polygon, a convex plane polygon in
/// space, cuts every body's bonds, volumes and curved sheets included.
struct Crack {
  std::string name;
  SourceLoc where;
  Vec3 from{0, 0, 0};
  Vec3 to{0, 0, 0};
  std::vector<Vec3> polygon;  ///< corners in order; empty for a slit
  /// A polygon's mean plane n . x = offset (unit n) and a distance beyond which no point of its
  /// fan lies, round-off included: a bond with both ends farther on one side meets nothing (a
  /// filter before the exact test; infinite where not computed, filtering nothing).
  Vec3 plane_normal{0, 0, 0};
  double plane_offset = 0, plane_tolerance = INFINITY;
  /// A polygon's fan seen from its first corner, for crosses()' search of the fan triangles a
  /// bond may meet: axes u (toward the second corner) and v = n x u in the mean plane, and per fan
  /// triangle k (corners 1, k + 2, k + 3, counted from 1) bounds on its wedge's angles about the
  /// first corner that rise with k: fan_low[k] the least angle of triangles k and after,
  /// fan_high[k] the largest of triangles k and before. Empty: every triangle is tested.
  Vec3 fan_u{0, 0, 0}, fan_v{0, 0, 0};
  std::vector<double> fan_low, fan_high;
  bool is_polygon() const { return !polygon.empty(); }
  /// Whether it cuts the bonds of a body of this dimension (1 fibers, 2 sheets, 3 volumes).
  bool cuts_dimension(int dimension) const { return is_polygon() || dimension < 3; }
  /// A slit's distance in space from point x to its segment from .. to (z included) [m]. A slit
  /// cuts by its xy projection, so on a curved sheet the bonds it breaks farther than a horizon
  /// from it are walls above or below it that it does not touch.
  double slit_distance(const double* x) const;
};

/// Prescribed-velocity (or clamped: velocity 0) region.
struct Boundary {
  std::string name;
  SourceLoc where;
  Region region;
  Vec3 velocity{0, 0, 0};                       ///< [m/s]
  std::array<bool, 3> components{true, true, true};  ///< which components are prescribed
  double ramp_time = 0.0;  ///< [s] velocity rises linearly from 0 over this time (0: at once)
};

/// Rigid tool: a cylinder of infinite length with its axis along z (normal to membranes), moving
/// at a constant in-plane velocity; nodes inside it are pushed out by a penalty force, with
/// Coulomb friction (Silling & Bobaru 7.4, the blunt tool). Acts in dynamic stages.
struct Tool {
  std::string name;
  SourceLoc where;
  bool sphere = false;                 ///< kind sphere (a fragment) instead of cylinder
  double radius = 0.0;                 ///< [m] (> 0)
  std::array<double, 3> center{0, 0, 0};  ///< axis position (x, y) or sphere centre at t = 0 [m]
  std::array<double, 3> velocity{0, 0, 0};  ///< [m/s] (cylinder: in-plane, z = 0)
  double friction = 0.0;               ///< Coulomb coefficient mu (>= 0)
  /// Penalty stiffness relative to the stiffest node's bond stiffness (> 0); the stable step is
  /// divided by sqrt(1 + stiffness) when a scene has tools.
  double stiffness = 0.5;
  /// > 0: a free rigid body of this mass [kg], moved by the reaction of its contact forces from
  /// `velocity` at t = 0 (translation only); 0: the motion is prescribed (constant velocity).
  double mass = 0.0;
};

/// Initial conditions, applied before the first stage.
struct Initial {
  /// u = displacement_gradient * (X - center): e.g. a homogeneous preload. 3x3 row-major.
  std::array<double, 9> displacement_gradient{};
  /// v = velocity_gradient * (X - center). 3x3 row-major [1/s].
  std::array<double, 9> velocity_gradient{};
  Vec3 center{0, 0, 0};  ///< [m]
  /// Out-of-plane seed of example 7.1: u_z += A sin(2 pi x/Lx) sin(2 pi y/Ly) (a wavelength of 0
  /// drops its factor). amplitude 0 = no seed.
  double seed_amplitude = 0.0;  ///< A [m]
  double seed_wavelength_x = 0.0;  ///< Lx [m]
  double seed_wavelength_y = 0.0;  ///< Ly [m]
  SourceLoc gradient_where, seed_where;  ///< where displacement_gradient and seed.amplitude were given
};

enum class StageKind {
  Dynamic,      ///< explicit velocity Verlet over a duration
  QuasiStatic,  ///< static equilibrium by PETSc SNES with load stepping (no time passes)
  Release,      ///< break the bonds crossing named cracks, velocities set to zero (no time passes)
};

/// A velocity or displacement given to a named boundary by one stage.
struct BoundaryValue {
  std::string boundary;  ///< name of an entry of Scene::boundaries
  Vec3 value{0, 0, 0};
};

struct Stage {
  std::string name;
  SourceLoc where;
  StageKind kind = StageKind::Dynamic;
  // Dynamic stages: duration or steps (exactly one of them).
  double duration = 0.0;               ///< simulated time [s] (> 0); 0 when steps is given
  std::optional<long> steps;           ///< number of steps (1 .. kMaxStageSteps)
  std::optional<double> dt;            ///< time step [s]; default safety_factor * stable bound
  double safety_factor = 0.7;          ///< (0, 1]
  std::optional<SourceLoc> safety_factor_where;  ///< where safety_factor was given, if it was
  bool allow_unstable_dt = false;      ///< accept a dt above the stable bound
  double damping = 0.0;                ///< mass-proportional viscous damping alpha [1/s] (>= 0)
  /// Constant velocity of named boundaries during this stage (replaces their scene velocity and
  /// ramp for the stage) [m/s].
  std::vector<BoundaryValue> boundary_velocity;
  // Quasi-static stages.
  /// Displacement of named boundaries reached at the end of the stage, added to where they are
  /// at its start (prescribed components only) [m]. Boundaries not named keep their position.
  std::vector<BoundaryValue> displacements;
  /// Affine part of the same: constrained components also move by H (X - initial.center) over the
  /// stage (3x3 row-major, dimensionless; e.g. a homogeneous stretch of boundary bands).
  std::array<double, 9> displacement_gradient{};
  long load_steps = 10;         ///< initial number of load increments (adaptive afterwards)
  long max_load_steps = 1000;   ///< increments, cut-backs included, before giving up
  double max_load_step = 1.0;   ///< largest increment, a fraction of the stage's load in (0, 1]
  bool in_plane = true;         ///< membranes: out-of-plane components held where they are
  /// The Newton step's operator: the assembled tangent (also the preconditioner's matrix), the
  /// residual's directional difference with the assembled tangent, reassembled only when it stops
  /// paying, as the preconditioner's matrix (-snes_mf_operator), or differences alone (-snes_mf).
  enum class Jacobian { Assembled, MfOperator, MatrixFree };
  Jacobian jacobian = Jacobian::MfOperator;
  double jacobian_shift = 1e-8; ///< regularization of the tangent's diagonal (relative; not of the residual)
  /// Prescribed components: no unknowns of the Newton system (nodes held in all components drop
  /// out; flat membranes in an in_plane stage keep 2 per node), or unknowns held by scaled rows.
  enum class Prescribed { Eliminated, ScaledRows };
  Prescribed prescribed = Prescribed::Eliminated;
  long max_break_passes = 100;  ///< re-equilibrations per increment while bonds keep breaking
  // Release stages.
  std::vector<std::string> cracks;  ///< names of entries of Scene::cracks broken by this stage
};

/// Instability detectors of explicit stages (checked whenever energies, frames or checkpoints are
/// written, and every 20 steps).
struct Stability {
  /// Stop when |E(t) - E(0)| exceeds this fraction of the energy scale (E: kinetic + strain +
  /// dissipated - external work). 0 disables.
  double energy_error = 0.05;
  /// Stop when a node moves more than this fraction of its body's grid spacing in one step (a stable
  /// step moves a node by at most about safety_factor * (material speed / wave speed) spacings).
  double motion_per_step = 1.0;
};

/// The datasets a frame can hold, in the order frames hold them.
inline const std::vector<std::string>& frame_field_names() {
  static const std::vector<std::string> names{"position", "displacement", "velocity", "damage", "strain_energy_density"};
  return names;
}

struct Output {
  SourceLoc where;
  int frames = 20;             ///< HDF5 frames over the whole run (>= 1; first and last included)
  int series_every = 10;       ///< CSV energy row every N steps (>= 1)
  /// The frames' datasets (of frame_field_names, in that order). Without position the frames'
  /// geometry is the reference positions.
  std::vector<std::string> fields = frame_field_names();
  bool write_velocity = true;  ///< velocity among the fields (the scene key `velocity` of earlier scenes)
  long node_stride = 1;        ///< frames hold every node_stride-th node in natural order (>= 1)
  std::optional<std::array<Vec3, 2>> region;  ///< and only nodes in this box (reference positions)
  bool single_precision = false;  ///< frames' fields as float32 (never checkpoints)
  bool check_free_space = true;   ///< refuse a run whose predicted output exceeds the free space
  bool has_field(const std::string& f) const { return std::find(fields.begin(), fields.end(), f) != fields.end(); }
  bool selects_nodes() const { return node_stride > 1 || region.has_value(); }
  double progress_seconds = 2.0;  ///< wall seconds between progress lines (0: every check)
  long checkpoint_every_steps = 0;         ///< checkpoint every N steps (0: not by step count)
  double checkpoint_every_seconds = 900.0; ///< checkpoint every T wall seconds (0: not by time)
};

/// Which pairs of fiber nodes a long-range rule applies to (Silling & Bobaru eq. 34: the
/// coefficients may depend on the pair, symmetrically). Nodes of one segment never interact.
enum class PairKind {
  AdjacentSegments,  ///< one fiber, segments k and k +- 1
  DistantSegments,   ///< one fiber, segments two or more apart
  OtherFibers,       ///< nodes of different fiber bodies
  Segments,          ///< one fiber, two particular segments (the rule's `segments`)
};

struct PairRule {
  SourceLoc where;
  PairKind between = PairKind::AdjacentSegments;
  double alpha = 0.0;  ///< repulsive coefficient of (a/y)^12 [J/m^6] (>= 0)
  double beta = 0.0;   ///< attractive coefficient of (a/y)^6 [J/m^6] (< 0: a repulsive tail)
  double cutoff = 0.0; ///< the rule's own largest interacting distance [m]; 0: the section's cutoff
  /// between == Segments: the two segments (indices along each fiber from 0), different.
  std::int32_t segments[2] = {0, 0};
  SourceLoc segments_where;  ///< where `segments` was given, and its key path (setup's checks)
  std::string segments_key;
  /// The cutoff in effect: the rule's own, else the section's.
  double cutoff_or(double section_cutoff) const { return cutoff > 0 ? cutoff : section_cutoff; }
};

/// Long-range forces between fiber nodes, w2(y) = alpha (a/y)^12 - beta (a/y)^6 on the current
/// distance y (eqs. 32-36), never damaged, with their own horizon (cutoff). Pairs closer than
/// `exclusion` in the reference configuration (neighbours in one continuous body) do not interact.
struct LongRange {
  SourceLoc where;
  double length = 0.0;     ///< a [m] (> 0)
  double cutoff = 0.0;     ///< largest current distance of an interacting pair [m] (> 0), unless a rule sets its own
  double exclusion = 0.0;  ///< [m] (>= 0)
  SourceLoc exclusion_where;  ///< where `exclusion` was given (empty file: the default, the largest fiber horizon)
  /// A segments rule applies to its pair of segments whatever its place; otherwise the first rule
  /// of a pair's kind wins; a pair no rule matches does not interact.
  std::vector<PairRule> pairs;
};

struct Scene {
  std::string file;         ///< path it was read from ("<default scene>" for the embedded one)
  std::string name;         ///< short identifier
  std::string description;  ///< free text
  std::vector<Material> materials;
  std::vector<Body> bodies;
  std::vector<Crack> cracks;
  std::vector<Boundary> boundaries;
  std::vector<Tool> tools;
  std::optional<LongRange> long_range;
  Initial initial;
  std::vector<Stage> stages;
  Stability stability;
  Output output;

  const Material& material(const std::string& name) const;  ///< InputError if unknown
  int material_index(const std::string& name) const;        ///< -1 if unknown
  /// True when a release stage names the crack (it is then not broken at the start).
  bool released_later(const std::string& crack) const;
};

/// Most steps one dynamic stage may take, given as steps or as duration / dt.
inline constexpr long kMaxStageSteps = 1000000000;
/// Most YAML values (scalars, lists, maps) one scene may hold: the reader keeps about 0.5 kB
/// per value on every rank, so the limit is checked while the text is scanned, before any is kept.
inline constexpr long kMaxSceneValues = 1000000;

/// Polled by the scene reader while it scans long texts: true once the reading should stop
/// (the reader then throws StopRequested). Empty: never.
using StopCheck = std::function<bool()>;

/// Command-line override "path.to.key=value"; value is parsed as YAML (scalars, [a, b], {k: v}).
/// Map entries by key (bodies.sheet.spacing); list entries by index (stages.0.duration) or by
/// their name (boundaries.top.velocity). A stage's steps and duration exclude each other: an
/// override of one drops the other when the file gave it.
struct Override {
  std::string path;
  std::string value;
};

/// Read, override and validate a scene. `text` is the YAML document, `file` its name for
/// messages. Throws InputError with "file:line: a.b.c: expected ..., got ..." on the first
/// problem found ("--set: a.b.c: ..." for overridden values). Identical on every rank.
Scene parse_scene(const std::string& text, const std::string& file,
                  const std::vector<Override>& overrides = {}, const StopCheck& stop = {});

/// Read a scene file (InputError if it cannot be read).
Scene load_scene(const std::string& path, const std::vector<Override>& overrides = {},
                 const StopCheck& stop = {});

/// The embedded default scene (example 7.1 at demo resolution), as YAML text.
const std::string& default_scene_text();

/// Fully resolved scene as YAML (every key, defaults filled in). parse_scene(emit_scene(s))
/// emits the same text again (round trip). `derived` lines are appended as YAML comments.
std::string emit_scene(const Scene& s, const std::vector<std::string>& derived = {});

}  // namespace peri
