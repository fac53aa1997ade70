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

#include <vector>

#include "peri/core/simd.hpp"
#include "peri/kernels/forces.hpp"

namespace peri {

/// Doubles per node of dashpot_records: [x, y, z, v_x, v_y, v_z, -, -], one cache line.
inline constexpr std::int64_t kDashpotRecord = 8;

/// The nodes' records for bond_dashpots: each node's current position (view.x) and velocity
/// (3 per local node, ghosts current) in one cache line, so that a bond reads one line of its
/// neighbour, not four (three position planes and the velocity).
void dashpot_records(const BondView& view, const double* velocity, std::int64_t nodes, double* records);

/// Rows the dashpot pass walks side by side, one per vector lane: eight with AVX-512, four with
/// AVX2, else one.
#if defined(PERI_AVX512VL)
inline constexpr int kDashpotLanes = 8;
#elif defined(PERI_AVX2)
inline constexpr int kDashpotLanes = 4;
#else
inline constexpr int kDashpotLanes = 1;
#endif

/// The dashpots of some rows as bond_dashpots reads them: the rows in groups of kDashpotLanes
/// (in the rows' order), slot k of lane l of group g at at[g] + k kDashpotLanes + l for k below
/// the group's longest family, holding the bond's neighbour j and constant tau C w V; a lane past
/// its row's end holds its own row and 0 (coincident ends: no bond). One stream per group, so
/// that a slot's lanes are read from one pointer (with a list and a constant pointer per lane the
/// loop kept them on the stack), and the lanes' constants load as one vector. With one lane, each
/// row's bonds in CSR order.
struct DashpotLanes {
  std::vector<std::int64_t> at;  ///< per group its first slot, then the end
  std::vector<std::int32_t> neighbor;
  simd::AlignedVector<double> coefficient;
};

/// The DashpotLanes of `rows` (owned rows of one body, reference geometry from the view) with
/// the bonds' dashpot constants tau C_ij w_ij V_j [N s/m^4] of `law`.
DashpotLanes dashpot_lanes(const BondLaw& law, double tau, const BondView& view, const std::int32_t* rows,
                           std::size_t nrows);
/// The same with given constants at the bonds' CSR positions (coefficient[b]).
DashpotLanes dashpot_lanes(const BondView& view, const double* coefficient, const std::int32_t* rows,
                           std::size_t nrows);

/// Writes the dashpot force density of each of `rows` into viscous[3 i + c] (replacing what was
/// there): records: dashpot_records' of every local node; lanes: dashpot_lanes' of these rows
/// (broken bonds are skipped by their flags). With AVX2 or AVX-512, kDashpotLanes rows at a time,
/// one per lane (each lane its own row's bonds in CSR order); the same bits as
/// bond_dashpots_portable.
void bond_dashpots(const BondView& view, const double* records, const DashpotLanes& lanes, const std::int32_t* rows,
                   std::size_t nrows, double* viscous);

/// bond_dashpots one row and one bond at a time, on every build (the unit tests' reference).
void bond_dashpots_portable(const BondView& view, const double* records, const double* coefficient,
                            const std::int32_t* rows, std::size_t nrows, double* viscous);

/// The stable explicit step with dashpots of retardation time tau, from the step dt0 without them
/// (both for the node whose stiffness sets dt0).
double dashpot_stable_time_step(double dt0, double tau);

}  // namespace peri
