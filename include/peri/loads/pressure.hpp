// Internal pressure of sphere bodies (Silling & Bobaru 7.2, the balloon) and of mesh membranes (on
// their files' triangles, as oriented there), a follower load: each triangle (the sphere's
// geodesic ones, the mesh's) carries p(t) times its current area vector, a third to each
// corner whose bonds to the other two corners are intact (a torn triangle holds no gas). p rises
// linearly from 0 over the body's pressure_ramp_time. Work: the mean of the two forces of a node
// times its displacement between two booked evaluations (trapezoidal).
// In quasi-static stages the pressure steps with the load factor instead of the time (from its
// value at the stage's start to the full p) and stays full after; its stiffness, not symmetric
// (a follower load), joins the tangent.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "peri/geometry/discretization.hpp"
#include "peri/loads/load.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"

namespace peri {

class Pressure final : public Load {
 public:
  /// The loaded sphere bodies' triangles (bodies: per body, with their triangles) at this rank's
  /// owned corners. `domain`: this rank's nodes and bonds, read at every evaluation.
  Pressure(const Scene& scene, const std::vector<BodyGeometry>& bodies, const Domain& domain);
  /// Whether no body is loaded (the scene needs no pressure load).
  bool empty() const { return loads_.empty(); }
  void add_forces(double t, const LoadTarget& target, bool book, EnergyLedger& ledger) override;
  bool quasistatic() const override { return true; }
  void begin_quasistatic(double t) override;
  void set_quasistatic_level(double level) override;
  std::string quasistatic_text(double level) const override;
  void add_stiffness(const LoadTarget& target, const StiffnessSink& sink) const override;

 private:
  struct Sphere {
    std::string body;  // its name
    double pressure = 0, ramp = 0;
    double held = -1, held_from = 0;  // quasi-static: p held at `held` (< 0: p(t)), level 0 at held_from
    std::vector<std::int32_t> node;                   // owned loaded nodes (local)
    std::vector<double> inv_volume;                   // per loaded node, 1 / its measure
    std::vector<std::int64_t> begin{0};               // per loaded node, into the lists below
    std::vector<std::int32_t> triangle;               // per share: its triangle, into `corners`
    std::vector<std::array<std::int32_t, 3>> corners;  // the triangles met (local corners, the file's order)
    std::vector<double> area;                          // per triangle, its current 2 x area vector
    std::vector<std::array<std::int64_t, 2>> bonds;   // CSR positions of the bonds to the other two
                                                      // corners, in turn after the node (-1: none)
    std::vector<double> force_prev, x_prev;           // per loaded node: last force [N], position
    bool started = false;
  };
  double current(const Sphere& load, double t) const;
  bool intact(std::int64_t q) const { return q < 0 || !(domain_.bonds.broken[q] & 1); }
  /// A share's triangle's other two corners, in turn after node i (counter-clockwise).
  static std::array<std::int32_t, 2> others(const Sphere& load, std::int64_t e, std::int32_t i) {
    const auto& t = load.corners[load.triangle[e]];
    const int k = t[0] == i ? 0 : t[1] == i ? 1 : 2;
    return {t[(k + 1) % 3], t[(k + 2) % 3]};
  }
  const Domain& domain_;
  std::vector<Sphere> loads_;
};

}  // namespace peri
