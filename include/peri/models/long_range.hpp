// Long-range forces between fiber nodes (Silling & Bobaru eqs. 32-36): a 6-12 pair potential
//   w2(y) = alpha (a/y)^12 - beta (a/y)^6       [J/m^6, energy per volume squared]
// on the *current* distance y of two nodes, never damaged, with its own horizon (the cutoff).
// The coefficients depend on the pair (eq. 34), symmetrically: scene rules tell apart adjacent
// and distant segments of one fiber and nodes of different fibers, or name two particular
// segments (each rule with its own cutoff, by default the section's); nodes of one segment, and
// pairs closer than the exclusion distance in the reference configuration (neighbours in one
// continuous body, where the singular force makes no sense), do not interact.
//
// The force density on node i is sum_j w2'(y_ij) (x_j - x_i)/y_ij V_j (eq. 35's second term with
// eq. 31's quadrature), w2'(y) = -12 alpha/a (a/y)^13 + 6 beta/a (a/y)^7. The energy booked is
// that of the potential shifted to zero at the cutoff (w2(y) - w2(cutoff)), so that pairs crossing
// the cutoff do not make the energy balance jump; the forces are those of eq. 35.
//
// The table of participating nodes (natural id, fiber, segment, reference position, volume: 48
// bytes per node) is replicated on every rank; the current positions are not. Each rank sums the
// pairs of its own nodes (the rows) over the nodes it sees: its own and a halo of the nodes owned
// elsewhere within the list's reach + skin (stages/long_range_halo.hpp exchanges them). This
// kernel, free of MPI, builds the Verlet list through a cell list on the current positions of the
// nodes seen and sums each row's pairs in ascending table order, whatever the rank count.
#pragma once
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "peri/geometry/discretization.hpp"
#include "peri/models/laws/pair.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

/// Every fiber node of a scene with long_range, in natural order, with what the rules read.
struct LongRangeTable {
  std::vector<std::int64_t> natural;  ///< node -> natural id (ascending)
  std::vector<int> fiber;             ///< fiber (a path of a fiber body), numbered over the scene
  std::vector<std::int32_t> segment;  ///< segment along its fiber (0 when segment_length is 0)
  std::vector<double> X;              ///< 3 per node: reference position [m]
  std::vector<double> volume;         ///< measure A ds [m^3]
  std::int64_t size() const { return static_cast<std::int64_t>(natural.size()); }
  /// Table index of a natural id, or -1 when that node takes no part.
  std::int64_t index_of(std::int64_t natural_id) const;
};

/// The table of a scene's fiber nodes (empty when the scene has no fiber body).
LongRangeTable long_range_table(const Nodes& nodes);

/// The pair law of a scene's long_range section. Its rules in effect are numbered: 0, 1, 2 the
/// pair kinds (PairKind; the first rule of each kind), then one per pair of segments that a
/// segments rule names (the first rule of that pair). Each has its coefficients and cutoff.
struct PairLaw {
  static constexpr int kMaxPairRules = 65535;  ///< rules in effect (the list stores 16 bits per pair)
  double length = 0, cutoff = 0, exclusion = 0;
  double reach = 0;  ///< the largest cutoff of a rule in effect: how far the neighbour list looks [m]
  bool acts[3] = {false, false, false};  ///< by PairKind: some rule matches
  /// Per rule in effect: the potential (beta < 0: a repulsive 1/y^6 tail) and its cutoff [m].
  std::vector<LennardJonesPair> potentials;
  std::vector<double> cutoffs;
  /// The segments rules in effect, sorted by (lo, hi), lo < hi: the rule number of each pair.
  struct SegmentPair {
    std::int32_t lo, hi;
    int rule;
  };
  std::vector<SegmentPair> segment_pairs;
  explicit PairLaw(const LongRange& spec);
  /// The potential of a pair kind (models/laws/pair.hpp).
  LennardJonesPair potential(PairKind k) const noexcept { return potentials[static_cast<int>(k)]; }
  /// w2(y) (eq. 33), unshifted.
  double energy(PairKind k, double y) const noexcept;
  /// dw2/dy: the scalar force, positive when the pair attracts.
  double force(PairKind k, double y) const noexcept;
  /// The rule in effect for table nodes p and q (0..2: a kind's, 3..: a segments rule's), or -1
  /// when they do not interact (one segment, or no rule). The reference exclusion and the
  /// cutoffs are not looked at here.
  int rule_of(const LongRangeTable& table, std::int64_t p, std::int64_t q) const;
  int rules() const { return static_cast<int>(potentials.size()); }
  /// What the pair sums read of each rule: alpha, beta, 12 alpha, 6 beta, cutoff^2 and
  /// w2(cutoff) (the energy's shift).
  struct Coefficients {
    double alpha, beta, alpha12, beta6, cut2, shift;
  };
  std::vector<Coefficients> coefficients() const;
};

