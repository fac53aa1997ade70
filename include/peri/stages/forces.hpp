// The force model of a run: each body's bond law by the one bond loop (kernels/), with the
// displacement halo exchange overlapped by the rows that need no ghost; the Marder lattice
// bodies' two- and three-body forces, reduced onto their owners (forces_lattice.cpp); long-range
// pair forces between fiber nodes (each rank receives the positions of those fiber nodes within
// the pairs' reach of its own: long_range_halo.hpp). Built once by the setup; only the force
// terms the scene names exist.
//
// Also the other passes over the bonds: the strain energy of a state, each node's energy
// density and damage, the stable step of each body, and for the quasi-static loader the
// reference stiffness and the tangent.
#pragma once
#include <mpi.h>
#include <petscmat.h>

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "peri/core/simd.hpp"
#include "peri/kernels/dashpots.hpp"
#include "peri/kernels/forces.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/models/long_range.hpp"
#include "peri/models/marder.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"
#include "peri/state/state.hpp"
#include "peri/stages/long_range_halo.hpp"
#include "peri/stages/tip_advance.hpp"

namespace peri {

/// Long-range forces (scene long_range): every rank holds the table of all fiber nodes (48 bytes
/// per node); at each force evaluation it refreshes the current positions of its own fiber nodes
/// and of their halo (the nodes owned elsewhere within the list's reach + skin, LongRangeHalo),
/// and evaluates the pairs of its own.
struct LongRangeForces {
  LongRangeForces(PairLaw l, LongRangeTable t, MPI_Comm comm) : law(l), table(std::move(t)), halo(comm) {}
  PairLaw law;
  LongRangeTable table;
  std::vector<std::int32_t> mine_local;  // local (owned) index of each own fiber node
  std::vector<std::int64_t> rows;        // 0 .. own - 1: the own nodes among those seen
  std::vector<std::int64_t> id;          // table index of each node seen: the own ones, then the halo
  std::vector<double> x, volume;         // their current positions (3 each) and measures
  std::vector<double> force;             // 3 per own node
  LongRangeList list;
  LongRangeHalo halo;
  /// The current positions of the nodes seen: the own ones X + u (u nullptr: X), the halo's
  /// received. When some node has moved more than skin / 2 since the list was built (on any
  /// rank), the halo and the list are rebuilt. Collective.
  void refresh(const double* X, const double* u);
  PairNodes nodes() const {
    return {id.data(), x.data(), volume.data(), static_cast<std::int64_t>(id.size())};
  }
};

/// The long-range table of the scene's fibers, from the global node arrays (before they are
/// freed); InputError when the cutoff takes in too many pairs. Collective.
LongRangeForces make_long_range(const Scene& scene, const Nodes& nodes, const Domain& domain, MPI_Comm comm);

class Forces {
 public:
  /// bodies, laws: per body (laws: empty for lattice bodies). Lattice bodies get their laws, accumulators and
  /// bond flags here (InputError for what a lattice cannot run), then every peridynamic body its
  /// bond loop's plans.
  Forces(const Scene& scene, const std::vector<BodyGeometry>& bodies, Domain& domain, State& state,
         std::vector<BondLaw> laws, std::optional<LongRangeForces> long_range, MPI_Comm comm);
  Forces(const Forces&) = delete;
  Forces& operator=(const Forces&) = delete;

  /// Force densities [N/m^3] of every owned node at the current displacement (halos exchanged
  /// here) into force(); with `intact`, by laws that never break (quasi-static residuals). Adds
  /// the bonds dissipated and broken to `tally`, sets its strain energy (with_energy: also each
  /// node's energy density, for energy_density()).
  void compute(bool with_energy, bool intact, BondTally& tally);
  /// The time of the next force evaluations (the crack-tip rule's break times).
  void set_time(double time) { time_ = time; }
  /// The incremental crack-tip advance of the bodies whose material sets tip_advance, or nullptr.
  TipAdvance* tip_advance() { return tip_advance_ ? &*tip_advance_ : nullptr; }
  double* force() { return force_.data(); }
  const double* force() const { return force_.data(); }
  /// Current positions of the local nodes (planes x, y, z position_stride() apart), as of the
  /// last pass over the bonds.
  const double* positions() const { return positions_.data(); }
  std::int64_t position_stride() const { return position_stride_; }
  /// Dashpot force densities of the last evaluation (3 per owned node; lattice dashpots and the
  /// peridynamic bodies' kernels/dashpots.hpp), or nullptr when no body has dashpots.
  const double* viscous() const { return has_kelvin_ ? viscous_.data() : nullptr; }
  /// The velocity the dashpots of the last evaluation saw (3 per owned node; the half step's in a
  /// dynamic step, which a checkpoint keeps so that a resumed run's first evaluation sees it too),
  /// or nullptr when no body has dashpots.
  const std::vector<double>* dashpot_velocity() const { return has_kelvin_ ? &dashpot_velocity_ : nullptr; }
  bool has_dashpots() const { return has_kelvin_; }

