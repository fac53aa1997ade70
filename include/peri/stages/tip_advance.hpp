// The incremental crack-tip advance of section 7.4 (materials' tip_advance) on a rank: break
// times of the owned nodes, the crack-tip nodes, the nodes that may break a bond and the rows
// whose bonds may break, exchanged with the ghosts. The rule itself: kernels/tip_advance.hpp.
#pragma once
#include <mpi.h>

#include <cstdint>
#include <vector>

#include "peri/kernels/forces.hpp"
#include "peri/partition/domain.hpp"
#include "peri/state/state.hpp"

namespace peri {

class TipAdvance {
 public:
  /// radius: per body, r [m] of its material's tip_advance, or negative (no rule); by_body: per
  /// body, 1 where its tips are the body's latest damage (tip_advance_tips: body).
  TipAdvance(std::vector<double> radius, std::vector<std::uint8_t> by_body, const Domain& domain, State& state);
  bool applies(int body) const { return radius2_[static_cast<std::size_t>(body)] >= 0; }
  /// From the break times before `now`: the tip nodes, the nodes that may break (may_break()),
  /// and per body the owned rows with a bond that may break (rows()). Collective (three halo
  /// exchanges, and a reduction of the latest break time where a body's tips are its latest).
  void prepare(const BondView& v, double now);
  const std::uint8_t* may_break() const { return allowed_.data(); }
  /// The owned rows of body b with a bond that may break, for the portable walk.
  const RowBlocks& rows(int body) const { return rows_[static_cast<std::size_t>(body)]; }
  /// Owned nodes of rule bodies whose count of broken bonds rose since the last call get the
  /// break time `time`.
  void stamp(const BondView& v, double time);
  /// (natural id, break time) of every damaged owned node, gathered to rank 0, after the time
  /// of the save (checkpoints). Collective.
  std::vector<double> save(double time, MPI_Comm comm) const;
  /// The break times of a checkpoint (nullptr: none stored); counts from the current flags;
  /// a damaged node the checkpoint does not list gets the checkpoint's time.
  void restore(const std::vector<double>* flat, const BondView& v);
  /// Tip nodes and nodes that may break of this rank at the last prepare (owned).
  std::int64_t tip_nodes() const { return tip_count_; }
  std::int64_t allowed_nodes() const { return allowed_count_; }

 private:
  std::vector<double> radius2_;        // per body: r^2, or -1
  std::vector<std::uint8_t> by_body_;  // per body: tips are the body's latest damage
  const Domain& domain_;
  State& state_;
  std::vector<std::int32_t> rule_rows_;  // owned rows of rule bodies
  std::vector<std::int32_t> boundary_;   // those with ghost neighbours
  std::vector<double> stamp_;            // local: break time, -inf while intact
  std::vector<std::int32_t> count_;      // owned: broken bonds at the last stamp
  std::vector<std::int32_t> damaged_;    // owned rows with a break time
  std::vector<std::uint8_t> tip_, allowed_, near_;  // local
  std::vector<RowBlocks> rows_;          // per body
  std::int64_t tip_count_ = 0, allowed_count_ = 0;
};

}  // namespace peri
