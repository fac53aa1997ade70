#include "peri/diagnostics/crack_tips.hpp"

#include "peri/core/error.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <stdexcept>
#include <tuple>
#include <unordered_map>

namespace peri {
namespace {

double dist(const double* a, const double* b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

// Uniform hash grid over points; neighbours within r are enumerated in a fixed order.
class PointGrid {
 public:
  PointGrid(const std::vector<double>& X, double cell) : X_(X), cell_(cell) {
    for (std::size_t i = 0; i < X.size() / 3; ++i) cells_[key(cell_of(&X[3 * i]))].push_back(static_cast<int>(i));
  }
  template <class F>
  void for_each_within(const double* p, double r, F&& f) const {
    const auto c = cell_of(p);
    const int reach = static_cast<int>(std::ceil(r / cell_));
    for (int a = -reach; a <= reach; ++a)
      for (int b = -reach; b <= reach; ++b)
        for (int e = -reach; e <= reach; ++e) {
          const auto it = cells_.find(key({c[0] + a, c[1] + b, c[2] + e}));
          if (it == cells_.end()) continue;
          for (int j : it->second)
            if (dist(p, &X_[3 * j]) <= r) f(j);
        }
  }

 private:
  std::array<std::int64_t, 3> cell_of(const double* p) const {
    return {static_cast<std::int64_t>(std::floor(p[0] / cell_)), static_cast<std::int64_t>(std::floor(p[1] / cell_)),
            static_cast<std::int64_t>(std::floor(p[2] / cell_))};
  }
  static std::uint64_t key(const std::array<std::int64_t, 3>& c) {
    const std::uint64_t m = (1u << 21) - 1;
    return ((std::uint64_t(c[0]) & m) << 42) | ((std::uint64_t(c[1]) & m) << 21) | (std::uint64_t(c[2]) & m);
  }
  const std::vector<double>& X_;
  double cell_;
  std::unordered_map<std::uint64_t, std::vector<int>> cells_;
};

}  // namespace

std::vector<CrackTip> find_crack_tips(const std::vector<std::int64_t>& ids, const std::vector<double>& X,
                                      const std::vector<double>& seeds, const CrackTipSettings& s) {
  if (!(s.link_distance > 0) || !(s.tip_separation > 0))
    throw std::invalid_argument("find_crack_tips: link_distance and tip_separation must be positive");
  const int n = static_cast<int>(ids.size());
  if (X.size() != 3 * ids.size()) throw std::invalid_argument("find_crack_tips: X must hold 3 values per node");
  std::vector<CrackTip> tips;
  if (n == 0) return tips;
  const double link = s.link_distance, sep = s.tip_separation;

  // Links between damaged nodes (CSR, neighbours in increasing index).
  const PointGrid grid(X, link);
  std::vector<int> off(n + 1, 0), adj;
  for (int i = 0; i < n; ++i) {
    std::vector<int> nb;
    grid.for_each_within(&X[3 * i], link, [&](int j) { if (j != i) nb.push_back(j); });
    std::sort(nb.begin(), nb.end());
    adj.insert(adj.end(), nb.begin(), nb.end());
    off[i + 1] = static_cast<int>(adj.size());
  }

  // Clusters: connected components, numbered in order of their lowest node.
  std::vector<int> cluster(n, -1);
  std::vector<std::vector<int>> members;
  for (int i = 0; i < n; ++i) {
    if (cluster[i] >= 0) continue;
    const int c = static_cast<int>(members.size());
    members.emplace_back();
    std::vector<int> stack{i};
    cluster[i] = c;
    while (!stack.empty()) {
      const int k = stack.back();
      stack.pop_back();
      members[c].push_back(k);
      for (int a = off[k]; a < off[k + 1]; ++a)
        if (cluster[adj[a]] < 0) cluster[adj[a]] = c, stack.push_back(adj[a]);
    }
    std::sort(members[c].begin(), members[c].end());
  }

  // Geodesic distances (Dijkstra) from a set of roots; ties broken by node index.
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> d(n, inf);
  auto dijkstra = [&](const std::vector<int>& roots, const std::vector<int>& nodes) {
    for (int k : nodes) d[k] = inf;
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> q;
    for (int r : roots) d[r] = 0, q.push({0.0, r});
    while (!q.empty()) {
      const auto [dk, k] = q.top();
      q.pop();
      if (dk > d[k]) continue;
      for (int a = off[k]; a < off[k + 1]; ++a) {
        const int j = adj[a];
        const double nd = dk + dist(&X[3 * k], &X[3 * j]);
        if (nd < d[j]) d[j] = nd, q.push({nd, j});
      }
    }
  };
  auto farthest = [&](const std::vector<int>& nodes) {
    int best = nodes.front();
    for (int k : nodes)
      if (d[k] > d[best]) best = k;
    return best;
  };

  std::vector<std::vector<int>> roots(members.size());
  for (std::size_t sd = 0; 3 * sd + 2 < seeds.size(); ++sd) {
    const double* p = &seeds[3 * sd];
    int best = -1;
    double bd = inf;
    grid.for_each_within(p, link, [&](int j) {
      const double e = dist(p, &X[3 * j]);
      if (e < bd || (e == bd && j < best)) bd = e, best = j;
    });
    if (best >= 0) roots[cluster[best]].push_back(best);
  }
  for (std::size_t c = 0; c < members.size(); ++c) {
    auto& r = roots[c];
    std::sort(r.begin(), r.end());
    r.erase(std::unique(r.begin(), r.end()), r.end());
    if (r.empty()) {
      // Middle of the longest geodesic path (double sweep).
      dijkstra({members[c].front()}, members[c]);
      const int a = farthest(members[c]);
      dijkstra({a}, members[c]);
      const int b = farthest(members[c]);
      const double half = 0.5 * d[b];
      // Walk back from b along decreasing d to the node nearest the half length.
      int k = b;
      while (d[k] > half) {
        int next = k;
        for (int e = off[k]; e < off[k + 1]; ++e)
          if (d[adj[e]] < d[next]) next = adj[e];
        if (next == k) break;
        k = next;
      }
      r.push_back(k);
    }
    dijkstra(r, members[c]);
  }

  // Tip candidates: largest (d, -index) within tip_separation in their own cluster.
  const PointGrid wide(X, sep);
  auto beats = [&](int a, int b) { return d[a] > d[b] || (d[a] == d[b] && a < b); };
  std::vector<int> candidates;
  for (int i = 0; i < n; ++i) {
    if (!(d[i] >= 0.5 * sep)) continue;
    bool top = true;
    wide.for_each_within(&X[3 * i], sep, [&](int j) {
      if (j != i && cluster[j] == cluster[i] && beats(j, i)) top = false;
    });
    if (top) candidates.push_back(i);
  }
  std::sort(candidates.begin(), candidates.end(), beats);
  std::vector<int> kept;
  for (int i : candidates) {
    bool far = true;
    for (int k : kept) far = far && dist(&X[3 * i], &X[3 * k]) > sep;
    if (far) kept.push_back(i);
  }
  // Report in cluster order, then by decreasing path length.
  std::sort(kept.begin(), kept.end(), [&](int a, int b) {
    return cluster[a] != cluster[b] ? cluster[a] < cluster[b] : beats(a, b);
  });
  for (int i : kept) {
    CrackTip t;
    t.node = ids[i];
    t.cluster = cluster[i];
    t.path_length = d[i];
    double sum[3] = {0, 0, 0};
    int count = 0;
    grid.for_each_within(&X[3 * i], link, [&](int j) {
      if (cluster[j] == cluster[i] && d[j] >= d[i] - link) {
        for (int c = 0; c < 3; ++c) sum[c] += X[3 * j + c];
        ++count;
      }
    });
    for (int c = 0; c < 3; ++c) t.position[c] = sum[c] / count;
    tips.push_back(t);
  }
  return tips;
}

std::vector<CrackTip> find_crack_tips_in_field(const std::vector<double>& X, const std::vector<double>& damage,
                                               const std::vector<double>& seeds, const CrackTipSettings& s) {
  std::vector<std::int64_t> ids;
  std::vector<double> Xd;
  for (std::size_t i = 0; i < damage.size(); ++i)
    if (damage[i] >= s.damage_threshold) {
      ids.push_back(static_cast<std::int64_t>(i));
      Xd.insert(Xd.end(), &X[3 * i], &X[3 * i] + 3);
    }
  return find_crack_tips(ids, Xd, seeds, s);
}

double least_squares_slope(const double* t, const double* y, std::size_t n) {
  if (n < 2) return std::numeric_limits<double>::quiet_NaN();
  double tm = 0, ym = 0;
  for (std::size_t k = 0; k < n; ++k) tm += t[k], ym += y[k];
  tm /= n;
  ym /= n;
  double stt = 0, sty = 0;
  for (std::size_t k = 0; k < n; ++k) stt += (t[k] - tm) * (t[k] - tm), sty += (t[k] - tm) * (y[k] - ym);
  return stt > 0 ? sty / stt : std::numeric_limits<double>::quiet_NaN();
}

CrackTipTracker::CrackTipTracker(CrackTipSettings settings, double window, double max_jump)
    : settings_(settings), window_(window), max_jump_(max_jump) {}

void CrackTipTracker::update(double time, const std::vector<CrackTip>& tips) {
  // Greedy matching by smallest distance between active tracks' last positions and tips.
  std::vector<std::tuple<double, int, int>> pairs;
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    if (!tracks_[k].active) continue;
    for (std::size_t j = 0; j < tips.size(); ++j) {
      const double e = dist(tracks_[k].position.back().data(), tips[j].position.data());
      if (e <= max_jump_) pairs.emplace_back(e, static_cast<int>(k), static_cast<int>(j));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<int> tip_track(tips.size(), -1);
  std::vector<char> track_used(tracks_.size(), 0);
  for (const auto& [e, k, j] : pairs)
    if (!track_used[k] && tip_track[j] < 0) track_used[k] = 1, tip_track[j] = k;
  for (std::size_t k = 0; k < tracks_.size(); ++k)
    if (!track_used[k]) tracks_[k].active = false;
  for (std::size_t j = 0; j < tips.size(); ++j) {
    if (tip_track[j] < 0) {
      tip_track[j] = static_cast<int>(tracks_.size());
      CrackTrack t;
      t.id = static_cast<int>(tracks_.size());
      tracks_.push_back(t);
    }
    CrackTrack& t = tracks_[tip_track[j]];
    t.time.push_back(time);
    t.position.push_back(tips[j].position);
    t.path_length.push_back(tips[j].path_length);
    // Trailing-window least-squares velocity.
    std::size_t first = t.time.size() - 1;
    while (first > 0 && t.time[first - 1] > time - window_) --first;
    const std::size_t m = t.time.size() - first;
    double speed = std::numeric_limits<double>::quiet_NaN();
    if (time - t.time.front() >= window_ && m >= 3) {
      double v2 = 0;
      std::vector<double> y(m);
      for (int c = 0; c < 3; ++c) {
        for (std::size_t k = 0; k < m; ++k) y[k] = t.position[first + k][c];
        const double v = least_squares_slope(&t.time[first], y.data(), m);
        v2 += v * v;
      }
      speed = std::sqrt(v2);
    }
    t.speed.push_back(speed);
  }
}

double CrackTipTracker::max_speed() const {
  double m = 0;
  for (const CrackTrack& t : tracks_)
    for (double v : t.speed)
      if (std::isfinite(v)) m = std::max(m, v);
  return m;
}

std::array<double, 3> CrackTipTracker::steady_part(const CrackTrack& t) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (t.time.size() < 3) return {nan, nan, 0};
  std::vector<double> travel(t.time.size());
  for (std::size_t k = 0; k < t.time.size(); ++k) travel[k] = dist(t.position[k].data(), t.position[0].data());
  const double total = travel.back();
  if (!(total > 0)) return {nan, nan, 0};
  double t25 = nan, t75 = nan, s25 = 0, s75 = 0;
  for (std::size_t k = 0; k < travel.size(); ++k) {
    if (std::isnan(t25) && travel[k] >= 0.25 * total) t25 = t.time[k], s25 = travel[k];
    if (std::isnan(t75) && travel[k] >= 0.75 * total) t75 = t.time[k], s75 = travel[k];
  }
  return {t25, t75, s75 - s25};
}

double CrackTipTracker::mean_speed() const {
  double distance = 0, duration = 0;
  for (const CrackTrack& t : tracks_) {
    if (t.time.empty() || dist(t.position.back().data(), t.position.front().data()) < 4 * settings_.tip_separation)
      continue;
    const auto [t25, t75, s] = steady_part(t);
    if (std::isfinite(t25) && std::isfinite(t75) && t75 > t25) distance += s, duration += t75 - t25;
  }
  return duration > 0 ? distance / duration : std::numeric_limits<double>::quiet_NaN();
}

std::vector<double> CrackTipTracker::save() const {
  std::vector<double> out{static_cast<double>(tracks_.size())};
  for (const CrackTrack& t : tracks_) {
    out.insert(out.end(), {static_cast<double>(t.id), t.active ? 1.0 : 0.0, static_cast<double>(t.time.size())});
    for (std::size_t k = 0; k < t.time.size(); ++k)
      out.insert(out.end(), {t.time[k], t.position[k][0], t.position[k][1], t.position[k][2], t.path_length[k],
                             t.speed[k]});
  }
  return out;
}

void CrackTipTracker::restore(const std::vector<double>& flat) {
  const auto bad = [] { throw InputError("checkpoint: crack-tip history is malformed"); };
  std::size_t at = 0;
  const auto next = [&]() {
    if (at >= flat.size()) bad();
    return flat[at++];
  };
  const auto count = [&]() {
    const double n = next();
    if (!(n >= 0 && n <= 1e9) || n != std::floor(n)) bad();
    return static_cast<std::size_t>(n);
  };
  std::vector<CrackTrack> tracks(count());
  for (CrackTrack& t : tracks) {
    t.id = static_cast<int>(next());
    t.active = next() != 0;
    const std::size_t n = count();
    if (n * 6 > flat.size() - std::min(at, flat.size())) bad();
    for (std::size_t k = 0; k < n; ++k) {
      t.time.push_back(next());
      t.position.push_back({next(), next(), next()});
      t.path_length.push_back(next());
      t.speed.push_back(next());
    }
  }
  if (at != flat.size()) bad();
  tracks_ = std::move(tracks);
}

}  // namespace peri
