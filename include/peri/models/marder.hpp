// Marder's multi-particle rubber model (Marder, "Dynamic fracture of nonlinear solids with
// multi-particle modeling", eqs. (7)-(33)): mass points on a triangular lattice of spacing Delta
// with two-body forces f(u) and three-body forces h(u_ij) h(u_ik) g(u_ij . u_ik), chosen so that
// for homogeneous deformations with Delta + u_s < u < u_c the energy per node is
//   U_i = A F_i + B (G_i - H_i + 4 Delta^4) = m a [J1 + b J2]          (eqs. 22-27)
// i.e. the 2D Mooney-Rivlin sheet W/rho = a [J1 + b J2] (eq. 6), with m the mass per node.
//
// Pure layer: the law (constants and the three functions, models/laws/marder.hpp) and the loop over
// owned rows of a CSR neighbour list. No MPI, no PETSc. The energy is a sum of node-centred terms U_i that depend only on the
// bond vectors d_j = x_j - x_i of row i; the loop adds -dU_i/dx to node i and to its neighbours,
// which may be ghosts: the caller sums ghost contributions back to their owners.
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "peri/kernels/forces.hpp"
#include "peri/models/laws/marder.hpp"

namespace peri {

/// Largest neighbour count of a lattice row (triangular lattice).
constexpr int kMarderMaxNeighbours = 6;

/// Why the parameters are unusable, or an empty string when they are fine. Refused: a <= 0;
/// u_s <= 0; u_c <= Delta + u_s (bonds would break before reaching the Mooney-Rivlin range);
/// b >= 2 (the stretched sheet has no shear stiffness: c_s^2 = a (1 - b/2) <= 0); and b outside
/// (-2 Delta/u_s, Delta/u_s), where the unstretched lattice (cutoff branch of eq. 31) is
/// unstable to a homogeneous shear or dilatation (derived in docs/theory/marder.md). Of the
/// options: a stiffening onset u_g off the Mooney-Rivlin branch [Delta + u_s, u_c), a width
/// w < 0, a break separation u_b outside (Delta + u_s, u_c].
std::string marder_parameter_problem(double a, double b, double delta, double us, double uc,
                                     const MarderOptions& options = {});

/// Constants for a lattice of spacing Delta whose nodes have mass m, with the options.
MarderLaw marder_law(double a, double b, double delta, double us, double uc, double mass,
                     bool reversible, const MarderOptions& options = {});

/// Dashpot coefficient per bond [kg/s] that gives a triangular lattice of spacing Delta and node
/// mass m the viscous stress rho nu (2 D + (tr D) I) (reference lattice, strain rate D):
/// eta = 8 m nu / (3 Delta^2).
double marder_dashpot(double kelvin_viscosity, double delta, double mass) noexcept;

/// Node-centred energy U_i of one row and its gradient: d[3*j..] are the bond vectors
/// x_j - x_i of the n <= 6 neighbours, active[j] = 0 for a broken bond (no two-body term,
/// h = 0). grad[3*j..] receives dU_i/dd_j (may be nullptr). Returns U_i [J].
double marder_node(const MarderLaw& law, int n, const double* d, const std::uint8_t* active,
                   double* grad) noexcept;

/// Per-node force slots: slot 0 holds the force of the node's own term U_i, slot 1 + s the force
/// from the term of its neighbour in lattice direction s (0..5, angle s*60 degrees). Every slot is
/// written by exactly one row, so a reverse ghost update with ADD_VALUES onto zeroed owner slots
/// copies values exactly, and the owner sums the slots in a fixed order: forces are the same bit
/// for bit on any number of ranks.
constexpr int kMarderSlots = 1 + kMarderMaxNeighbours;

/// Lattice direction (0..5) of every ordered bond of the rows: round(angle(X_j - X_i) / 60 deg).
std::vector<std::uint8_t> marder_directions(const BondView& view, std::int64_t rows);

/// Force [N] of each node from its slots (3 * kMarderSlots per node), summed in slot order.
void marder_sum_slots(const double* slots, const std::int32_t* nodes, std::size_t n, double* force);

/// Forces [N] of the rows: writes -dU_i/dx of each row into slot 0 of node i and into slot
/// 1 + direction(j -> i) of every neighbour j (local indices, ghosts included; the caller zeroes
/// the slots, reduces them to the owners and sums them). Updates the bond flags first:
/// irreversible (default) a bond with u >= u_b (MarderLaw::break_length) breaks for good;
/// reversible, the flag follows u >= u_b except for bonds cut at the start (flag bit kMarderCut).
/// The energy lost when a bond breaks irreversibly (its two-body term and the three-body terms it
/// switches off) is added to tally.dissipated, so kinetic + strain + dissipated is conserved. With
/// `with_energy`, the energy of the rows is added to tally.strain_energy.
///
/// Kelvin dashpots (law.dashpot > 0 and `velocity` given: 3 * local velocities, ghosts
/// included): each row writes the dashpot force on its own node, sum over its intact bonds (CSR
/// order) of eta (e . (v_j - v_i)) e, into viscous[3 i..] [N] (no ghost slot: row j computes the
/// opposite force, bit for bit the negative, from the same two velocities), and adds half of each
/// bond's dissipated power eta (e . (v_j - v_i))^2 to tally.viscous_power (the other half is
/// row j's). Bonds flagged broken (past u_c) have no dashpot.
void marder_forces(const MarderLaw& law, const BondView& view, const std::int32_t* rows,
                   std::size_t nrows, const std::uint8_t* direction, double* slots, bool with_energy,
                   BondTally& tally, const double* velocity = nullptr, double* viscous = nullptr);

/// Energy of the rows with the current flags (no breaking, no forces).
double marder_energy(const MarderLaw& law, const BondView& view, const std::int32_t* rows,
                     std::size_t nrows);

/// Flag bit of a bond cut by a pre-crack: stays broken in the reversible mode too.
constexpr std::uint8_t kMarderCut = 4;
/// Flag bit of a bond that never breaks (outside a lattice body's breakable box).
constexpr std::uint8_t kMarderUnbreakable = 8;

/// Estimate of the stable explicit time step of the lattice: sqrt(2 m / k) with k the sum over
/// six neighbours of the largest pair stiffness reachable below u_c (cutoff branch at Delta + u_s
/// or quartic branch and stiffening at u_c, both rows of a bond) plus bounds of the three-body
/// curvature over the pairs a bond takes part in, including the switch h near u_c (see marder.cpp). With
/// dashpots (force from the half-step velocity, see docs/theory/marder.md) the step also
/// satisfies (omega dt / 2)^2 + gamma dt / 2 <= 1 with omega = 2 / (undamped bound) and
/// gamma = 24 eta / m the largest damping rate.
double marder_stable_time_step(const MarderLaw& law);

/// Small-amplitude wave speeds of the Mooney-Rivlin sheet W/rho = a [J1 + b J2] about the
/// homogeneous stretch diag(lambda_along, lambda_across), for propagation along the first axis,
/// in the reference frame (reference distance per time; multiply by lambda_along for the lab
/// frame). Derived in docs/theory/marder.md:
///   c_l^2 = a [1 + (b/2)(lambda_across^2 - 1)],   c_s^2 = a (1 - b/2).
struct WaveSpeeds {
  double longitudinal = 0, shear = 0;
};
WaveSpeeds mooney_rivlin_wave_speeds(double a, double b, double lambda_along, double lambda_across);

/// The stretches along x and y of the lattice's initial homogeneous deformation F = I + H (H row
/// major): |F e_x| and |F e_y| in the sheet's plane.
inline std::array<double, 2> lattice_initial_stretches(const std::array<double, 9>& H) {
  return {std::hypot(1 + H[0], H[3]), std::hypot(H[1], 1 + H[4])};
}

/// Small-amplitude long-wave speeds of the lattice itself about the homogeneous stretch
/// diag(lambda_along, lambda_across), for propagation along the first axis, in the reference
/// frame. The triangular lattice is a Bravais lattice, so a long wave sees the energy per node of
/// the homogeneous deformation U(F) (all six pair terms and all three-body terms, the switch h
/// included): c_l^2 = (d^2 U / dF_11^2) / m and c_s^2 = (d^2 U / dF_21^2) / m (central
/// differences). Equal to mooney_rivlin_wave_speeds only where every bond is on the
/// Mooney-Rivlin branch (Delta + u_s < u) and h = 1; near u_c (h < 1, the quartic pair term no
/// longer cancelled) or on the cutoff branch the lattice is stiffer. `along_y` rotates the
/// lattice's bond directions by 90 degrees relative to the wave (propagation along y).
WaveSpeeds marder_lattice_wave_speeds(const MarderLaw& law, double lambda_along, double lambda_across,
                                      bool along_y = false);

}  // namespace peri