  /// This rank's strain energy of the current state: a separate, non-breaking pass over the bonds
  /// and the lattice's terms (not the long-range pairs). Not collective.
  double strain_energy();
  /// Strain energy per unit volume of each owned node (bonds, long-range pairs; lattice nodes:
  /// 0), from the last force evaluation when it was an energy call on this state.
  const double* energy_density();
  /// Damage of each owned node from the bond flags.
  const double* damage();
  /// The stable time step of each body on this rank (infinity where it has no rows); density:
  /// per body. undamped: if given, the same without the bond dashpots.
  std::vector<double> stable_time_steps(const std::vector<double>& density, std::vector<double>* undamped = nullptr);
  /// The bond loop's plans forget what they keep of the broken flags: after flags are written
  /// other than by the loop (release stage, restart).
  void flags_changed();
  /// Whether owned row `row` has an intact bond.
  bool has_intact_bond(std::int32_t row) const {
    for (std::int64_t b = domain_.bonds.offsets[row]; b < domain_.bonds.offsets[row + 1]; ++b)
      if (!(domain_.bonds.broken[b] & 1)) return true;  // bit 0: broken (lattices keep other bits)
    return false;
  }
  /// The current displacement changed other than by the explicit update (quasi-static loader):
  /// energy densities are recomputed.
  void displacement_changed() { density_current_ = false; }

  const std::vector<BondLaw>& laws() const { return laws_; }
  /// Bytes the bond loop's plans keep beside the bond arrays (RowBlocks::extra_bytes).
  std::size_t plan_bytes() const;
  /// The lattice law of body b, or nullptr for a peridynamic body.
  const MarderLaw* marder(std::size_t b) const { return marder_[b] ? &*marder_[b] : nullptr; }
  /// This rank's bond arrays, positions as of the last pass (u filled by the caller).
  BondView bond_view();

  // Quasi-static loader (intact laws).
  /// Sum over this rank's rows of each row's reference stiffness.
  double reference_stiffness_sum();
  /// Adds K = -d(F V)/du at the current displacement to J (ghosts current): the rows and columns
  /// of the local nodes with a block index >= 0 in `block` (owned, then ghosts), the leading
  /// `components` x `components` part of each node block.
  void add_tangent(Mat J, const PetscInt* block, int components);

 private:
  void lattice_setup(const Scene& scene, const std::vector<BodyGeometry>& bodies);
  void lattice_forces(const BondView& view, bool interior, bool with_energy, BondTally& tally,
                      const double* velocity);
  void lattice_reduce();
  void dashpot_setup(const Scene& scene, const std::vector<BodyGeometry>& bodies);
  void add_dashpots(const BondView& view, const double* velocity);
  double lattice_energy(const BondView& view);
  double add_long_range_forces(const double* u, bool with_energy);  // returns this rank's energy share

  Domain& domain_;
  State& state_;
  MPI_Comm comm_;
  std::vector<BondLaw> laws_;         // per body
  std::vector<BondLaw> intact_laws_;  // same, never breaking (quasi-static residuals, tangents)
  std::vector<std::optional<MarderLaw>> marder_;  // per body: set for lattice bodies
  bool has_lattice_ = false;
  bool has_kelvin_ = false;                      // some body has bond dashpots (velocity halo)
  std::vector<double> dashpot_tau_;              // per peridynamic body: its dashpots' tau [s] (0: none)
  std::vector<std::array<DashpotLanes, 2>> dashpot_lanes_;  // per body: its interior and boundary rows' dashpots
  std::vector<std::uint8_t> lattice_direction_;  // lattice direction of every owned-row bond
  std::vector<double> dashpot_velocity_;          // the velocity the dashpots last saw, 3 * owned
  std::vector<double> viscous_;                  // dashpot force densities, 3 * local (owned rows written)
  simd::AlignedVector<double> dashpot_records_;  // per local node: position and velocity (dashpot_records)
  std::optional<LongRangeForces> long_range_;
  std::vector<std::vector<std::int32_t>> interior_by_body_, boundary_by_body_;
  std::vector<RowBlocks> interior_plan_, boundary_plan_;  // the same rows grouped for the bond loop
  std::vector<double> force_;                    // force densities, 3 * owned
  std::vector<double> positions_;  // current positions X + u, planes x, y, z of local() each (bond kernel input)
  std::int64_t position_stride_ = 0;  // doubles from one plane of positions_ to the next
  std::vector<double> energy_density_;  // owned: strain energy per unit volume (frames)
  // Whether energy_density_ holds the bond energies of the current state: written by the bond
  // loop in energy calls (compute), so a frame needs no separate pass over the bonds.
  bool density_current_ = false;
  std::vector<double> damage_;  // owned
  // The crack-tip rule (tip_advance): its bodies' rows run the intact laws in the bond loop, then
  // the rows whose bonds may break run again in the portable walk with the rule.
  std::optional<TipAdvance> tip_advance_;
  double time_ = 0;
};

}  // namespace peri
