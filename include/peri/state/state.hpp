// State: the PETSc objects of a run, owned in one place. Ghosted block Vecs (bs = 3) for
// displacement and velocity (owned entries first, ghosts after, in the Domain's local order),
// the halo exchange of displacement, and scatters to the natural (rank-independent) order used
// by output and checkpoints.
#pragma once
#include <petscvec.h>

#include <cstdint>
#include <utility>
#include <vector>

#include "peri/core/petsc.hpp"
#include "peri/partition/domain.hpp"

namespace peri {

/// Raw access to the local (owned + ghost) array of a ghosted Vec for the lifetime of the guard.
class LocalArray {
 public:
  explicit LocalArray(Vec ghosted);
  ~LocalArray();
  LocalArray(const LocalArray&) = delete;
  LocalArray& operator=(const LocalArray&) = delete;
  double* data() { return a_; }
 private:
  Vec g_ = nullptr, l_ = nullptr;
  double* a_ = nullptr;
};

class State {
 public:
  State(const Domain& domain, MPI_Comm comm);
  ~State();
  State(const State&) = delete;
  State& operator=(const State&) = delete;
  Vec displacement() const { return u_.get(); }
  Vec velocity() const { return v_.get(); }
  /// Halo exchange of displacement (owner values -> ghost copies), split so that interior bonds
  /// can be computed while messages are in flight. Point-to-point with persistent requests:
  /// halo_end waits for this rank's receives only; its sends are completed two exchanges later
  /// (two send buffers, used alternately), so a rank never waits for a slower neighbour to
  /// reach its own halo_end (as a scatter's end, which completes sends and receives together,
  /// would make it), only for the neighbour's data.
  void halo_begin();
  void halo_end();
  /// Halo exchange of velocity (only scenes with velocity-dependent forces: lattice dashpots).
  void velocity_halo_begin();
  void velocity_halo_end();
  /// Blocking halo exchange of a per-node array of `width` bytes per node (local order: owned,
  /// then ghosts): each ghost entry gets its owner's value (the crack-tip rule's break times and
  /// flags). Collective over the halo's neighbours.
  void exchange_ghosts(void* local, std::size_t width);
  /// Gather owned per-node values (bs = 1 or 3) into the natural order. Returns this rank's
  /// contiguous slice; natural_begin()/natural_count() say which natural ids it holds.
  const double* to_natural(const double* owned_values, int bs);
  std::int64_t natural_begin() const { return nat_begin_; }
  std::int64_t natural_count() const { return nat_count_; }
  MPI_Comm comm() const { return comm_; }

  /// Ghosted force accumulator (block size bs per node) for terms whose force lands on ghosts
  /// (Marder's three-body forces): created on first call. Kernels write into its local form
  /// (owned + ghosts); the reverse update adds every ghost entry into its owner (ADD_VALUES,
  /// SCATTER_REVERSE).
  void enable_force_accumulation(int bs);
  Vec force_accumulator() const { return f_.get(); }
  void reverse_begin();
  void reverse_end();

 private:
  void setup_halo(const Domain& d);
  OwnedVec f_;
  std::vector<PetscInt> ghost_globals_;
  std::int64_t global_nodes_ = 0;
  MPI_Comm comm_;
  OwnedVec u_, v_;
  OwnedVec owned1_, owned3_, nat1_, nat3_;  // solver-order and natural-order work vectors
  OwnedScatter to_nat1_, to_nat3_;
  std::int64_t nat_begin_ = 0, nat_count_ = 0;
  std::int32_t owned_ = 0;
  std::vector<double> slice_;

  // Displacement halo (see halo_begin): neighbour ranks, per neighbour the owned local nodes it
  // needs and the range of this rank's ghosts it owns (ghosts are in global order, so the ghosts
  // of one owner are contiguous).
  MPI_Comm halo_comm_ = MPI_COMM_NULL;
  std::vector<int> halo_ranks_;
  std::vector<std::int32_t> send_nodes_;       // concatenated over neighbours
  std::vector<std::int64_t> send_offset_;      // neighbours + 1 (nodes)
  std::vector<std::int64_t> recv_offset_;      // neighbours + 1 (ghosts, from 0)
  std::vector<double> send_buffer_[2], recv_buffer_;
  std::vector<MPI_Request> send_requests_[2], recv_requests_;
  int parity_ = 0;
};

}  // namespace peri
