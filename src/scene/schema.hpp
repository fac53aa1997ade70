// The scene's schema: every map's keys (name, required, the "missing required key" message) with
// their documentation (unit, default, meaning), the names of the enums' values, and the key
// tables as documentation (scene/describe.hpp: --describe-keys, docs/user/scene-reference.md).
//
// Each key's documentation is for --describe-keys and docs/user/scene-reference.md: a key added
// here without a meaning makes --describe-keys fail, and one whose documentation differs from the
// reference page fails the ctest scene_reference.
#pragma once
#include <map>
#include <string>

#include "peri/scene/located_yaml.hpp"
#include "peri/scene/writer.hpp"

namespace peri::scene_detail {

/// Prefix of the default names of a list's unnamed entries ("crack0", "stage1"); empty when the
/// entries have no default name.
std::string default_name_prefix(const std::string& list_path);

// Each key: name, required, what (the "missing required key" message), and its documentation for
// --describe-keys and docs/user/scene-reference.md (scene/describe.hpp): unit, default (what an
// absent key means; empty: no value) and meaning. A key added here without a meaning makes
// --describe-keys fail, and one whose documentation differs from the reference page fails the
// ctest scene_reference.

inline const Keys kSceneKeys = {
    {.name = "name", .required = true, .what = "scene name, 1 to 64 characters of A-Z a-z 0-9 _ - not starting with -",
     .doc = "the scene's name, 1 to 64 characters of A-Z a-z 0-9 _ -, not starting with -; the default output "
            "directory is `out/<name>`"},
    {.name = "description", .fallback = "empty", .doc = "free text"},
    {.name = "materials", .required = true, .what = "map of material name to material",
     .doc = "map of material name to material (`materials.<name>`); at least one"},
    {.name = "bodies", .required = true, .what = "map of body name to body",
     .doc = "map of body name to body (`bodies.<name>`); at least one"},
    {.name = "cracks", .fallback = "none",
     .doc = "list of pre-cracks (`cracks[i]`): slits, which cut sheets and fibers (a scene whose bodies are all "
            "solids refuses them), and plane polygons, which cut every body"},
    {.name = "boundaries", .fallback = "none",
     .doc = "list of regions with prescribed velocity components, clamps included (`boundaries[i]`)"},
    {.name = "tools", .fallback = "none", .doc = "list of rigid tools acting by contact (`tools[i]`)"},
    {.name = "long_range", .doc = "long-range pair forces between fiber nodes (`long_range`)"},
    {.name = "initial", .fallback = "at rest, undeformed", .doc = "the state before the first stage (`initial`)"},
    {.name = "stages", .required = true, .what = "list of stages, at least one",
     .doc = "list of stages run in order (`stages[i]`); at least one of kind dynamic"},
    {.name = "stability", .fallback = "the defaults below", .doc = "instability detectors of dynamic stages (`stability`)"},
    {.name = "output", .fallback = "the defaults below", .doc = "what is written and how often (`output`)"},
};

inline const Keys kMaterialKeys = {
    {.name = "model", .required = true, .what = "force law: membrane, pmb, marder, or another registered law",
     .doc = "the material model, one of the values of model listed with this section; it decides which other "
            "keys the material takes"},
    {.name = "density", .required = true, .what = "mass density, kg/m^3", .unit = "kg/m^3",
     .doc = "rho > 0; of the sheet's material for membranes, spheres and lattices (mass per area: rho h)"},
    {.name = "wave_speed", .unit = "m/s", .fallback = "one of four",
     .doc = "stiffness, exactly one of wave_speed, bulk_modulus, youngs_modulus, micromodulus: the small-strain "
            "longitudinal wave speed c_l > 0 (membranes, spheres, solids: mu = rho c_l^2 / 3; fibers: the bar "
            "speed, E = rho c_l^2)"},
    {.name = "bulk_modulus", .unit = "Pa", .fallback = "one of four",
     .doc = "K > 0: the in-plane modulus 2 mu of membranes and spheres, the 3D modulus 5 mu / 3 of solids, read "
            "as the bar modulus E for fibers"},
    {.name = "youngs_modulus", .unit = "Pa", .fallback = "one of four",
     .doc = "E > 0: 8 mu / 3 for membranes and spheres, 5 mu / 2 for solids, E itself for fibers"},
    {.name = "micromodulus", .unit = "J/m^6, N/m^6", .fallback = "one of four",
     .doc = "the micromodulus c > 0 itself (membrane law J/m^6, pmb N/m^6)"},
    {.name = "influence", .fallback = "constant",
     .doc = "g(xi) of eq. (13): `constant` (g = 1) or `conical` (g = 1 - xi/delta)"},
    {.name = "critical_stretch", .fallback = "none: bonds never break",
     .doc = "membrane: the stretch lambda_0 >= 1 + 1e-10 at which a bond breaks (eqs. 11, 22); pmb: the critical "
            "bond strain s_0 >= 1e-10 (a bond breaks at s = lambda - 1 >= s_0; the papers' \"critical stretch\" "
            "0.1, 0.03, 0.3 of examples 7.3-7.6 is this strain)"},
    {.name = "critical_stretch_at_horizon", .fallback = "= critical_stretch",
     .doc = "Lambda_delta of eq. (29): the critical value at xi = delta, critical_stretch being the one at xi = 0, "
            "linear in between; needs critical_stretch; the same limits"},
    {.name = "tip_advance", .unit = "m", .fallback = "none: bonds break wherever they reach the failure test",
     .doc = "the paper's incremental crack-tip advance (section 7.4): a bond may break only if one of its ends "
            "lies within this distance r > 0 of a crack-tip node, a damaged node whose family holds no node "
            "damaged later; without damage nothing breaks (crack from a pre-crack or notch); needs "
            "critical_stretch; r at most the horizon (checked at setup)"},
    {.name = "tip_advance_tips", .fallback = "family",
     .doc = "which damaged nodes are the crack tips of tip_advance: `family`, each damaged node whose family "
            "holds no node damaged later (a tip for every crack; a branch that starts keeps growing); `body`, the "
            "nodes of the body damaged at its latest break time (one tip for the whole body: a crack that stops "
            "breaking while another breaks stays arrested); needs tip_advance"},
    {.name = "hardening", .fallback = "none",
     .doc = "power-law hardening of eq. (16), `{coefficient: c', exponent: n}` (`materials.<name>.hardening`); runs "
            "in the portable bond loop"},
    {.name = "mooney_rivlin_a", .unit = "J/kg", .fallback = "required",
     .doc = "a of W/rho = a [J1 + b J2] (Marder eq. 6), > 0"},
    {.name = "mooney_rivlin_b", .fallback = "required",
     .doc = "b; with the body's spacing Delta and the cutoff u_s: b < 2 and -2 Delta/u_s < b < Delta/u_s (the "
            "unstretched lattice is stable)"},
    {.name = "cutoff", .unit = "m", .fallback = "required", .doc = "u_s of Marder eqs. (31), (32), > 0"},
    {.name = "fracture_separation", .unit = "m", .fallback = "required",
     .doc = "u_c of Marder eqs. (31), (32), > Delta + u_s (checked at the body's spacing)"},
    {.name = "breaking", .fallback = "irreversible",
     .doc = "`irreversible`: a bond reaching u_c is cut for good with its three-body terms, and the energy removed "
            "is booked as dissipated; `reversible`: the paper's functional as written (f constant beyond u_c, h "
            "smooth; bonds act again below u_c; pre-cracks stay cut)"},
    {.name = "kelvin_viscosity", .unit = "m^2/s", .fallback = "0 (none)",
     .doc = "kinematic viscosity nu >= 0 of Kelvin-Voigt dashpots on the intact bonds, whose small-strain viscous "
            "stress is rho nu (2 D + (tr D) I) (D: the strain rate); their work is booked as dissipated energy. "
            "marder: force eta (e_ij . (v_j - v_i)) e_ij, eta = 8 m nu / (3 Delta^2); the peridynamic laws: each "
            "bond's force gains tau C (e_ij . (v_j - v_i)), C its reference stiffness, tau = rho nu / mu (a wave "
            "of angular frequency omega decays at tau omega^2 / 2); not for fibers. Lowers the stable step"},
    {.name = "stiffening_onset", .unit = "m", .fallback = "none",
     .doc = "u_g: bonds longer than u_g stiffen beyond the Mooney-Rivlin law, pair energy (A/36) (u - u_g)^4 / w^2 "
            "(not in the paper); Delta + u_s <= u_g < u_c, given with stiffening_width"},
    {.name = "stiffening_width", .unit = "m", .fallback = "none",
     .doc = "w > 0: at u = u_g + w a bond's stiffness is twice the Mooney-Rivlin pair stiffness A/3"},
    {.name = "break_separation", .unit = "m", .fallback = "fracture_separation",
     .doc = "u_b: bonds break when their length reaches u_b, Delta + u_s < u_b <= u_c, while f and the switch h keep "
            "u_c (not in the paper): a breaking stretch close to the far field's without the switch changing it"},
};

inline constexpr const char* kMarderKeys[] = {"mooney_rivlin_a", "mooney_rivlin_b", "cutoff", "fracture_separation", "breaking",
                                   "stiffening_onset", "stiffening_width",
                                   "break_separation"};

inline const Keys kHardeningKeys = {
    {.name = "coefficient", .required = true, .what = "hardening coefficient c', >= 0", .unit = "J/m^6",
     .doc = "c' >= 0 of the added energy c' (lambda^n - n lambda + n - 1) g (eq. 16, written so that the "
            "reference state is stress-free)"},
    {.name = "exponent", .required = true, .what = "hardening exponent n, in (1, 100]", .doc = "1 < n <= 100 (lambda^n stays a finite double)"},
};

/// The keys of every body; each kind's own keys are its module's (scene/body_kind.hpp).
inline const Keys kBodyKeys = {
    {.name = "kind", .fallback = "membrane",
     .doc = "the body kind, one of the values of kind listed with this section; it decides which other keys the "
            "body takes (a key of another kind is refused, naming the kind that takes it)"},
    {.name = "material", .required = true, .what = "name of a material",
     .doc = "name of an entry of materials; a lattice body needs a marder material and a marder material a "
            "lattice body"},
};

inline const Keys kLongRangeKeys = {
    {.name = "length", .required = true, .what = "a of w2 = alpha (a/y)^12 - beta (a/y)^6, m", .unit = "m",
     .doc = "a > 0 of w2(y) = alpha (a/y)^12 - beta (a/y)^6 (eqs. 32-36) on the current distance y"},
    {.name = "cutoff", .required = true, .what = "largest interacting distance, m", .unit = "m",
     .doc = "largest current distance of an interacting pair, > 0, for every rule without a cutoff of its own; "
            "the energy booked is w2(y) - w2(cutoff); "
            "refused at setup when it takes in more than 5000 pairs per node or 2e8 in all at the reference "
            "positions"},
    {.name = "exclusion", .unit = "m", .fallback = "the largest fiber horizon",
     .doc = ">= 0: pairs closer than this in the reference configuration (neighbours in one continuous body) do "
            "not interact; refused at setup when it holds every pair a rule applies to (the rule would never act)"},
    {.name = "pairs", .required = true, .what = "list of pair rules {between, alpha, beta}",
     .doc = "non-empty list of rules (`long_range.pairs[i]`); a segments rule applies to its pair of segments, "
            "otherwise the first rule of a pair's kind applies; nodes of one segment never interact, a pair no "
            "rule names does not interact"},
};

inline const Keys kPairRuleKeys = {
    {.name = "between", .required = true, .what = "adjacent_segments, distant_segments, other_fibers or segments",
     .doc = "`adjacent_segments` (one fiber, segments k and k +- 1), `distant_segments` (one fiber, segments two or "
            "more apart), `other_fibers` (different fiber bodies, or different fibers of one network) or `segments` "
            "(the two segments named by segments, in every fiber that has both)"},
    {.name = "segments", .fallback = "required with between: segments",
     .doc = "[i, j]: two different segment indices, counted from 0 at each fiber's first node (every path of a "
            "fiber body, every fiber of a network, counts its own); the rule applies to the nodes of segments i "
            "and j of one fiber, never across fibers, and takes precedence over the kind rules for that pair "
            "wherever it stands in the list (the first segments rule of a pair wins); an index must name a "
            "segment of some fiber (checked at setup, against the segment count)"},
    {.name = "alpha", .required = true, .what = "coefficient of (a/y)^12, J/m^6", .unit = "J/m^6",
     .doc = "coefficient of (a/y)^12, >= 0"},
    {.name = "beta", .required = true, .what = "coefficient of (a/y)^6, J/m^6 (negative: repulsive tail)",
     .unit = "J/m^6", .doc = "coefficient of (a/y)^6, any sign (negative: a repulsive 1/y^6 tail)"},
    {.name = "cutoff", .unit = "m", .fallback = "long_range.cutoff",
     .doc = "> 0: the largest current distance at which this rule's pairs interact (energy shifted by w2 at it); "
            "the neighbour list reaches the largest cutoff in effect"},
};

inline const Keys kCrackKeys = {
    {.name = "name", .fallback = "crack<i>", .doc = "the crack's name, which release stages use"},
    {.name = "from", .what = "start point [x, y, z], m", .unit = "m", .fallback = "required unless polygon",
     .doc = "a slit's one end [x, y, z]"},
    {.name = "to", .what = "end point [x, y, z], m", .unit = "m", .fallback = "required unless polygon",
     .doc = "the slit's other end [x, y, z], different from from. At the start every bond of a membrane, lattice, "
            "fiber or sphere whose reference segment meets the slit in the xy plane is broken (solids are not cut), "
            "unless a release stage names the crack"},
    {.name = "polygon", .what = "corners [[x, y, z], ...], m", .unit = "m", .fallback = "- (a slit)",
     .doc = "instead of from and to: at least 3 corners, in order, of a convex polygon in one plane (to 1e-9 of its "
            "size), anywhere in space. At the start every bond of any body (solids and curved sheets included) "
            "whose reference segment meets the closed polygon in space is broken, unless a release stage names "
            "the crack"},
};

inline const Keys kBoundaryKeys = {
    {.name = "name", .required = true, .what = "boundary name, unique", .doc = "unique; stages name boundaries by it"},
    {.name = "region", .required = true, .what = "box {min: [x, y, z], max: [x, y, z]}",
     .doc = "the nodes it holds (`boundaries[i].region`); a node in several regions follows the last boundary "
            "listed"},
    {.name = "velocity", .unit = "m/s", .fallback = "[0, 0, 0] (a clamp)",
     .doc = "prescribed velocity [vx, vy, vz] of the selected components"},
    {.name = "components", .fallback = "[x, y, z]",
     .doc = "non-empty list of distinct letters from x, y, z: the components prescribed; the others move freely (a nonzero velocity or stage value in them is refused)"},
    {.name = "ramp_time", .unit = "s", .fallback = "0", .doc = "the velocity rises linearly from 0 over this time, >= 0"},
};

inline const Keys kToolKeys = {
    {.name = "name", .required = true, .what = "tool name, unique", .doc = "unique; names the tool's columns in series.csv"},
    {.name = "kind", .required = true, .what = "tool kind: cylinder or sphere",
     .doc = "`cylinder` (a rigid cylinder of infinite length, axis along z) or `sphere` (a rigid sphere); tools act "
            "on every node by a penalty force with Coulomb friction, in dynamic stages (one that touches the body "
            "at the end of a quasistatic stage stops the run), and must start clear of the bodies"},
    {.name = "radius", .required = true, .what = "cylinder radius, m", .unit = "m", .doc = "> 0"},
    {.name = "center", .required = true, .what = "axis position [x, y] at t = 0, m", .unit = "m",
     .doc = "cylinder: axis position [x, y] at t = 0; sphere: centre [x, y, z] at t = 0"},
    {.name = "velocity", .unit = "m/s", .fallback = "at rest",
     .doc = "constant velocity (with `mass`: the velocity at t = 0): cylinder [vx, vy], sphere [vx, vy, vz]"},
    {.name = "friction", .fallback = "0",
     .doc = "Coulomb coefficient mu >= 0; friction opposes sliding over the tool's surface, along a cylinder's "
            "axis too"},
    {.name = "stiffness", .fallback = "0.5",
     .doc = "penalty stiffness relative to the stiffest node's bond stiffness, in (0, 1e6]; the stable step of a "
            "scene with tools is divided by sqrt(1 + largest stiffness)"},
    {.name = "mass", .unit = "kg", .fallback = "none: prescribed motion",
     .doc = "in (0, 1e30]: a free rigid body of this mass, started at `velocity` and moved by the reaction of its contact "
            "forces (translation only: friction's torque does not spin it); its velocity is in series.csv and the "
            "kinetic energy it gives the bodies is booked as external work"},
};

inline const Keys kRegionKeys = {
    {.name = "min", .what = "lower corner [x, y, z], m", .unit = "m", .fallback = "required unless group",
     .doc = "lower corner [x, y, z]"},
    {.name = "max", .what = "upper corner [x, y, z], m", .unit = "m", .fallback = "required unless group",
     .doc = "upper corner [x, y, z], >= min in every component; the region holds the nodes whose reference "
            "position lies in the closed box, at least one"},
    {.name = "body", .fallback = "every body", .doc = "name of a body: only its nodes"},
    {.name = "group", .fallback = "- (the box)",
     .doc = "instead of min and max: the name of a physical group of the mesh of `body` (a mesh body, required "
            "then): the region holds the group's nodes that are the body's (any dimension the name is given to)"},
};

inline const Keys kInitialKeys = {
    {.name = "displacement_gradient", .fallback = "zeros",
     .doc = "3 x 3 matrix G, rows as lists: u = G (X - center) (`[[0, 0, 0], [0, 0.08, 0], [0, 0, 0]]` stretches y "
            "by 8%); may move a node by at most 100 times its body's extent, and shorten no bond below 0.01 of its length "
            "(F = I + G collapses no body)"},
    {.name = "velocity_gradient", .unit = "1/s", .fallback = "zeros", .doc = "3 x 3 matrix L: v = L (X - center)"},
    {.name = "center", .unit = "m", .fallback = "[0, 0, 0]", .doc = "the fixed point of both fields"},
    {.name = "seed", .fallback = "none",
     .doc = "an out-of-plane seed `{amplitude, wavelength}` (`initial.seed`)"},
};

inline const Keys kSeedKeys = {
    {.name = "amplitude", .required = true, .what = "seed amplitude, m", .unit = "m",
     .doc = "A >= 0 of u_z += A sin(2 pi x / Lx) sin(2 pi y / Ly) at the reference position (x, y)"},
    {.name = "wavelength", .unit = "m", .fallback = "[0, 0]",
     .doc = "[Lx, Ly], each >= 0; a wavelength of 0 drops its factor"},
};

inline const Keys kStageKeys = {
    {.name = "name", .fallback = "stage<i>", .doc = "the stage's name"},
    {.name = "kind", .fallback = "dynamic",
     .doc = "`dynamic` (explicit velocity Verlet), `quasistatic` (static equilibrium by PETSc SNES; no time passes) "
            "or `release` (break the bonds crossing named cracks; no time passes); a key of another kind is "
            "refused"},
    {.name = "duration", .unit = "s", .fallback = "required unless steps",
     .doc = "simulated time > 0, covered exactly by n = ceil(duration / dt) steps of duration / n"},
    {.name = "steps", .fallback = "none",
     .doc = "instead of duration: the number of steps, an integer in 1 .. 1e9, each of dt (through --set one "
            "replaces the other given in the file)"},
    {.name = "dt", .unit = "s", .fallback = "safety_factor x the stable bound",
     .doc = "time step > 0; refused above the stable bound (the message gives it) unless allow_unstable_dt; "
            "duration / dt at most 1e9"},
    {.name = "safety_factor", .fallback = "0.7", .doc = "in (0, 1]: dt = safety_factor x the stable bound; not used where dt is given (a warning says so)"},
    {.name = "allow_unstable_dt", .fallback = "false",
     .doc = "run a dt above the stable bound anyway (the stability detectors still watch)"},
    {.name = "damping", .unit = "1/s", .fallback = "0",
     .doc = "mass-proportional viscous damping alpha >= 0 (force density -rho alpha v), alpha dt / 2 <= 1; its "
            "work is booked as dissipated energy"},
    {.name = "boundary_velocity", .unit = "m/s", .fallback = "the boundaries' own",
     .doc = "`{boundary: [vx, vy, vz], ...}`: a constant velocity of named boundaries during the stage, replacing "
            "their velocity and ramp_time"},
    {.name = "displacements", .unit = "m", .fallback = "none",
     .doc = "`{boundary: [dx, dy, dz], ...}`: displacement of named boundaries (their prescribed components) "
            "reached at the stage's end, added to where they are at its start; unnamed boundaries stay put"},
    {.name = "displacement_gradient", .fallback = "zeros",
     .doc = "3 x 3 matrix H: prescribed components also move by H (X - initial.center) over the stage "
            "(homogeneous loading of boundary bands)"},
    {.name = "load_steps", .fallback = "10",
     .doc = "initial number of load increments, an integer in 1 .. 1e6; a diverged increment is halved, one of at "
            "most 4 Newton iterations grows 1.5 x"},
    {.name = "max_load_steps", .fallback = "1000",
     .doc = "increments, cut-backs included, before the stage fails (exit status 3); an integer in 1 .. 1e8, at "
            "least load_steps"},
    {.name = "max_load_step", .fallback = "1",
     .doc = "largest load increment as a fraction of the stage's load, a number in (0, 1]: the adaptive growth "
            "stops there; with load_steps = 1 / max_load_step the increments are uniform (one row of "
            "quasistatic.csv each) unless Newton diverges"},
    {.name = "in_plane", .fallback = "true",
     .doc = "hold membranes' out-of-plane components where they are (a flat membrane has no out-of-plane "
            "stiffness at zero tension)"},
    {.name = "jacobian", .fallback = "mf_operator",
     .doc = "`mf_operator`: the Krylov solver's operator is the residual's directional difference (matrix-free) "
            "and the assembled bond tangent builds the preconditioner, reassembled only when a "
            "linear solve needs more than twice the iterations of the first after the last assembly, or bonds "
            "broke; `assembled`: the tangent is assembled at every Newton iteration and is the operator too; "
            "`matrix_free`: finite-difference Newton-Krylov, no preconditioner"},
    {.name = "jacobian_shift", .fallback = "1e-8",
     .doc = "in [0, 1): shift of the tangent's diagonal relative to the mean nodal stiffness; the residual is "
            "unchanged, so converged states are exact equilibria"},
    {.name = "prescribed", .fallback = "eliminated",
     .doc = "`eliminated`: prescribed components are no unknowns of the Newton system (nodes held in all "
            "components drop out, and where every node's out-of-plane component is held, flat membranes in an "
            "in_plane stage, each node keeps its 2 in-plane ones: block size 2); `scaled_rows`: all 3 components "
            "of every node are unknowns, the prescribed ones held by rows s (u - u_prescribed)"},
    {.name = "max_break_passes", .fallback = "100",
     .doc = "re-equilibrations of one increment while bonds keep breaking, an integer in 1 .. 1e6"},
    {.name = "cracks", .fallback = "required",
     .doc = "non-empty list of names of cracks entries, each released by one stage only; they are not broken at "
            "the start: this stage breaks every intact bond crossing them in the current state and books each "
            "bond's energy as dissipated"},
};


/// Stage keys that only one kind of stage accepts.
inline const std::map<std::string, StageKind> kStageKeyKind = {
    {"duration", StageKind::Dynamic},         {"steps", StageKind::Dynamic},
    {"dt", StageKind::Dynamic},               {"safety_factor", StageKind::Dynamic},
    {"allow_unstable_dt", StageKind::Dynamic}, {"damping", StageKind::Dynamic},
    {"boundary_velocity", StageKind::Dynamic}, {"displacements", StageKind::QuasiStatic},
    {"displacement_gradient", StageKind::QuasiStatic},
    {"load_steps", StageKind::QuasiStatic},   {"max_load_steps", StageKind::QuasiStatic},
    {"max_load_step", StageKind::QuasiStatic},
    {"in_plane", StageKind::QuasiStatic},     {"jacobian", StageKind::QuasiStatic},
    {"jacobian_shift", StageKind::QuasiStatic}, {"max_break_passes", StageKind::QuasiStatic},
    {"prescribed", StageKind::QuasiStatic},
    {"cracks", StageKind::Release},
};

inline const Keys kStabilityKeys = {
    {.name = "energy_error", .fallback = "0.05",
     .doc = ">= 0: stop a dynamic stage when the energy balance error |E - E0| exceeds this fraction of the "
            "largest energy term (at least the energy of a 1e-10 strain of every body) at every series row for 10 "
            "steps or more (a transient, such as a tool's first touch, is let through), or at the run's last row; 0: "
            "off"},
    {.name = "motion_per_step", .fallback = "1",
     .doc = ">= 0: stop when a node with intact bonds moves more than this many grid spacings in one step; 0: off"},
};

inline const Keys kOutputKeys = {
    {.name = "frames", .fallback = "20",
     .doc = "HDF5 frames over the whole run, first and last step included; an integer >= 1 (more than the steps + "
            "1 writes every step, with a warning)"},
    {.name = "series_every", .unit = "steps", .fallback = "10",
     .doc = "a series.csv row (and a crack-tip sample) every N steps, an integer >= 1"},
    {.name = "fields", .fallback = "all five",
     .doc = "the frames' datasets, a non-empty list of `position`, `displacement`, `velocity`, `damage`, "
            "`strain_energy_density`; without `position` the frames' geometry is the reference positions"},
    {.name = "velocity", .fallback = "true",
     .doc = "`false` drops velocity from the fields (the key of earlier scenes; not with fields)"},
    {.name = "node_stride", .fallback = "1",
     .doc = "frames hold every N-th node in natural order (bodies in scene order, grids row by row), an integer >= "
            "1; their natural ids are in `/mesh/natural_id`"},
    {.name = "region", .unit = "m", .fallback = "everywhere",
     .doc = "frames hold only the nodes in this box of reference positions, `{min: [x, y, z], max: [x, y, z]}`; "
            "with node_stride, those of the stride's nodes"},
    {.name = "precision", .fallback = "double",
     .doc = "`double` or `single`: the frames' fields as 64- or 32-bit floats (the mesh and checkpoints are always "
            "double)"},
    {.name = "check_free_space", .fallback = "true",
     .doc = "refuse (exit status 2) a run whose predicted frames, mesh and step-count checkpoints exceed the free "
            "space of the output directory's file system; `--dry-run` prints the prediction"},
    {.name = "progress_seconds", .unit = "s", .fallback = "2",
     .doc = "wall time between progress lines, >= 0 (0: at every check)"},
    {.name = "checkpoint_every_steps", .unit = "steps", .fallback = "0 (off)",
     .doc = "write checkpoint.h5 every N steps, an integer >= 0"},
    {.name = "checkpoint_every_seconds", .unit = "s", .fallback = "900",
     .doc = "write checkpoint.h5 when this much wall time has passed since the last one (rank 0's clock, checked "
            "every 20 steps), >= 0; 0: off"},
};

inline constexpr const char* kStiffnessKeys[] = {"wave_speed", "bulk_modulus", "youngs_modulus", "micromodulus"};

}  // namespace peri::scene_detail
