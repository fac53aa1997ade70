// peridrive: dynamic fracture of peridynamic membranes (and PMB solids) on MPI + PETSc.
//
//   mpirun -n 2 peridrive [scene] [--out DIR] [--set key=value ...] [PETSc options]
//   mpirun -n 2 peridrive --resume DIR            (continue a stopped or killed run)
//
// With no scene, runs the embedded default: example 7.1 of Silling & Bobaru (slit membrane).
#include <petscsys.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
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
#include "peri/io/run_dir.hpp"
#include "peri/scene/describe.hpp"
#include "peri/core/format.hpp"
#include "peri/stages/simulation.hpp"

namespace {

const char* kUsage = R"(usage: mpirun -n N peridrive [scene] [options] [PETSc options]

Runs a peridynamic fracture scene. The scene is the first argument that is not an option, whatever
its name: a YAML file (a regular file of at most 64 MiB). Without one, runs the embedded default
scene (Silling & Bobaru example 7.1: a slit membrane pulled apart, under a minute on 2 cores).

options (a value must not be empty nor start with '-': write ./-name for such a path):
  --out DIR          output directory (default: out/<scene name>), created if missing. One run
                     writes into a directory at a time: rank 0 holds DIR/.peridrive.lock, naming
                     it, for the whole run, and another run or resume into DIR is refused. A fresh
                     run removes every file of an earlier run in DIR before it writes
  --resume PATH      continue a run from its last checkpoint: PATH is the run's output
                     directory (its checkpoint.h5, or checkpoint.prev.h5 if that is missing) or
                     a checkpoint file. The scene is the checkpoint's (a scene file given too must
                     resolve to the same physics); outputs continue in PATH (or --out), dropping
                     frames and series rows after the checkpoint's step. --out must be new, hold
                     no run's files, or hold the checkpoint's own run (same scene)
  --set KEY=VALUE    override a scene value, e.g. --set bodies.sheet.spacing=5e-4,
                     --set stages.0.duration=1e-5, --set boundaries.top.velocity=[0,20,0];
                     repeatable; VALUE is YAML
  --print-scene      print the resolved scene (defaults filled in) as YAML and exit
  --dry-run          validate, print the size estimate and the derived constants, write nothing
  --describe-keys    print every scene key with its unit, default and meaning, and exit;
                     --format text (the default) or --format markdown (the tables of
                     docs/user/scene-reference.md)
  --quiet            no progress lines
  --version          print the version and exit
  --help             this text
PETSc options (one dash and a letter, e.g. -log_view) pass through to PETSc; the argument after
one is its value unless it is an option (or, before any scene, a name ending in .yaml or .yml).
Partitioner (which rank owns which node; results do not depend on it):
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
SIGTERM or SIGINT to a rank: all ranks write a final checkpoint and stop (a second signal ends at
once); while the scene is read or the run set up (and in --dry-run) they stop at once, writing
nothing; in a quasi-static stage, at its next load increment, with DIR/FAILED (no checkpoint
part-way through a stage). mpirun forwards SIGTERM to the ranks but sends SIGKILL 1 s later (Open MPI's
odls_base_sigkill_timeout). Ranks started by mpirun end at once (SIGKILL) if mpirun dies.
exit status: 0 success, 2 invalid input (command line, scene, output directory, checkpoint;
nothing written), 3 failure during the run (numerical, or output that cannot be written, e.g. on a
full disk; DIR/FAILED), 4 internal error (MPI_ABORT),
5 stopped by SIGTERM/SIGINT (after a final checkpoint once the run has begun: continue with
--resume DIR). See docs/user/running.md; limits and checks of scene values: docs/user/limits.md.
)";

struct Args {
  std::string scene;
  bool has_scene = false;
  std::string out;
  std::string resume;
  std::vector<peri::Override> overrides;
  bool print_scene = false, dry_run = false, quiet = false, help = false, version = false;
  bool describe_keys = false;
  std::string format;  // of --describe-keys: text (default) or markdown
  std::vector<char*> petsc;  // argv for PetscInitialize
  std::string command;       // the command line, for the output directory's lock
};

bool ends_with_nocase(const std::string& s, const std::string& suffix) {
  if (s.size() < suffix.size()) return false;
  for (std::size_t k = 0; k < suffix.size(); ++k)
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + k])) != suffix[k]) return false;
  return true;
}

