// Crack tips of a running simulation: at each series row, the tips of the damage field of the
// breaking membranes (crack_tips.hpp), their tracks and speeds; the series columns they fill,
// the rows of tips.csv, and the summary's speeds. Every rank gathers the few damaged nodes and finds
// the same tips, so the tracks are identical on every rank. (tips.csv: the rows csv_rows() gives.)
#pragma once
#include <mpi.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "peri/diagnostics/crack_tips.hpp"
#include "peri/diagnostics/energies.hpp"
#include "peri/geometry/discretization.hpp"
#include "peri/models/law.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

class CrackTipMonitor {
 public:
  /// Tracking runs when some membrane material breaks (crack tips are paths in a sheet; solid
  /// bodies have crack surfaces and are not tracked): nullptr otherwise. Lengths from the
  /// breaking bodies (crack_tips.hpp): link 2 dx, tip separation 2 delta, window 10 delta / c_l,
  /// jumps up to 2 delta + 2 c_l x `sample_interval` (the time between series rows). Seeds: the
  /// pre-cracks' midpoints. laws, bodies, density: per body.
  static std::unique_ptr<CrackTipMonitor> create(const Scene& scene, const std::vector<BondLaw>& laws,
                                                 const std::vector<BodyGeometry>& bodies,
                                                 const std::vector<double>& density, double sample_interval,
                                                 const Domain& domain, MPI_Comm comm);

  /// The series columns' names (comma-separated): the tip count, then x, y and speed of the
  /// first tracks.
  std::string series_columns() const;
  /// One sample at `row`: the tips of the damage field (`damage()` gives the owned nodes' damage;
  /// called only when bonds broke since the last sample) and their tracks. Returns the series
  /// columns' values. Collective.
  std::string sample(const EnergyRow& row, const std::function<const double*()>& damage);
  /// The rows of tips.csv for the tracks sampled at `row` (step,time,track,x,y,z,path_length,speed).
  static constexpr const char* kCsvHeader = "step,time,track,x,y,z,path_length,speed\n";
  std::string csv_rows(const EnergyRow& row) const;

  /// The tracks as a flat array (checkpoints), and back (nullptr: a checkpoint without them).
  std::vector<double> save() const { return tracker_.save(); }
  void restore(const std::vector<double>* flat);

  double rayleigh_wave_speed() const { return rayleigh_; }
  double window() const { return tracker_.window(); }
  double max_speed() const { return tracker_.max_speed(); }
  double mean_speed() const { return tracker_.mean_speed(); }
  /// JSON array, one object per track (summary.json's crack_tips).
  std::string tracks_json() const;
  /// Time spent finding and tracking tips on this rank [s].
  double seconds() const { return seconds_; }
  const CrackTipTracker& tracker() const { return tracker_; }

 private:
  CrackTipMonitor(CrackTipSettings settings, double window, double max_jump, const Domain& domain, MPI_Comm comm)
      : tracker_(settings, window, max_jump), domain_(domain), comm_(comm) {}

  CrackTipTracker tracker_;
  const Domain& domain_;
  MPI_Comm comm_;
  std::vector<bool> tip_bodies_;    // per body: its crack tips are tracked (breaking membranes)
  std::vector<double> seeds_;       // pre-crack midpoints
  double rayleigh_ = 0;             // smallest Rayleigh wave speed of the tracked bodies
  std::int64_t broken_at_ = -1;     // broken-bond count of the last sample
  std::vector<CrackTip> last_tips_;
  double seconds_ = 0;
};

}  // namespace peri