/// The explicit step a pair rule's contact allows: a rule with a potential well (alpha, beta > 0,
/// its bottom at a (2 alpha / beta)^(1/6) inside the cutoff) pulls nodes together, and a pair that
/// falls in from rest comes as close as the potential's zero, sigma = a (alpha / beta)^(1/6), where
/// its stiffness k(sigma) = 114 beta^2 / (alpha sigma^2) comes on top of the bonds'. A fiber node
/// at sigma from a straight fiber of a body's nodes (spacing ds, measure V = pi d^2/4 ds, the
/// partners at hypot(sigma, k ds) within the cutoff) feels sum max(0, k) V, and the step of that
/// stiffness alone is sqrt(2 rho / sum) (as the bonds', Silling & Askari 2005). An estimate, not a
/// bound: more partners (a bundle, a coil) stiffen it further. Per rule of the scene's pairs list
/// with a well inside its cutoff, the smallest over the fiber bodies.
struct PairContactStep {
  int rule = 0;        ///< index in the scene's long_range.pairs
  double sigma = 0;    ///< the potential's zero [m]
  double dt = 0;       ///< [s]
  std::string body;    ///< the fiber body that gives the smallest step
  /// The step the bonds' stable step dt_bonds and this contact allow together (their stiffnesses
  /// add): 1 / sqrt(1 / dt_bonds^2 + 1 / dt^2).
  double with_bonds(double dt_bonds) const {
    return 1.0 / std::sqrt(1.0 / (dt_bonds * dt_bonds) + 1.0 / (dt * dt));
  }
  /// Whether a step dt_step takes more than kMargin of what the bonds and the contact allow
  /// (fiber_attracting_ends.yaml, its first nanosecond, alpha and beta both scaled by 10: the
  /// energy balance holds at 0.5 of it, 0.4% error, and fails at 0.7 and 0.83; the scene as given
  /// steps 0.42 of it).
  /// A contact that lowers the bonds' bound by less than a fifth is not counted (the stage's own
  /// safety_factor covers it: fiber_network.yaml's, 0.04%, at the default 0.7).
  static constexpr double kMargin = 0.5;
  bool exceeded_by(double dt_step, double dt_bonds) const {
    const double allowed = with_bonds(dt_bonds);
    return allowed < 0.8 * dt_bonds && dt_step > kMargin * allowed;
  }
};
std::vector<PairContactStep> pair_contact_steps(const Scene& scene);

/// Refuses (InputError naming the rule's `segments` key) a segments rule whose index names no
/// segment of any of the table's fibers.
void check_segment_rules(const LongRange& spec, const LongRangeTable& table);

/// Checks that the rules reach the scene's pairs. Refuses (InputError naming long_range.exclusion
/// and the rule) a rule in effect whose every pair of nodes lies closer than the exclusion in the
/// reference configuration, so that it would never act (an exclusion as long as the fiber, or as
/// the distance between two named segments), and (naming long_range) a section none of whose
/// rules applies to any pair (other_fibers with one fiber, segment kinds on fibers of one
/// segment). Returns the warnings, one line each: a rule in effect that applies to no pair while
/// others do, and a later rule that an earlier one of the same pairs shadows. The rule of a pair
/// depends only on the two nodes' fibers and segments: the table's runs of one (fiber, segment)
/// are compared two by two, by their bounding boxes first.
std::vector<std::string> check_pair_rules(const LongRange& spec, const PairLaw& law, const LongRangeTable& table);