// A PETSc option: one dash and a letter (-log_view), as PETSc itself tells options from values.
bool petsc_option(const std::string& s) {
  return s.size() > 1 && s[0] == '-' && std::isalpha(static_cast<unsigned char>(s[1]));
}

Args parse_args(int argc, char** argv) {
  Args a;
  a.petsc.push_back(argv[0]);
  for (int k = 0; k < argc; ++k) a.command.append(k ? " " : "").append(argv[k]);
  // An option's value: present, not empty, and not another option (--out --dry-run is a slip,
  // not a directory named --dry-run; write ./-name for a name that starts with a dash).
  auto checked = [](const std::string& opt, const std::string& v) {
    if (v.empty()) throw peri::InputError("option " + opt + ": expected a value, got an empty string");
    if (v[0] == '-')
      throw peri::InputError("option " + opt + " needs a value, got the option '" + v + "'" +
                             (opt == "--set" ? "" : " (a path that starts with '-' is written ./" + v + ")"));
    return v;
  };
  auto value = [&](int& k, const std::string& opt) -> std::string {
    if (k + 1 >= argc) throw peri::InputError("option " + opt + " needs a value; see --help");
    return checked(opt, argv[++k]);
  };
  auto once = [](std::string& slot, const std::string& opt, const std::string& v) {
    if (!slot.empty()) throw peri::InputError("option " + opt + " given twice ('" + slot + "' and '" + v + "')");
    slot = v;
  };
  bool after_petsc_option = false;  // the previous argument was a PETSc option: this may be its value
  for (int k = 1; k < argc; ++k) {
    const std::string s = argv[k];
    const bool petsc_value_allowed = after_petsc_option;
    after_petsc_option = false;
    if (s == "--help" || s == "-h") a.help = true;
    else if (s == "--version") a.version = true;
    else if (s == "--quiet") a.quiet = true;
    else if (s == "--print-scene") a.print_scene = true;
    else if (s == "--dry-run") a.dry_run = true;
    else if (s == "--describe-keys") a.describe_keys = true;
    else if (s == "--format") once(a.format, s, value(k, s));
    else if (s.rfind("--format=", 0) == 0) once(a.format, "--format", checked("--format", s.substr(9)));
    else if (s == "--out") once(a.out, s, value(k, s));
    else if (s.rfind("--out=", 0) == 0) once(a.out, "--out", checked("--out", s.substr(6)));
    else if (s == "--resume") once(a.resume, s, value(k, s));
    else if (s.rfind("--resume=", 0) == 0) once(a.resume, "--resume", checked("--resume", s.substr(9)));
    else if (s == "--set" || s.rfind("--set=", 0) == 0) {
      const std::string kv = s == "--set" ? value(k, s) : checked("--set", s.substr(6));
      const auto eq = kv.find('=');
      if (eq == std::string::npos || eq == 0)
        throw peri::InputError("--set " + peri::shown_value(kv) + ": expected KEY=VALUE, e.g. --set bodies.sheet.spacing=5e-4");
      a.overrides.push_back({kv.substr(0, eq), kv.substr(eq + 1)});
    } else if (s.rfind("--", 0) == 0) {
      throw peri::InputError("unknown option " + peri::shown_value(s) + "; see --help");
    } else if (petsc_option(s)) {
      a.petsc.push_back(argv[k]);
      after_petsc_option = true;
    } else if (petsc_value_allowed) {
      // The PETSc option's value, as PETSc reads it; but a name ending in .yaml or .yml while no
      // scene was given is the scene (-log_view scene.yaml), unless the option takes a file.
      const std::string opt = a.petsc.back();
      if (!a.has_scene && !s.empty() && s[0] != '-' && (ends_with_nocase(s, ".yaml") || ends_with_nocase(s, ".yml")) &&
          opt != "-options_file" && opt != "-options_file_yaml") {
        a.scene = s;
        a.has_scene = true;
      } else {
        a.petsc.push_back(argv[k]);
      }
    } else if (!s.empty() && s[0] == '-') {
      throw peri::InputError("unexpected argument '" + s + "'; see --help");
    } else if (!a.has_scene) {
      a.scene = s;  // the scene, whatever its name
      a.has_scene = true;
    } else {
      throw peri::InputError("unexpected argument '" + s + "': the scene is '" + a.scene +
                             "' (one scene per run; PETSc options take their value right after them)");
    }
  }
  if (!a.format.empty() && !a.describe_keys)
    throw peri::InputError("option --format applies to --describe-keys only; see --help");
  if (!a.format.empty() && a.format != "text" && a.format != "markdown")
    throw peri::InputError("option --format: expected text or markdown, got '" + a.format + "'");
  return a;
}

