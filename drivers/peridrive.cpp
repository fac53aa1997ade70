// peridrive: dynamic fracture of peridynamic membranes (and PMB solids) on MPI + PETSc.
//
//   mpirun -n 2 peridrive [scene.yaml] [--out DIR] [--set key=value ...] [PETSc options]
//   mpirun -n 2 peridrive --resume DIR            (continue a stopped or killed run)
//
// With no scene, runs the embedded default: example 7.1 of Silling & Bobaru (slit membrane).
#include <petscsys.h>

#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "peri/core/build_info.hpp"
#include "peri/io/checkpoint.hpp"
#include "peri/kernels/forces.hpp"
#include "peri/io/output.hpp"
#include "peri/io/restart.hpp"
#include "peri/stages/simulation.hpp"

namespace {

const char* kUsage = R"(usage: mpirun -n N peridrive [scene.yaml] [options] [PETSc options]

Runs a peridynamic fracture scene. Without a scene file, runs the embedded default scene
(Silling & Bobaru example 7.1: a slit membrane pulled apart, under a minute on 2 cores).

options:
  --out DIR          output directory (default: out/<scene name>)
  --resume PATH      continue a run from its last checkpoint: PATH is the run's output
                     directory (its checkpoint.h5, or checkpoint.prev.h5 if that is missing) or
                     a checkpoint file. The scene is the checkpoint's (a scene file given too must
                     resolve to the same physics); outputs continue in PATH (or --out), dropping
                     frames and series rows after the checkpoint's step
  --set KEY=VALUE    override a scene value, e.g. --set bodies.sheet.spacing=5e-4,
                     --set stages.0.duration=1e-5, --set boundaries.top.velocity=[0,20,0];
                     repeatable; VALUE is YAML
  --print-scene      print the resolved scene (defaults filled in) as YAML and exit
  --dry-run          validate, print the size estimate and the derived constants, write nothing
  --quiet            no progress lines
  --version          print the version and exit
  --help             this text
PETSc options (single dash, e.g. -log_view) pass through to PETSc. Partitioner (which rank owns
which node; results do not depend on it):
  -partition_method auto    the default: rcb for one square-grid body that fills its box, else cells
  -partition_method rcb     recursive coordinate bisection: flat cuts along grid planes, parts
                            weighted by their bonds, on every rank in O(N log N log P)
  -partition_method cells   METIS k-way on a coarse graph of cells of about the horizon (serial
                            on rank 0, memory O(cells), >= 64 cells per rank)
  -partition_method bonds   METIS k-way on the full bond graph (serial on rank 0, about 20 bytes
                            per ordered bond on rank 0 during setup)
  -partition_method petsc   PETSc MatPartitioning on the cell graph, in parallel; type by
                            -partition_mat_partitioning_type (default ptscotch)
  -partition_cells_per_part N   cells per rank at least (default 64; cells shrink to the spacing)
  -partition_line_weight W  weight of a cut across x lines (default 2; rcb, cells, petsc)
  -halo_chunk_nodes N       split a halo message to a rank on the same node into N-node messages
                            (default: one message; 160 keeps them below the 4 KB eager limit)
summary.json reports the method, edge cut, balance (largest rank's bonds / mean), partitioner
time, and the peak memory summed over ranks after each setup phase ("memory").

outputs (in DIR): frames.h5 + frames.xdmf (open in ParaView), series.csv (energies),
scene.resolved.yaml, summary.json (written last: its presence marks a complete run),
checkpoint.h5 (+ checkpoint.prev.h5) every output.checkpoint_every_steps / _seconds.
SIGTERM or SIGINT: all ranks write a final checkpoint and stop (a second signal ends at once);
while the scene is read or the run set up (and in --dry-run) they stop at once, writing nothing.
exit status: 0 success, 2 invalid input, 3 numerical failure, 5 stopped by SIGTERM/SIGINT (after
a final checkpoint once the run has begun: continue with --resume DIR), other values internal
errors. Limits and checks of scene values: docs/user/limits.md.
)";

