// What the body kinds' modules share: the horizon keys, the grid sheet's keys and nodes, a box
// key table, and the texts of their messages. Private to src/geometry/kinds/.
#pragma once
#include <cstdint>
#include <string>

#include "peri/core/format.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/scene/body_kind.hpp"
#include "peri/scene/located_yaml.hpp"
#include "peri/scene/writer.hpp"

namespace peri::kinds {

using scene_detail::Key;
using scene_detail::Keys;
using scene_detail::kBoxKeys;
using scene_detail::Map;
using scene_detail::Value;
using scene_detail::Writer;

inline constexpr double kPi = 3.14159265358979323846;

// The horizon of a peridynamic body: horizon_factor (m spacings) or horizon [m].
inline const Key kHorizonFactorKey = {.name = "horizon_factor", .fallback = "3",
                                      .doc = "m of delta = m dx, >= 1; not with horizon"};
inline const Key kHorizonKey = {.name = "horizon", .unit = "m", .fallback = "horizon_factor x spacing",
                                .doc = "delta itself, >= spacing; not with horizon_factor"};
void read_horizon(const Map& m, Body& b);
/// horizon and horizon_factor exclude each other: writes the one in effect.
void emit_horizon(Writer& w, const Body& b);

/// Nodes inside a horizon of m spacings on a grid of dimension d (continuum estimate with the
/// boundary cells): pi (m + 0.71)^2 or 4/3 pi (m + 0.71)^3.
double grid_family(const Body& b, int dimension);

/// A flat sheet on a grid (membranes, lattices): origin, size [Lx, Ly], thickness, spacing (the
/// reader has checked that they are given).
void read_sheet_extent(const Map& m, Body& b);
/// Its nodes at the centres of the grid's cells, rows along x: square (dx by dx cells) or
/// hexagonal (rows dx sqrt(3)/2 apart, odd rows shifted by dx/2); measure cell area x h.
void grid_sheet_nodes(const Body& b, BodyGeometry& g, NodeSink& sink);
/// Nodes of a grid sheet before any is made (a hexagonal grid has 2/sqrt(3) more).
double grid_sheet_count(const Body& b);

/// Number of grid cells along a length (at least one).
std::int64_t count_along(double length, double dx);

/// "bodies.<name>.<key> <value> m" for messages.
std::string key_text(const Body& b, const char* key, double value);

}  // namespace peri::kinds
