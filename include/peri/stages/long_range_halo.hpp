// The halo of the long-range pairs (models/long_range.hpp): each rank receives the current
// positions of those fiber nodes owned elsewhere that may come within the pair list's reach of
// its own, and nothing of the others.
//
// At a rebuild (when the Verlet list is rebuilt: some node moved more than skin / 2) every rank
// splits its own fiber nodes' current positions into a few boxes (up to kBoxes, by median
// cuts along the longest side) and all ranks gather them (6 doubles per box, kBoxes per rank: the
// only data that grows with the rank count). Rank s then sends to rank r its own nodes that lie
// in one of r's boxes grown by `grow` (reach + skin), their table indices once and their positions
// at every force evaluation until the next rebuild, point to point. Every node within reach +
// skin of one of r's nodes at the rebuild is inside r's grown boxes (each coordinate differs by
// at most the distance), so r's list sees every partner it can have until the next rebuild.
// What a rank sends to whom is decided by both ends from the gathered boxes alone: s may send to
// r when one of s's boxes meets one of r's grown ones; counts travel first, then only the
// neighbours with something to send.
//
// Messages go through a communicator of its own (duplicated once): no tag of another exchange
// on the same ranks can match them.
#pragma once
#include <mpi.h>

#include <array>
#include <cstdint>
#include <vector>

namespace peri {

class LongRangeHalo {
 public:
  static constexpr int kBoxes = 8;  ///< boxes per rank (median cuts three deep)
  /// An axis-aligned box; empty when lo > hi (+inf, -inf).
  struct Box {
    std::array<double, 3> lo, hi;
  };
  /// Collective over comm (duplicates it).
  explicit LongRangeHalo(MPI_Comm comm);
  ~LongRangeHalo();
  LongRangeHalo(LongRangeHalo&& other) noexcept;
  LongRangeHalo& operator=(LongRangeHalo&&) = delete;
  LongRangeHalo(const LongRangeHalo&) = delete;
  LongRangeHalo& operator=(const LongRangeHalo&) = delete;

  /// New send and receive lists (collective) from the current positions of this rank's own fiber
  /// nodes, the first `own` entries of `id` (table indices) and `x` (3 each); grow: reach + skin
  /// [m]. Appends the halo's table indices and current positions to id and x (by sending rank,
  /// then in the sender's order).
  void rebuild(std::int64_t own, std::vector<std::int64_t>& id, std::vector<double>& x, double grow);
  /// The current positions of the halo into x_halo (3 each, in rebuild's order) from those of the
  /// own nodes, x_own (collective among the neighbours).
  void exchange(const double* x_own, double* x_halo);
  /// Whether `mine` holds on some rank (collective).
  bool on_any_rank(bool mine) const;
  /// Halo nodes, and ranks sent to and received from, since the last rebuild.
  std::int64_t size() const { return recv_begin_.empty() ? 0 : recv_begin_.back(); }
  int send_neighbours() const { return static_cast<int>(send_rank_.size()); }
  int recv_neighbours() const { return static_cast<int>(recv_rank_.size()); }

  /// Up to kBoxes boxes that hold the n points x (3 each), the unused ones empty: the points'
  /// bounding box cut at its median point along its longest side, each half again, three deep.
  static std::array<Box, kBoxes> boxes_of(const double* x, std::int64_t n);

 private:
  MPI_Comm comm_ = MPI_COMM_NULL;
  int ranks_ = 1, rank_ = 0;
  std::vector<int> send_rank_, recv_rank_;            // neighbours, ascending rank
  std::vector<std::int64_t> send_begin_, recv_begin_;  // per neighbour, into send_node_ / the halo (+ 1)
  std::vector<std::int32_t> send_node_;               // own node index of each entry sent
  std::vector<double> send_buffer_;
  std::vector<MPI_Request> requests_;
};

}  // namespace peri