/// The nodes a rank's pairs read: its rows and their possible partners, each with its table
/// index, current position and measure.
struct PairNodes {
  const std::int64_t* id = nullptr;    ///< table index of each; nullptr: node k is table node k
  const double* x = nullptr;           ///< current positions, 3 per node [m]
  const double* volume = nullptr;      ///< measure of each [m^3]
  std::int64_t count = 0;
  std::int64_t table_index(std::int64_t k) const { return id ? id[k] : k; }
};

/// Verlet list of the long-range pairs of some rows: every partner within its rule's cutoff +
/// skin (and not excluded by the rules) when it was built; rebuilt once any node has moved more
/// than skin / 2 since (then no pair within its cutoff can be missing from it: two nodes that
/// were farther apart than cutoff + skin at the build have each moved at most skin / 2, so they
/// are still farther apart than the cutoff).
struct LongRangeList {
  static constexpr int kPad = 8;       ///< unused entries past the end of partner and rule (whole lanes)
  double skin = 0;                     ///< [m]; 0: 1/4 of the section's cutoff (set_skin)
  std::vector<std::int64_t> begin;     ///< per row, into partner (rows + 1); begin.back(): the pairs
  std::vector<std::int32_t> partner;   ///< index among the PairNodes, ascending table index per row
  std::vector<std::uint16_t> rule;     ///< PairLaw's rule of each pair (kMaxPairRules at most)
  int shared_rule = -1;                ///< the rule of every pair where they share one, else -1
  std::vector<double> x_built;         ///< positions of the nodes seen at the build (3 each)
  long builds = 0;
  /// The default skin, a quarter of the section's cutoff, unless one was set.
  void set_skin(const PairLaw& law) {
    if (!(skin > 0)) skin = 0.25 * law.cutoff;  // the section's cutoff, not the reach
  }
  /// Whether some of the nodes seen has moved more than skin / 2 since the build, or their number
  /// changed (or no list was built).
  bool stale(const double* x, std::int64_t count) const;
};

/// Rebuilds `list` for the rows (indices among `nodes`): a cell list on the nodes' current
/// positions, every partner within its rule's cutoff + skin, partners in ascending table order.
void build_long_range_list(const PairLaw& law, const LongRangeTable& table, const PairNodes& nodes,
                           const std::int64_t* rows, std::int64_t row_count, LongRangeList& list);

/// Forces and energy of the long-range pairs of the rows (indices among `nodes`) through the
/// current `list` (built for these rows; not rebuilt here). Adds the force density of rows[k] to
/// force[3 * k ..] [N/m^3]; with_energy: returns half the shifted pair energies w2 V_i V_j summed
/// over the rows' pairs (each pair is counted once over all ranks) [J], else 0. Each row sums its
/// pairs in the list's order (ascending table index), the same on every rank. With
/// `energy_density` (and with_energy), also adds each row's share 1/2 sum_j (w2 - w2(cutoff)) V_j
/// [J/m^3] to energy_density[k].
double long_range_pair_forces(const PairLaw& law, const PairNodes& nodes, const std::int64_t* rows,
                              std::int64_t row_count, double* force, const LongRangeList& list,
                              bool with_energy = true, double* energy_density = nullptr);

/// The same where every table node is seen (one process; the tests): positions `x` of all table
/// nodes, rows `mine` (table indices); the list is rebuilt here when stale.
double long_range_forces(const PairLaw& law, const LongRangeTable& table, const double* x,
                         const std::vector<std::int64_t>& mine, double* force, LongRangeList& list,
                         bool with_energy = true, double* energy_density = nullptr);

}  // namespace peri
