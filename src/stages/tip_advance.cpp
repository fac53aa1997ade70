#include "peri/stages/tip_advance.hpp"

#include <algorithm>
#include <limits>
#include <unordered_map>
#include <utility>

#include "peri/kernels/tip_advance.hpp"

namespace peri {

TipAdvance::TipAdvance(std::vector<double> radius, std::vector<std::uint8_t> by_body, const Domain& domain,
                       State& state)
    : by_body_(std::move(by_body)), domain_(domain), state_(state) {
  for (double r : radius) radius2_.push_back(r >= 0 ? r * r : -1.0);
  for (std::int32_t i = 0; i < domain.owned; ++i)
    if (applies(domain.body[i])) rule_rows_.push_back(i);
  for (std::int32_t i : domain.boundary_rows)
    if (applies(domain.body[i])) boundary_.push_back(i);
  std::sort(boundary_.begin(), boundary_.end());
  const auto local = static_cast<std::size_t>(domain.local());
  stamp_.assign(local, -std::numeric_limits<double>::infinity());
  count_.assign(static_cast<std::size_t>(domain.owned), 0);
  tip_.assign(local, 0);
  allowed_.assign(local, 0);
  near_.assign(local, 0);
  rows_.resize(radius2_.size());
}

void TipAdvance::prepare(const BondView& v, double now) {
  state_.exchange_ghosts(stamp_.data(), sizeof(double));
  std::fill(tip_.begin(), tip_.end(), std::uint8_t{0});
  mark_crack_tips(v, damaged_, stamp_.data(), now, tip_.data());
  if (std::any_of(by_body_.begin(), by_body_.end(), [](std::uint8_t b) { return b != 0; })) {
    std::vector<double> latest(by_body_.size(), -std::numeric_limits<double>::infinity());
    latest_breaks(damaged_, domain_.body.data(), stamp_.data(), now, by_body_, latest);
    MPI_Allreduce(MPI_IN_PLACE, latest.data(), static_cast<int>(latest.size()), MPI_DOUBLE, MPI_MAX, state_.comm());
    mark_latest_tips(damaged_, domain_.body.data(), stamp_.data(), by_body_, latest, tip_.data());
  }
  state_.exchange_ghosts(tip_.data(), 1);
  std::fill(allowed_.begin(), allowed_.end(), std::uint8_t{0});
  mark_within(v, domain_.owned, domain_.body.data(), damaged_, boundary_, tip_.data(), radius2_, allowed_.data());
  state_.exchange_ghosts(allowed_.data(), 1);
  // Rows with a bond that may break: within a family of a node that may break.
  std::vector<std::int32_t> allowed_rows;
  tip_count_ = allowed_count_ = 0;
  for (std::int32_t i : rule_rows_) {
    tip_count_ += tip_[i];
    if (allowed_[i]) allowed_rows.push_back(i);
  }
  allowed_count_ = static_cast<std::int64_t>(allowed_rows.size());
  std::fill(near_.begin(), near_.end(), std::uint8_t{0});
  std::vector<double> whole(radius2_.size(), std::numeric_limits<double>::infinity());
  mark_within(v, domain_.owned, domain_.body.data(), allowed_rows, boundary_, allowed_.data(), whole, near_.data());
  for (RowBlocks& r : rows_) r.rest.clear();
  for (std::int32_t i : rule_rows_)
    if (near_[i]) rows_[static_cast<std::size_t>(domain_.body[i])].rest.push_back(i);
}

void TipAdvance::stamp(const BondView& v, double time) {
  stamp_breaks(v, rule_rows_.data(), rule_rows_.size(), count_.data(), stamp_.data(), damaged_, time);
}

std::vector<double> TipAdvance::save(double time, MPI_Comm comm) const {
  std::vector<double> local;
  for (std::int32_t i : damaged_) local.insert(local.end(), {double(domain_.natural[i]), stamp_[i]});
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  const int n = static_cast<int>(local.size());
  std::vector<int> counts(ranks), displs(ranks, 0);
  MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm);
  for (int r = 1; r < ranks; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(rank == 0 ? 1 + displs.back() + counts.back() : 0);
  if (rank == 0) all[0] = time;
  MPI_Gatherv(local.data(), n, MPI_DOUBLE, rank == 0 ? all.data() + 1 : nullptr, counts.data(), displs.data(),
              MPI_DOUBLE, 0, comm);
  return all;
}

void TipAdvance::restore(const std::vector<double>* flat, const BondView& v) {
  std::fill(stamp_.begin(), stamp_.end(), -std::numeric_limits<double>::infinity());
  std::fill(count_.begin(), count_.end(), 0);
  damaged_.clear();
  double time = 0;
  if (flat && !flat->empty()) {
    time = (*flat)[0];
    std::unordered_map<std::int64_t, std::int32_t> local;
    for (std::int32_t i : rule_rows_) local.emplace(domain_.natural[i], i);
    for (std::size_t e = 1; e + 2 <= flat->size(); e += 2)
      if (const auto it = local.find(static_cast<std::int64_t>((*flat)[e])); it != local.end())
        stamp_[it->second] = (*flat)[e + 1];
  }
  // Counts from the flags; break times of the checkpoint (else its time).
  std::vector<double> stored(stamp_.begin(), stamp_.begin() + domain_.owned);
  stamp_breaks(v, rule_rows_.data(), rule_rows_.size(), count_.data(), stamp_.data(), damaged_, time);
  for (std::int32_t i : damaged_)
    if (stored[i] > -std::numeric_limits<double>::infinity()) stamp_[i] = stored[i];
  std::sort(damaged_.begin(), damaged_.end());
}

}  // namespace peri
