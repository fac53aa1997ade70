#include "peri/stages/long_range_halo.hpp"

#include <algorithm>
#include <limits>
#include <numeric>
#include <utility>

#include "peri/core/error.hpp"

namespace peri {

namespace {

constexpr int kCountTag = 1, kIdTag = 2, kPositionTag = 3;

// Whether box a meets box b grown by g on every side (false when either is empty).
bool meets_grown(const LongRangeHalo::Box& a, const LongRangeHalo::Box& b, double g) {
  for (int d = 0; d < 3; ++d)
    if (!(a.lo[d] <= b.hi[d] + g && b.lo[d] - g <= a.hi[d])) return false;
  return true;
}

bool inside_grown(const double* x, const LongRangeHalo::Box& b, double g) {
  for (int d = 0; d < 3; ++d)
    if (!(b.lo[d] - g <= x[d] && x[d] <= b.hi[d] + g)) return false;
  return true;
}

}  // namespace

LongRangeHalo::LongRangeHalo(MPI_Comm comm) {
  MPI_Comm_dup(comm, &comm_);
  MPI_Comm_size(comm_, &ranks_);
  MPI_Comm_rank(comm_, &rank_);
}

LongRangeHalo::~LongRangeHalo() {
  if (!requests_.empty()) MPI_Waitall(static_cast<int>(requests_.size()), requests_.data(), MPI_STATUSES_IGNORE);
  if (comm_ != MPI_COMM_NULL) MPI_Comm_free(&comm_);
}

LongRangeHalo::LongRangeHalo(LongRangeHalo&& o) noexcept
    : comm_(std::exchange(o.comm_, MPI_COMM_NULL)),
      ranks_(o.ranks_),
      rank_(o.rank_),
      send_rank_(std::move(o.send_rank_)),
      recv_rank_(std::move(o.recv_rank_)),
      send_begin_(std::move(o.send_begin_)),
      recv_begin_(std::move(o.recv_begin_)),
      send_node_(std::move(o.send_node_)),
      send_buffer_(std::move(o.send_buffer_)),
      requests_(std::move(o.requests_)) {}

std::array<LongRangeHalo::Box, LongRangeHalo::kBoxes> LongRangeHalo::boxes_of(const double* x, std::int64_t n) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::array<Box, kBoxes> boxes;
  for (Box& b : boxes) b = {{inf, inf, inf}, {-inf, -inf, -inf}};
  std::vector<std::int64_t> order(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), std::int64_t{0});
  int used = 0;
  auto bound = [&](std::int64_t b, std::int64_t e) {
    Box box = {{inf, inf, inf}, {-inf, -inf, -inf}};
    for (std::int64_t k = b; k < e; ++k)
      for (int d = 0; d < 3; ++d) {
        box.lo[d] = std::min(box.lo[d], x[3 * order[k] + d]);
        box.hi[d] = std::max(box.hi[d], x[3 * order[k] + d]);
      }
    return box;
  };
  // Leaves of the cut tree over order[b, e): kBoxes = 2^3 at depth 3.
  auto cut = [&](auto&& self, std::int64_t b, std::int64_t e, int depth) -> void {
    if (b == e) return;
    const Box box = bound(b, e);
    if (depth == 3 || e - b < 2) {
      boxes[used++] = box;
      return;
    }
    int axis = 0;
    for (int d = 1; d < 3; ++d)
      if (box.hi[d] - box.lo[d] > box.hi[axis] - box.lo[axis]) axis = d;
    const std::int64_t mid = b + (e - b) / 2;
    std::nth_element(order.begin() + b, order.begin() + mid, order.begin() + e,
                     [&](std::int64_t p, std::int64_t q) { return x[3 * p + axis] < x[3 * q + axis]; });
    self(self, b, mid, depth + 1);
    self(self, mid, e, depth + 1);
  };
  cut(cut, 0, n, 0);
  return boxes;
}

