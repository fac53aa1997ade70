// Warnings about a scene's geometry that setup gives on rank 0: sheets and fibers too thick for
// their models, meshes that are flat within round-off or plane at a tilt, and slits that cut
// walls of curved sheets far from them in space (a slit is taken in the xy plane).
#pragma once
#include <string>

#include "peri/geometry/discretization.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

struct Problem;

/// Warns (rank 0) of a sheet (membrane, sphere, lattice) thicker than 10 horizons (a lattice: 10
/// spacings), or a fiber whose diameter is: not a membrane or a bar, and most likely a length in
/// mm written as m.
void warn_thick_bodies(const Scene& scene, const Nodes& nodes, int rank);
/// Warns (rank 0) of each triangle mesh made flat (MeshData::flattened): its nodes' z spread by
/// round-off only, now set to one z; and of each plane mesh whose normal is not along z
/// (MeshData::tilted_normal), which runs as a curved sheet.
void warn_flattened_meshes(const Scene& scene, int rank);
/// The warning (rank 0 prints it) for `count` bonds of the curved sheet `body` that slits break
/// farther than its horizon from them in space, up to `farthest` [m]: "<subject> <verb> <count>
/// bonds ... from <from> in space".
void warn_slit_far_walls(const std::string& subject, const char* verb, long long count, const std::string& body,
                         double horizon, const char* from, double farthest);
/// Warns (rank 0) of each slit broken at the start that breaks bonds of a curved sheet farther
/// than its horizon from the slit's segment in space (Domain::crack_far): walls above or below
/// it that it does not touch. Collective.
void warn_far_slit_walls(const Problem& p);

}  // namespace peri