struct Args {
  std::string scene;
  std::string out;
  std::string resume;
  std::vector<peri::Override> overrides;
  bool print_scene = false, dry_run = false, quiet = false, help = false, version = false;
  std::vector<char*> petsc;  // argv for PetscInitialize
};

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

Args parse_args(int argc, char** argv) {
  Args a;
  a.petsc.push_back(argv[0]);
  auto value = [&](int& k, const std::string& opt) -> std::string {
    if (k + 1 >= argc) throw peri::InputError("option " + opt + " needs a value; see --help");
    return argv[++k];
  };
  for (int k = 1; k < argc; ++k) {
    std::string s = argv[k];
    if (s == "--help" || s == "-h") a.help = true;
    else if (s == "--version") a.version = true;
    else if (s == "--quiet") a.quiet = true;
    else if (s == "--print-scene") a.print_scene = true;
    else if (s == "--dry-run") a.dry_run = true;
    else if (s == "--out") a.out = value(k, s);
    else if (s.rfind("--out=", 0) == 0) a.out = s.substr(6);
    else if (s == "--resume") a.resume = value(k, s);
    else if (s.rfind("--resume=", 0) == 0) a.resume = s.substr(9);
    else if (s == "--set" || s.rfind("--set=", 0) == 0) {
      const std::string kv = s == "--set" ? value(k, s) : s.substr(6);
      const auto eq = kv.find('=');
      if (eq == std::string::npos || eq == 0)
        throw peri::InputError("--set " + kv + ": expected KEY=VALUE, e.g. --set bodies.sheet.spacing=5e-4");
      a.overrides.push_back({kv.substr(0, eq), kv.substr(eq + 1)});
    } else if (s.rfind("--", 0) == 0) {
      throw peri::InputError("unknown option " + s + "; see --help");
    } else if (s[0] != '-' && a.scene.empty() && (ends_with(s, ".yaml") || ends_with(s, ".yml"))) {
      a.scene = s;
    } else {
      a.petsc.push_back(argv[k]);  // PETSc option or its value
    }
  }
  return a;
}

std::string fmt_error(double e) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2e", e);
  return buf;
}

