#include "peri/diagnostics/crack_tip_monitor.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "peri/core/error.hpp"
#include "peri/core/json.hpp"
#include "peri/models/model.hpp"

namespace peri {
namespace {

constexpr int kTipColumns = 4;  // crack tip tracks with their own columns in series.csv

}  // namespace

std::unique_ptr<CrackTipMonitor> CrackTipMonitor::create(const Scene& scene, const std::vector<BondLaw>& laws,
                                                         const std::vector<BodyGeometry>& bodies,
                                                         const std::vector<double>& density, double sample_interval,
                                                         const Domain& domain, MPI_Comm comm) {
  double dx = 0, delta = 0, c_l = INFINITY, c_r = INFINITY;
  std::vector<bool> tip_bodies(laws.size(), false);
  for (std::size_t b = 0; b < laws.size(); ++b) {
    if (!laws[b].breaks() || !bodies[b].traits.flat) continue;  // flat sheets only
    tip_bodies[b] = true;
    const ElasticConstants e = elastic_constants(laws[b], bodies[b], density[b]);
    dx = std::max(dx, bodies[b].spacing);
    delta = std::max(delta, laws[b].horizon());
    c_l = std::min(c_l, e.c_longitudinal);
    c_r = std::min(c_r, e.c_rayleigh);
  }
  if (!(delta > 0)) return nullptr;
  CrackTipSettings s;
  s.link_distance = 2 * dx;
  s.tip_separation = 2 * delta;
  std::unique_ptr<CrackTipMonitor> m(
      new CrackTipMonitor(s, 10 * delta / c_l, s.tip_separation + 2 * c_l * sample_interval, domain, comm));
  m->tip_bodies_ = std::move(tip_bodies);
  for (const Crack& c : scene.cracks) {
    Vec3 centre{0.5 * (c.from[0] + c.to[0]), 0.5 * (c.from[1] + c.to[1]), 0.5 * (c.from[2] + c.to[2])};
    if (c.is_polygon()) {  // the corners' mean
      centre = {0, 0, 0};
      for (const Vec3& x : c.polygon)
        for (int k = 0; k < 3; ++k) centre[k] += x[k] / static_cast<double>(c.polygon.size());
    }
    for (int k = 0; k < 3; ++k) m->seeds_.push_back(centre[k]);
  }
  m->rayleigh_ = c_r;
  return m;
}

std::string CrackTipMonitor::series_columns() const {
  std::string columns = "crack_tips";
  for (int k = 0; k < kTipColumns; ++k)
    for (const char* c : {"_x", "_y", "_speed"}) columns += ",tip" + std::to_string(k) + c;
  return columns;
}

void CrackTipMonitor::restore(const std::vector<double>* flat) {
  // The tip history continues across restarts; the tips themselves are recomputed from damage.
  if (flat) tracker_.restore(*flat);
  broken_at_ = -1;
}

std::string CrackTipMonitor::sample(const EnergyRow& row, const std::function<const double*()>& damage_of) {
  const auto t0 = std::chrono::steady_clock::now();
  // The damage field changes only when bonds break: otherwise the last tips stand.
  if (row.broken_bonds != broken_at_) {
    broken_at_ = row.broken_bonds;
    const double* damage = damage_of();
    std::vector<std::int64_t> ids;
    std::vector<double> X;
    for (std::int32_t i = 0; i < domain_.owned; ++i)
      if (tip_bodies_[domain_.body[i]] && damage[i] >= tracker_.settings().damage_threshold) {
        ids.push_back(domain_.natural[i]);
        X.insert(X.end(), &domain_.X[3 * i], &domain_.X[3 * i] + 3);
      }
    // Every rank gathers the (few) damaged nodes, sorts them by natural id, finds the same tips.
    int ranks = 1;
    MPI_Comm_size(comm_, &ranks);
    const int n = static_cast<int>(ids.size());
    std::vector<int> counts(ranks), displs(ranks, 0), counts3(ranks), displs3(ranks, 0);
    MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
    for (int r = 0; r < ranks; ++r) {
      if (r > 0) displs[r] = displs[r - 1] + counts[r - 1];
      counts3[r] = 3 * counts[r];
      displs3[r] = 3 * displs[r];
    }
    const int total = displs.back() + counts.back();
    std::vector<std::int64_t> all_ids(total);
    std::vector<double> all_X(3 * static_cast<std::size_t>(total));
    MPI_Allgatherv(ids.data(), n, MPI_INT64_T, all_ids.data(), counts.data(), displs.data(), MPI_INT64_T, comm_);
    MPI_Allgatherv(X.data(), 3 * n, MPI_DOUBLE, all_X.data(), counts3.data(), displs3.data(), MPI_DOUBLE, comm_);
    std::vector<int> order(total);
    for (int k = 0; k < total; ++k) order[k] = k;
    std::sort(order.begin(), order.end(), [&](int a, int b) { return all_ids[a] < all_ids[b]; });
    std::vector<std::int64_t> sorted_ids(total);
    std::vector<double> sorted_X(3 * static_cast<std::size_t>(total));
    for (int k = 0; k < total; ++k) {
      sorted_ids[k] = all_ids[order[k]];
      for (int c = 0; c < 3; ++c) sorted_X[3 * k + c] = all_X[3 * order[k] + c];
    }
    last_tips_ = find_crack_tips(sorted_ids, sorted_X, seeds_, tracker_.settings());
  }
  tracker_.update(row.time, last_tips_);
  // Series columns: tip count, then position and speed of tracks 0..kTipColumns-1 if sampled now.
  std::ostringstream out;
  out << std::setprecision(12) << last_tips_.size();
  for (int k = 0; k < kTipColumns; ++k) {
    const CrackTrack* t = k < static_cast<int>(tracker_.tracks().size()) ? &tracker_.tracks()[k] : nullptr;
    if (t && t->active && t->time.back() == row.time) {
      out << ',' << t->position.back()[0] << ',' << t->position.back()[1] << ',';
      if (std::isfinite(t->speed.back())) out << t->speed.back();
    } else {
      out << ",,,";
    }
  }
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out.str();
}

std::string CrackTipMonitor::csv_rows(const EnergyRow& row) const {
  std::ostringstream out;
  out << std::setprecision(12);
  for (const CrackTrack& t : tracker_.tracks()) {
    if (!t.active || t.time.back() != row.time) continue;
    out << row.step << ',' << row.time << ',' << t.id << ',' << t.position.back()[0] << ',' << t.position.back()[1]
        << ',' << t.position.back()[2] << ',' << t.path_length.back() << ',';
    if (std::isfinite(t.speed.back())) out << t.speed.back();
    out << '\n';
  }
  return out.str();
}

std::string CrackTipMonitor::tracks_json() const {
  std::ostringstream j;
  j << "[";
  for (const CrackTrack& t : tracker_.tracks()) {
    const auto& p = t.position.back();
    const auto& p0 = t.position.front();
    double vmax = 0;
    for (double v : t.speed)
      if (std::isfinite(v)) vmax = std::max(vmax, v);
    const auto steady = tracker_.steady_part(t);
    j << (t.id ? "," : "") << "\n    {\"track\": " << t.id << ", \"active\": " << (t.active ? "true" : "false")
      << ", \"position\": [" << json_number(p[0]) << ", " << json_number(p[1]) << ", " << json_number(p[2]) << "]"
      << ", \"path_length\": " << json_number(t.path_length.back())
      << ", \"speed\": " << json_number(t.speed.back()) << ", \"max_speed\": " << json_number(vmax)
      << ", \"first_time\": " << json_number(t.time.front()) << ", \"last_time\": " << json_number(t.time.back())
      << ", \"first_position\": [" << json_number(p0[0]) << ", " << json_number(p0[1]) << ", "
      << json_number(p0[2]) << "]"
      << ", \"steady_from\": " << json_number(steady[0]) << ", \"steady_to\": " << json_number(steady[1])
      << ", \"steady_mean_speed\": " << json_number(steady[2] / (steady[1] - steady[0])) << "}";
  }
  j << (tracker_.tracks().empty() ? "]" : "\n  ]");
  return j.str();
}

}  // namespace peri
