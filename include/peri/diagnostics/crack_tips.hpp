// Crack tips: where the cracks of a per-node damage field end, and how fast they move.
// Pure: works on any per-node damage array given reference positions (peridynamic bonds or a
// lattice alike); no MPI, no PETSc. The caller gathers the damaged nodes of every rank (sorted by
// node id), so every rank computes the same tips from the same input.
//
// Tips of one sample (find_crack_tips):
//  1. A node is damaged when damage >= damage_threshold (default 0.3: a node next to a straight
//     crack through a disc family of radius 3 dx loses 35-40% of its weight, the next row 20%).
//  2. Damaged nodes closer than link_distance are neighbours; the connected components are the
//     cracks (clusters).
//  3. Each cluster gets a root: the cluster node nearest to a seed point (a pre-crack's midpoint)
//     if a seed lies within link_distance of the cluster (several seeds: several roots); else
//     the middle of its longest geodesic path (double sweep). Path length d = shortest distance
//     from the root(s) through the cluster's links (Dijkstra, Euclidean link lengths).
//  4. Tips are the nodes whose (d, -id) is largest among all cluster nodes within
//     tip_separation, with d >= tip_separation / 2, taken in decreasing d and kept only if no
//     kept tip lies within tip_separation (so a side branch shorter than about 0.7 x
//     tip_separation is not a tip, and noise on a crack's front makes one tip, not several).
//  5. A tip's position is the centroid of the front: the cluster nodes within link_distance of
//     the tip node whose d is within link_distance of the tip's.
//
// Tip histories (CrackTipTracker): each sample's tips are matched to the running tracks greedily
// by smallest distance (ties by track id, then tip order), a match allowed within max_jump; an
// unmatched tip starts a new track (a branch), an unmatched track ends. Speed of a track at a
// sample = |least-squares slope of its position over the samples in the trailing window
// (t - window, t]| (needs the track to be at least `window` old and 3 samples; NaN before).
// Mean speed over the steady part: per track, the time between the first samples at which the
// track's distance from its first position reaches 25% and 75% of its final distance; mean =
// sum of those distances / sum of those times over tracks that moved at least
// 4 x tip_separation.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

namespace peri {

struct CrackTipSettings {
  double damage_threshold = 0.3;  ///< node damaged when damage >= this
  double link_distance = 0;       ///< damaged nodes closer than this are connected [m]
  double tip_separation = 0;      ///< radius of the tip test; distinct tips are further apart [m]
};

struct CrackTip {
  std::array<double, 3> position{};  ///< front centroid, reference configuration [m]
  double path_length = 0;            ///< geodesic distance from the cluster's root [m]
  std::int64_t node = -1;            ///< id of the tip node
  int cluster = -1;                  ///< index of its cluster (0.., in order of lowest node id)
};

/// Tips of the damaged nodes given by ids (strictly increasing) and reference positions X
/// (3 per node), with optional seed points (3 per seed). Deterministic in its input.
std::vector<CrackTip> find_crack_tips(const std::vector<std::int64_t>& ids, const std::vector<double>& X,
                                      const std::vector<double>& seeds, const CrackTipSettings& s);

/// Convenience for a whole field: selects nodes with damage >= threshold (id = index).
std::vector<CrackTip> find_crack_tips_in_field(const std::vector<double>& X, const std::vector<double>& damage,
                                               const std::vector<double>& seeds, const CrackTipSettings& s);

/// Least-squares slope of y(t) (NaN with fewer than 2 distinct times).
double least_squares_slope(const double* t, const double* y, std::size_t n);

struct CrackTrack {
  int id = 0;
  bool active = true;
  std::vector<double> time;
  std::vector<std::array<double, 3>> position;
  std::vector<double> path_length;
  std::vector<double> speed;  ///< smoothed speed at each sample (NaN until the window is full)
};

class CrackTipTracker {
 public:
  CrackTipTracker(CrackTipSettings settings, double window, double max_jump);
  /// Add one sample's tips (times strictly increasing).
  void update(double time, const std::vector<CrackTip>& tips);
  const std::vector<CrackTrack>& tracks() const { return tracks_; }
  const CrackTipSettings& settings() const { return settings_; }
  double window() const { return window_; }
  /// Largest smoothed speed of any track (0 if none defined).
  double max_speed() const;
  /// Mean speed over the steady part (see file comment); NaN if no track moved enough.
  double mean_speed() const;
  /// Steady part of one track: (t25, t75, distance between); t25 = t75 = NaN if undefined.
  std::array<double, 3> steady_part(const CrackTrack& t) const;
  /// The tracks as a flat array (checkpoints), and back: restore(save()) gives the same tracker.
  std::vector<double> save() const;
  void restore(const std::vector<double>& flat);

 private:
  CrackTipSettings settings_;
  double window_, max_jump_;
  std::vector<CrackTrack> tracks_;
};

}  // namespace peri