int rank_of_world() {
  int r = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &r);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  std::string arg_error;
  try {
    args = parse_args(argc, argv);
  } catch (const peri::InputError& e) {
    arg_error = e.what();
    args.petsc.assign(1, argv[0]);
  }
  int pargc = static_cast<int>(args.petsc.size());
  args.petsc.push_back(nullptr);
  char** pargv = args.petsc.data();
  if (PetscInitialize(&pargc, &pargv, nullptr, nullptr) != 0) return 4;
  peri::install_stop_handlers();  // after PETSc's own handlers, which would abort on SIGTERM
  const int rank = rank_of_world();
  int status = 0;
  try {
    if (!arg_error.empty()) throw peri::InputError(arg_error);
    if (args.help || args.version) {
      if (rank == 0) {
        if (args.help) std::fputs(kUsage, stdout);
        else std::printf("peridrive %s (%s), bond kernel %s\n", peri::version(), peri::git_revision(), peri::bond_kernel_isa());
      }
    } else {
      std::shared_ptr<const peri::Checkpoint> checkpoint;
      std::string checkpoint_file;
      if (!args.resume.empty()) {
        checkpoint_file = peri::resolve_resume_path(args.resume);
        checkpoint = peri::load_checkpoint(checkpoint_file, PETSC_COMM_WORLD);
        if (args.out.empty()) {
          const std::string dir = std::filesystem::path(checkpoint_file).parent_path().string();
          args.out = dir.empty() ? "." : dir;
        }
      }
      // A stop request ends the reading on the ranks that see it; all ranks then agree (a stop
      // wins over an input error, which every rank that read the whole scene found alike).
      const peri::StopCheck stop = [] { return peri::stop_signal() != 0; };
      peri::Scene scene;
      std::exception_ptr invalid;
      int stopped = 0, stopped_any = 0;
      try {
        scene = !args.scene.empty() ? peri::load_scene(args.scene, args.overrides, stop)
                : checkpoint        ? peri::parse_scene(checkpoint->scene, checkpoint_file + ": scene", args.overrides, stop)
                                    : peri::parse_scene(peri::default_scene_text(), "<default scene>", args.overrides, stop);
      } catch (const peri::StopRequested&) {
        stopped = peri::stop_signal();
      } catch (const peri::InputError&) {
        invalid = std::current_exception();
      }
      MPI_Allreduce(&stopped, &stopped_any, 1, MPI_INT, MPI_MAX, PETSC_COMM_WORLD);
      if (stopped_any)
        throw peri::StopRequested("stopped by signal " + std::to_string(stopped_any) +
                                  " while reading the scene; nothing was written");
      if (invalid) std::rethrow_exception(invalid);
      if (args.print_scene) {
        if (rank == 0) std::fputs(peri::emit_scene(scene).c_str(), stdout);
      } else if (args.dry_run) {
        const peri::SizeEstimate e = peri::estimate_size(scene);
        if (rank == 0) {
          std::printf("estimate: %.4g nodes, %.4g bonds, %.4g GB\n", e.nodes, e.bonds / 2, e.bytes / 1e9);
          std::fflush(stdout);
        }
        peri::Simulation sim(scene, PETSC_COMM_WORLD, {});
        if (rank == 0) {
          for (const std::string& line : sim.derived_lines()) std::printf("%s\n", line.c_str());
        }
      } else {
        peri::RunOptions opt;
        opt.out_dir = args.out.empty() ? "out/" + scene.name : args.out;
        opt.quiet = args.quiet;
        opt.restart = checkpoint;
        peri::Simulation sim(scene, PETSC_COMM_WORLD, opt);
        try {
          sim.run();
        } catch (const peri::RuntimeFailure& e) {
          if (rank == 0) peri::write_text_file(opt.out_dir + "/FAILED", std::string(e.what()) + "\n");
          throw;
        }
        const peri::RunSummary& s = sim.summary();
        const bool preload_counted = s.run_energy_balance_error != s.energy_balance_error;
        if (sim.stopped()) {
          if (rank == 0)
            std::fprintf(stderr, "peridrive: stopped by signal %d at step %lld/%lld; checkpoint %s; continue with: "
                         "peridrive --resume %s\n", peri::stop_signal(), static_cast<long long>(sim.current_step()),
                         static_cast<long long>(sim.total_steps()), sim.checkpoint_path().c_str(), opt.out_dir.c_str());
          status = peri::kExitStopped;
        } else if (rank == 0 && !args.quiet)
          std::printf("[peridrive] done: %lld steps (%lld timed here) in %.3g s (%.3g bond updates/s), %lld bonds "
                      "broken; energy balance error %.2e%s; results in %s/\n",
                      static_cast<long long>(s.steps), static_cast<long long>(s.steps_timed), s.wall_seconds,
                      s.step_seconds > 0 ? double(s.ordered_bonds) * s.steps_timed / s.step_seconds : 0.0,
                      static_cast<long long>(s.final_energy.broken_bonds), s.energy_balance_error,
                      preload_counted ? (" (explicit part; whole run, quasi-static work included: " +
                                         fmt_error(s.run_energy_balance_error) + ")").c_str() : "",
                      opt.out_dir.c_str());
      }
    }
  } catch (const peri::StopRequested& e) {
    // Decided together (the scene reading above, the setup's stop points): all ranks arrive here.
    if (rank == 0) std::fprintf(stderr, "peridrive: %s\n", e.what());
    status = peri::kExitStopped;
  } catch (const peri::InputError& e) {
    // Input is validated identically on every rank: all ranks arrive here together.
    if (rank == 0) std::fprintf(stderr, "peridrive: error: %s\n", e.what());
    status = 2;
  } catch (const peri::RuntimeFailure& e) {
    if (rank == 0) std::fprintf(stderr, "peridrive: error: %s\n", e.what());
    status = 3;
  } catch (const std::exception& e) {
    // Possibly raised on this rank alone: abort the job rather than leave others waiting.
    std::fprintf(stderr, "peridrive: internal error on rank %d: %s\n", rank, e.what());
    MPI_Abort(PETSC_COMM_WORLD, 4);
  }
  PetscFinalize();
  return status;
}
