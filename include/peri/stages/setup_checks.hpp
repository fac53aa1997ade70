// The setup's checks: derived quantities that extreme scene values would make overflow, vanish
// or grow without bound (node masses, energy scales, the stable step, step counts, motion per
// step, a tool's overlap with the body at t = 0, a sphere's wall stress) are refused with
// InputError naming the keys that made them and the bound; scenes that run but are likely not
// what was meant get a warning (rank 0). Each verdict is the same on every rank (global data, or
// reductions), and all come before anything is written. docs/user/limits.md lists them.
#pragma once
#include <mpi.h>

#include <cstdint>
#include <vector>

#include "peri/bonds/bonds.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/models/law.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

struct Problem;
struct StagePlan;

/// StopRequested on every rank when a stop signal reached any rank during the setup. Collective.
void stop_point(MPI_Comm comm);
/// Warns (rank 0) of a horizon that gives nodes very large families.
void warn_large_families(const Scene& scene, const SizeEstimate& e, int rank);
/// Warns (rank 0) of boundaries that share nodes but move them differently. regions: per
/// boundary, its nodes (natural ids, ascending).
void warn_overlapping_boundaries(const Scene& scene, const std::vector<std::vector<std::int64_t>>& regions, int rank);
/// Warns (rank 0) of a point-cloud body whose points' median volume^(1/3) is more than 1.5 times
/// its spacing or less than 1/1.5 of it: the horizon and the calibration take the spacing as the
/// points' distance, so such a body is far stiffer or softer than its material.
void warn_cloud_spacing(const Scene& scene, int rank);

/// Warns (rank 0) of each dynamic stage that gives both dt and safety_factor: the step is dt, and
/// safety_factor is not used.
void warn_unused_safety_factor(const Scene& scene, int rank);

/// Warns (rank 0) of a seed whose wavelength is below two spacings of the finest body: the nodes
/// sample it aliased (at one spacing every grid node lies on a zero).
void warn_aliased_seed(const Scene& scene, int rank);
/// Warns (rank 0) of two bodies whose nodes come within a horizon of each other: bodies do not
/// bond to each other, so a piece made of two bodies comes apart at their seam. Pairs of fibers
/// that take part in long-range pairs (which act between bodies) are not warned of.
void warn_touching_bodies(const Scene& scene, const Nodes& nodes, const CellList& cells, int rank);
/// Warns (rank 0) of a long-range rule whose contact (pair_contact_steps), with the bonds'
/// stiffness, leaves a dynamic stage's step less margin than the default safety_factor
/// (PairContactStep::exceeded_by): the run would likely go unstable once nodes meet.
void warn_pair_contact(const Scene& scene, const StagePlan& plan, int rank);
/// Every node within 1e9 spacings of the origin, where positions keep a spacing to 1e-7; a
/// warning (rank 0) beyond 1e6 spacings.
void check_node_positions(const Scene& scene, const Nodes& nodes, int rank);
/// After the partition (rank 0): a warning for each -partition_* PETSc option nobody read, a
/// misspelling such as -partition_methd, which PETSc would otherwise pass over in silence.
void warn_unused_partition_options(int rank);

/// Per body after the bonds are built (collective): a body none of whose nodes has a bond is
/// refused (InputError naming it and its horizon); nodes without a bond in a body with bonds are
/// warned of on rank 0 (how many, and where the first is). Lattice bodies are not checked.
void check_body_bonds(const Scene& scene, const std::vector<BodyGeometry>& bodies, const Domain& d, MPI_Comm comm,
                      int rank);

/// A polygon crack lying in the plane of a flat sheet (which would break every bond within its
/// area, not cut along a line): InputError naming the crack and the sheet.
void check_polygon_cracks(const Scene& scene, const Nodes& nodes);
/// Node measures, masses and each body's energy scale within the doubles' range (global node
/// arrays). laws, density: per body.
void check_node_masses(const Scene& scene, const Nodes& nodes, const std::vector<BondLaw>& laws,
                       const std::vector<double>& density);
/// The run's stable step from each body's on this rank (dt_body; dt_undamped: without the bond
/// dashpots), refused when absurdly small or not finite. Collective.
double check_stable_step(const Problem& p, const std::vector<double>& dt_body, const std::vector<double>& dt_undamped);
/// Stage s's damping and step count with time steps dt.
void check_stage(const Scene& scene, std::size_t s, double dt, double dt_stable);
/// The initial state (initial conditions applied to the problem's state), boundaries and tools:
/// displacements, tools clear of the body, motion per step, sphere wall stress. Collective.
void check_initial_state(const Problem& p);

}  // namespace peri
