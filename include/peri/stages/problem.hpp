// The problem a run solves, built once by the setup (setup.cpp) along DESIGN.md's data flow:
// scene -> nodes -> bonds -> partition -> this rank's domain and state -> the force model and
// the loads -> the stages' time steps. Everything here is fixed after the setup except the
// state (u, v), the bond flags and the force model's work arrays; the stages, diagnostics and
// output read it.
#pragma once
#include <mpi.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "peri/geometry/discretization.hpp"
#include "peri/loads/boundaries.hpp"
#include "peri/loads/load.hpp"
#include "peri/loads/tools.hpp"
#include "peri/partition/domain.hpp"
#include "peri/scene/scene.hpp"
#include "peri/stages/forces.hpp"
#include "peri/state/state.hpp"

namespace peri {

struct RunSummary;

/// Each stage's time step and step count.
struct StagePlan {
  double dt_stable = 0;             ///< the stable bound at the reference state, with the tools' penalty [s]
  std::vector<double> dt;           ///< per stage [s] (0: a stage that takes no time)
  std::vector<std::int64_t> steps;  ///< per stage (0: a stage that takes no time)
  std::int64_t total = 0;           ///< steps of all stages
};

struct Problem {
  Problem(const Scene& scene, MPI_Comm comm);
  Problem(const Problem&) = delete;
  Problem& operator=(const Problem&) = delete;

  Scene scene;
  MPI_Comm comm;
  int rank = 0, ranks = 1;
  std::vector<BodyGeometry> bodies;       ///< per body (the nodes' arrays are the domain's)
  std::vector<double> density;            ///< per body [kg/m^3]
  Domain domain;                          ///< this rank's nodes (owned, then ghosts) and bonds
  std::unique_ptr<State> state;           ///< displacement, velocity (ghosted Vecs), halo plans
  std::vector<double> mass, inv_density;  ///< per owned node [kg], [m^3/kg]
  double energy_floor = 0;                ///< smallest energy scale of the balance [J]
  std::unique_ptr<Forces> forces;         ///< bond laws, lattice, long-range forces; the bond loop's plans
  std::unique_ptr<Boundaries> boundaries; ///< prescribed motion
  std::vector<std::unique_ptr<Load>> loads;  ///< forces beside the bonds', in the order they add up
  Tools* tools = nullptr;                 ///< the tools among the loads, if any
  StagePlan stages;
  std::int64_t frame_nodes = 0;           ///< nodes a frame holds (output.node_stride, output.region)
  std::string resolved;                   ///< the resolved scene, with the derived constants as comments
};

/// Builds the problem of `scene` on the ranks of `comm`, checking on the way everything that
/// needs the discretization (InputError, the same on every rank, before anything is written;
/// StopRequested when a stop signal arrives), and puts the setup's figures (sizes, partition,
/// memory per phase, time steps, derived constants) in `summary`. Collective.
std::unique_ptr<Problem> build_problem(const Scene& scene, MPI_Comm comm, RunSummary& summary);

/// The initial conditions: displacement and velocity from the scene's gradients about its
/// centre, the seed, and the boundaries' initial velocities.
void apply_initial_conditions(const Problem& p);

}  // namespace peri