// The scene file's text, read on rank 0 with limits and broadcast: every rank parses the same
// text or none does. InputError naming the file otherwise. Collective.
std::string read_scene_text(const std::string& path, MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::string text, error;
  if (rank == 0) error = peri::read_input_file(path, peri::kMaxSceneFileBytes, text);
  long long sizes[2] = {static_cast<long long>(error.size()), static_cast<long long>(text.size())};
  MPI_Bcast(sizes, 2, MPI_LONG_LONG, 0, comm);
  error.resize(static_cast<std::size_t>(sizes[0]));
  text.resize(static_cast<std::size_t>(sizes[1]));
  MPI_Bcast(error.data(), static_cast<int>(sizes[0]), MPI_CHAR, 0, comm);
  if (!error.empty()) throw peri::InputError("cannot read scene file '" + path + "': " + error);
  MPI_Bcast(text.data(), static_cast<int>(sizes[1]), MPI_CHAR, 0, comm);  // <= 64 MiB
  return text;
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
  peri::end_with_launcher();  // first: a rank outlives no launcher
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
    if (args.help || args.version || args.describe_keys) {
      if (rank == 0) {
        if (args.help) std::fputs(kUsage, stdout);
        else if (args.describe_keys)
          std::fputs(peri::describe_scene_keys(args.format == "markdown" ? peri::KeyFormat::Markdown
                                                                          : peri::KeyFormat::Text)
                         .c_str(),
                     stdout);
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
        scene = args.has_scene ? peri::parse_scene(read_scene_text(args.scene, PETSC_COMM_WORLD), args.scene,
                                                   args.overrides, stop)
                : checkpoint   ? peri::parse_scene(checkpoint->scene, checkpoint_file + ": scene", args.overrides, stop)
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
          // (an estimate that overflowed reads ">1e308", as in the memory check's message)
          auto amount = [](double v) {
            char buf[32];
            if (std::isfinite(v)) std::snprintf(buf, sizeof buf, "%.4g", v);
            else std::snprintf(buf, sizeof buf, ">1e308");
            return std::string(buf);
          };
          std::printf("estimate: %s nodes, %s bonds, %s GB\n", amount(e.nodes).c_str(), amount(e.bonds / 2).c_str(),
                      amount(e.bytes / 1e9).c_str());
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
        // Before setup and before anything in the directory is touched: one run per directory,
        // and a resume only into the checkpoint's own run (or a new or empty directory).
        const peri::OutputDirLock lock(opt.out_dir, args.command, PETSC_COMM_WORLD);
        const std::vector<std::string> later =
            checkpoint ? peri::check_resume_dir(opt.out_dir, *checkpoint, checkpoint_file, PETSC_COMM_WORLD)
                       : std::vector<std::string>{};
        peri::Simulation sim(scene, PETSC_COMM_WORLD, opt);
        for (const std::string& path : later) std::remove(path.c_str());  // as the frames after the step
        try {
          sim.run();
        } catch (const peri::StopRequested& e) {  // (a quasi-static stage stopped part-way)
          try {
            if (rank == 0) peri::write_text_file(opt.out_dir + "/FAILED", std::string(e.what()) + "\n");
          } catch (const peri::Error&) {
          }
          throw;
        } catch (const peri::RuntimeFailure& e) {
          try {  // (on a full disk the marker may not fit either: the message below still says why)
            if (rank == 0) peri::write_text_file(opt.out_dir + "/FAILED", std::string(e.what()) + "\n");
          } catch (const peri::Error&) {
          }
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
    if (peri::abandoned_output_files()) {
      // A file whose parallel writes failed is left open: HDF5 1.10 would crash closing it at
      // MPI_Finalize. Every rank is here (the failure was agreed on); end without finalizing.
      std::fflush(nullptr);
      MPI_Barrier(PETSC_COMM_WORLD);
      std::_Exit(status);
    }
  } catch (const std::exception& e) {
    // Possibly raised on this rank alone: abort the job rather than leave others waiting.
    std::fprintf(stderr, "peridrive: internal error on rank %d: %s\n", rank, e.what());
    MPI_Abort(PETSC_COMM_WORLD, 4);
  }
  PetscFinalize();
  return status;
}