void LongRangeHalo::rebuild(std::int64_t own, std::vector<std::int64_t>& id, std::vector<double>& x, double grow) {
  if (!requests_.empty()) MPI_Waitall(static_cast<int>(requests_.size()), requests_.data(), MPI_STATUSES_IGNORE);
  requests_.clear();
  send_rank_.clear();
  recv_rank_.clear();
  send_begin_.assign(1, 0);
  recv_begin_.assign(1, 0);
  send_node_.clear();
  id.resize(static_cast<std::size_t>(own));
  x.resize(3 * static_cast<std::size_t>(own));
  if (ranks_ == 1) return;
  if (own > std::numeric_limits<std::int32_t>::max())
    throw RuntimeFailure("long-range halo: more than 2^31 fiber nodes on one rank");

  // Every rank's boxes (6 doubles each, kBoxes per rank).
  const std::array<Box, kBoxes> mine = boxes_of(x.data(), own);
  std::vector<Box> all(static_cast<std::size_t>(ranks_) * kBoxes);
  static_assert(sizeof(Box) == 6 * sizeof(double));
  MPI_Allgather(mine.data(), 6 * kBoxes, MPI_DOUBLE, all.data(), 6 * kBoxes, MPI_DOUBLE, comm_);
  // s may send to r: one of s's boxes meets one of r's grown boxes (both ends decide alike, from
  // the same gathered numbers).
  auto may_send = [&](int s, int r) {
    for (int a = 0; a < kBoxes; ++a)
      for (int b = 0; b < kBoxes; ++b)
        if (meets_grown(all[s * kBoxes + a], all[r * kBoxes + b], grow)) return true;
    return false;
  };
  std::vector<int> to, from;
  for (int r = 0; r < ranks_; ++r) {
    if (r == rank_) continue;
    if (may_send(rank_, r)) to.push_back(r);
    if (may_send(r, rank_)) from.push_back(r);
  }
  // The own nodes in each candidate's grown boxes, in own order.
  std::vector<std::int32_t> nodes;
  std::vector<std::int64_t> begin(1, 0);
  for (const int r : to) {
    const Box* boxes = &all[r * kBoxes];
    for (std::int64_t k = 0; k < own; ++k)
      for (int b = 0; b < kBoxes; ++b)
        if (inside_grown(&x[3 * k], boxes[b], grow)) {
          nodes.push_back(static_cast<std::int32_t>(k));
          break;
        }
    begin.push_back(static_cast<std::int64_t>(nodes.size()));
  }
  // Counts to and from the candidates; then only those with something to send.
  std::vector<std::int64_t> send_count(to.size()), recv_count(from.size());
  std::vector<MPI_Request> requests;
  requests.reserve(to.size() + from.size());
  for (std::size_t n = 0; n < from.size(); ++n) {
    requests.emplace_back();
    MPI_Irecv(&recv_count[n], 1, MPI_INT64_T, from[n], kCountTag, comm_, &requests.back());
  }
  for (std::size_t n = 0; n < to.size(); ++n) {
    send_count[n] = begin[n + 1] - begin[n];
    requests.emplace_back();
    MPI_Isend(&send_count[n], 1, MPI_INT64_T, to[n], kCountTag, comm_, &requests.back());
  }
  MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
  for (std::size_t n = 0; n < to.size(); ++n) {
    if (send_count[n] == 0) continue;
    send_rank_.push_back(to[n]);
    send_node_.insert(send_node_.end(), nodes.begin() + begin[n], nodes.begin() + begin[n + 1]);
    send_begin_.push_back(static_cast<std::int64_t>(send_node_.size()));
  }
  for (std::size_t n = 0; n < from.size(); ++n) {
    if (recv_count[n] == 0) continue;
    recv_rank_.push_back(from[n]);
    recv_begin_.push_back(recv_begin_.back() + recv_count[n]);
  }
  // The halo's table indices once, then its positions as at every step.
  const std::int64_t halo = size();
  id.resize(static_cast<std::size_t>(own + halo));
  x.resize(3 * static_cast<std::size_t>(own + halo));
  std::vector<std::int64_t> send_id(send_node_.size());
  for (std::size_t k = 0; k < send_node_.size(); ++k) send_id[k] = id[static_cast<std::size_t>(send_node_[k])];
  requests.clear();
  for (std::size_t n = 0; n < recv_rank_.size(); ++n) {
    requests.emplace_back();
    MPI_Irecv(&id[own + recv_begin_[n]], static_cast<int>(recv_begin_[n + 1] - recv_begin_[n]), MPI_INT64_T,
              recv_rank_[n], kIdTag, comm_, &requests.back());
  }
  for (std::size_t n = 0; n < send_rank_.size(); ++n) {
    requests.emplace_back();
    MPI_Isend(&send_id[send_begin_[n]], static_cast<int>(send_begin_[n + 1] - send_begin_[n]), MPI_INT64_T,
              send_rank_[n], kIdTag, comm_, &requests.back());
  }
  MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
  send_buffer_.resize(3 * send_node_.size());
  exchange(x.data(), x.data() + 3 * own);
}

void LongRangeHalo::exchange(const double* x_own, double* x_halo) {
  if (send_rank_.empty() && recv_rank_.empty()) return;
  // The previous exchange's sends are complete (its Waitall), so the buffer is free.
  requests_.clear();
  for (std::size_t n = 0; n < recv_rank_.size(); ++n) {
    requests_.emplace_back();
    MPI_Irecv(x_halo + 3 * recv_begin_[n], static_cast<int>(3 * (recv_begin_[n + 1] - recv_begin_[n])), MPI_DOUBLE,
              recv_rank_[n], kPositionTag, comm_, &requests_.back());
  }
  for (std::size_t k = 0; k < send_node_.size(); ++k)
    for (int c = 0; c < 3; ++c) send_buffer_[3 * k + c] = x_own[3 * static_cast<std::size_t>(send_node_[k]) + c];
  for (std::size_t n = 0; n < send_rank_.size(); ++n) {
    requests_.emplace_back();
    MPI_Isend(&send_buffer_[3 * send_begin_[n]], static_cast<int>(3 * (send_begin_[n + 1] - send_begin_[n])),
              MPI_DOUBLE, send_rank_[n], kPositionTag, comm_, &requests_.back());
  }
  MPI_Waitall(static_cast<int>(requests_.size()), requests_.data(), MPI_STATUSES_IGNORE);
  requests_.clear();
}

bool LongRangeHalo::on_any_rank(bool mine) const {
  if (ranks_ == 1) return mine;
  int in = mine ? 1 : 0, any = 0;
  MPI_Allreduce(&in, &any, 1, MPI_INT, MPI_LOR, comm_);
  return any != 0;
}

}  // namespace peri
