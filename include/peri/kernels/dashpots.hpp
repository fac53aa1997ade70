// Kelvin-Voigt bond dashpots of the peridynamic laws (the material key kelvin_viscosity). Pure
// kernel (no MPI, no PETSc). Each intact bond's force gains tau C y', C = df/dy at y = |xi| the
// law's reference bond stiffness and y' = e . (v_j - v_i) the rate of the bond's length, along
// the current bond direction e = (x_j - x_i) / |x_j - x_i|:
//   F_i^visc = sum_j tau C_ij (e_ij . (v_j - v_i)) e_ij w_ij V_j            (force density, N/m^3)
// At small strain the viscous stress is tau times the rate of the elastic stress, so tau = rho nu
// / mu gives the shear viscosity rho nu of the Marder lattice's dashpots (marder.hpp) for the same
// kinematic viscosity nu. A wave of angular frequency omega decays at the rate tau omega^2 / 2.
#pragma once
#include <cstddef>
#include <cstdint>

#include "peri/kernels/forces.hpp"

namespace peri {

/// The bonds' dashpot constants tau C_ij w_ij V_j [N s/m^4] of `rows` (owned rows of one
/// body, reference geometry from the view), written at their CSR positions: coefficient[b].
void dashpot_coefficients(const BondLaw& law, double tau, const BondView& view, const std::int32_t* rows,
                          std::size_t nrows, double* coefficient);

/// Doubles per node of dashpot_records: [x, y, z, v_x, v_y, v_z, -, -], one cache line.
inline constexpr std::int64_t kDashpotRecord = 8;

/// The nodes' records for bond_dashpots: each node's current position (view.x) and velocity
/// (3 per local node, ghosts current) in one cache line, so that a bond reads one line of its
/// neighbour, not four (three position planes and the velocity).
void dashpot_records(const BondView& view, const double* velocity, std::int64_t nodes, double* records);

/// Writes the dashpot force density of each of `rows` into viscous[3 i + c] (replacing what was
/// there): records: dashpot_records' of every local node; coefficient: dashpot_coefficients'
/// (broken bonds are skipped by their flags). With AVX2, four rows at a time, one per lane (each
/// lane its own row's bonds in CSR order); the same bits as bond_dashpots_portable.
void bond_dashpots(const BondView& view, const double* records, const double* coefficient,
                   const std::int32_t* rows, std::size_t nrows, double* viscous);

/// bond_dashpots one row and one bond at a time, on every build (the unit tests' reference).
void bond_dashpots_portable(const BondView& view, const double* records, const double* coefficient,
                            const std::int32_t* rows, std::size_t nrows, double* viscous);

/// The stable explicit step with dashpots of retardation time tau, from the step dt0 without them
/// (both for the node whose stiffness sets dt0).
double dashpot_stable_time_step(double dt0, double tau);

}  // namespace peri
