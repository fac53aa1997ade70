// The incremental crack-tip advance of Silling & Bobaru (2005), section 7.4: "the crack tip was
// permitted to advance only incrementally from its current position at any time". Pure passes over
// a rank's families (no MPI, no PETSc); the caller exchanges the per-node arrays with the ghosts
// between them (stages/tip_advance.hpp).
//
// The rule, for a body whose material sets tip_advance = r (r <= the horizon delta):
//  1. Each node keeps the time it last lost a bond (its break time; -inf while intact). A
//     pre-crack's nodes get the time of the first force evaluation after the cut.
//  2. A crack-tip node is a damaged node whose break time is not exceeded by that of any node of
//     its family: the newest damage within a horizon. A running crack's tip is its newest damage;
//     its flanks behind the tip are not (their neighbours towards the tip broke later); an
//     arrested crack keeps its tip. Break times at or after the current evaluation's time do not
//     count yet (a resumed run's first evaluation sees what the uninterrupted run saw).
//     With tip_advance_tips: body the tip nodes are instead the body's nodes whose break time is
//     the body's latest (before the current evaluation): one tip for the whole body, so a crack
//     that stops breaking while another breaks is arrested for good unless the growing one
//     reaches it.
//  3. A node may break a bond when it lies, in the reference configuration, within r of a tip
//     node (itself included).
//  4. A bond reaching the law's failure test breaks only if one of its two ends may break; else
//     it stays intact and acts as an intact bond (the law without failure). Both ends take the same
//     decision, so the broken flags stay symmetric and the result does not depend on the rank count.
// Without any damaged node nothing may break: a body with the rule cracks only from a pre-crack,
// a notch or a release stage.
#pragma once
#include <cstdint>
#include <vector>

#include "peri/kernels/forces.hpp"

namespace peri {

/// Stamps `time` as the break time of each of `rows` (owned) whose count of broken bonds rose
/// above `count[row]` (updated); appends a row stamped for the first time to `damaged`.
void stamp_breaks(const BondView& v, const std::int32_t* rows, std::size_t n, std::int32_t* count, double* stamp,
                  std::vector<std::int32_t>& damaged, double time);

/// tip[i] for each owned row i of `damaged`: its break time is before `now` and no node of its
/// family has a later one before `now` (stamp: local array, ghosts current). Other entries of
/// `tip` are left as they are (the caller clears them).
void mark_crack_tips(const BondView& v, const std::vector<std::int32_t>& damaged, const double* stamp, double now,
                     std::uint8_t* tip);

/// latest[b] = max(latest[b], the latest break time before `now` of the rows of `damaged` of
/// body b), for each b with by_body[b] (the rank's part of the body's latest break time).
void latest_breaks(const std::vector<std::int32_t>& damaged, const int* body, const double* stamp, double now,
                   const std::vector<std::uint8_t>& by_body, std::vector<double>& latest);

/// For each row i of `damaged` whose body b has by_body[b]: tip[i] = 1 when its break time is
/// latest[b] (the body's latest before the evaluation, over all ranks), else 0.
void mark_latest_tips(const std::vector<std::int32_t>& damaged, const int* body, const double* stamp,
                      const std::vector<std::uint8_t>& by_body, const std::vector<double>& latest, std::uint8_t* tip);

/// out[i] = 1 for each owned node i within reference distance sqrt(radius2[body]) of a node
/// marked in `marked` (local: owned and ghosts, ghosts current), i itself included: from the
/// families of the owned marked rows `marked_rows`, and for marked ghosts from the families of
/// `boundary_rows` (families are symmetric). radius2 per body of the marked node (owned marks)
/// or of the row (ghost marks); a negative value marks nothing beyond the node itself.
void mark_within(const BondView& v, std::int32_t owned, const int* body, const std::vector<std::int32_t>& marked_rows,
                 const std::vector<std::int32_t>& boundary_rows, const std::uint8_t* marked,
                 const std::vector<double>& radius2, std::uint8_t* out);

}  // namespace peri
