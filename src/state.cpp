#include "peri/state.hpp"

#include <algorithm>

#include "peri/error.hpp"

namespace peri {

LocalArray::LocalArray(Vec ghosted) : g_(ghosted) {
  PERI_PETSC(VecGhostGetLocalForm(g_, &l_));
  PERI_PETSC(VecGetArray(l_, &a_));
}

LocalArray::~LocalArray() {
  VecRestoreArray(l_, &a_);
  VecGhostRestoreLocalForm(g_, &l_);
}

State::State(const Domain& d, MPI_Comm comm) : comm_(comm), owned_(d.owned) {
  const PetscInt nghost = d.ghosts;
  std::vector<PetscInt> ghosts(nghost);
  for (PetscInt k = 0; k < nghost; ++k) ghosts[k] = static_cast<PetscInt>(d.global[d.owned + k]);
  Vec u, v;
  PERI_PETSC(VecCreateGhostBlock(comm, 3, 3 * d.owned, 3 * d.global_nodes, nghost, ghosts.data(), &u));
  PERI_PETSC(VecDuplicate(u, &v));
  ghost_globals_ = ghosts;
  global_nodes_ = d.global_nodes;
  u_ = OwnedVec(u);
  v_ = OwnedVec(v);
  PERI_PETSC(VecZeroEntries(u));
  PERI_PETSC(VecZeroEntries(v));

  // Natural layout: contiguous blocks of natural ids, split as PETSc would by default.
  Vec nat1, nat3, own1, own3;
  PERI_PETSC(VecCreateMPI(comm, PETSC_DECIDE, d.global_nodes, &nat1));
  PetscInt lo, hi;
  PERI_PETSC(VecGetOwnershipRange(nat1, &lo, &hi));
  nat_begin_ = lo;
  nat_count_ = hi - lo;
  PERI_PETSC(VecCreate(comm, &nat3));
  PERI_PETSC(VecSetSizes(nat3, 3 * nat_count_, 3 * d.global_nodes));
  PERI_PETSC(VecSetBlockSize(nat3, 3));
  PERI_PETSC(VecSetType(nat3, VECMPI));
  PERI_PETSC(VecCreateMPI(comm, d.owned, d.global_nodes, &own1));
  PERI_PETSC(VecCreate(comm, &own3));
  PERI_PETSC(VecSetSizes(own3, 3 * d.owned, 3 * d.global_nodes));
  PERI_PETSC(VecSetBlockSize(own3, 3));
  PERI_PETSC(VecSetType(own3, VECMPI));
  nat1_ = OwnedVec(nat1);
  nat3_ = OwnedVec(nat3);
  owned1_ = OwnedVec(own1);
  owned3_ = OwnedVec(own3);

  std::vector<PetscInt> natural(d.owned);
  for (std::int32_t l = 0; l < d.owned; ++l) natural[l] = static_cast<PetscInt>(d.natural[l]);
  IS from1, to1, from3, to3;
  PERI_PETSC(ISCreateStride(comm, d.owned, static_cast<PetscInt>(d.global_begin), 1, &from1));
  PERI_PETSC(ISCreateGeneral(comm, d.owned, natural.data(), PETSC_COPY_VALUES, &to1));
  PERI_PETSC(ISCreateBlock(comm, 3, d.owned, natural.data(), PETSC_COPY_VALUES, &to3));
  std::vector<PetscInt> own_blocks(d.owned);
  for (std::int32_t l = 0; l < d.owned; ++l) own_blocks[l] = static_cast<PetscInt>(d.global_begin + l);
  PERI_PETSC(ISCreateBlock(comm, 3, d.owned, own_blocks.data(), PETSC_COPY_VALUES, &from3));
  VecScatter s1, s3;
  PERI_PETSC(VecScatterCreate(own1, from1, nat1, to1, &s1));
  PERI_PETSC(VecScatterCreate(own3, from3, nat3, to3, &s3));
  to_nat1_ = OwnedScatter(s1);
  to_nat3_ = OwnedScatter(s3);
  ISDestroy(&from1);
  ISDestroy(&to1);
  ISDestroy(&from3);
  ISDestroy(&to3);
}

void State::halo_begin() {
  PERI_PETSC(VecGhostUpdateBegin(u_.get(), INSERT_VALUES, SCATTER_FORWARD));
}

void State::halo_end() {
  PERI_PETSC(VecGhostUpdateEnd(u_.get(), INSERT_VALUES, SCATTER_FORWARD));
}

void State::velocity_halo_begin() {
  PERI_PETSC(VecGhostUpdateBegin(v_.get(), INSERT_VALUES, SCATTER_FORWARD));
}

void State::velocity_halo_end() {
  PERI_PETSC(VecGhostUpdateEnd(v_.get(), INSERT_VALUES, SCATTER_FORWARD));
}

void State::enable_force_accumulation(int bs) {
  if (f_.get()) return;
  Vec f;
  PERI_PETSC(VecCreateGhostBlock(comm_, bs, bs * owned_, bs * global_nodes_,
                                 static_cast<PetscInt>(ghost_globals_.size()), ghost_globals_.data(), &f));
  PERI_PETSC(VecZeroEntries(f));
  f_ = OwnedVec(f);
}

void State::reverse_begin() {
  PERI_PETSC(VecGhostUpdateBegin(f_.get(), ADD_VALUES, SCATTER_REVERSE));
}

void State::reverse_end() {
  PERI_PETSC(VecGhostUpdateEnd(f_.get(), ADD_VALUES, SCATTER_REVERSE));
}

const double* State::to_natural(const double* owned_values, int bs) {
  Vec src = bs == 3 ? owned3_.get() : owned1_.get();
  Vec dst = bs == 3 ? nat3_.get() : nat1_.get();
  VecScatter sc = bs == 3 ? to_nat3_.get() : to_nat1_.get();
  PetscScalar* a;
  PERI_PETSC(VecGetArray(src, &a));
  std::copy(owned_values, owned_values + static_cast<std::size_t>(bs) * owned_, a);
  PERI_PETSC(VecRestoreArray(src, &a));
  PERI_PETSC(VecScatterBegin(sc, src, dst, INSERT_VALUES, SCATTER_FORWARD));
  PERI_PETSC(VecScatterEnd(sc, src, dst, INSERT_VALUES, SCATTER_FORWARD));
  const PetscScalar* r;
  PERI_PETSC(VecGetArrayRead(dst, &r));
  slice_.assign(r, r + static_cast<std::size_t>(bs) * nat_count_);
  PERI_PETSC(VecRestoreArrayRead(dst, &r));
  return slice_.data();
}

}  // namespace peri
