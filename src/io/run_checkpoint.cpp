#include "peri/io/run_checkpoint.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "peri/core/build_info.hpp"
#include "peri/core/collective.hpp"
#include "peri/core/error.hpp"
#include "peri/core/petsc.hpp"
#include "peri/io/restart.hpp"

namespace peri {

void CheckpointExtras::add(std::string name, std::function<std::vector<double>()> save,
                           std::function<void(const std::vector<double>*)> restore) {
  extras_.push_back({std::move(name), std::move(save), std::move(restore)});
}

void CheckpointExtras::save(Checkpoint& c, bool root) const {
  for (const Extra& e : extras_) {
    std::vector<double> values = e.save();
    if (root) c.extras[e.name] = std::move(values);
  }
}

void CheckpointExtras::restore(const Checkpoint& c) const {
  for (const Extra& e : extras_) {
    const auto it = c.extras.find(e.name);
    e.restore(it == c.extras.end() ? nullptr : &it->second);
  }
}

Checkpoint make_checkpoint(const Scene& scene, const Domain& domain, State& state, const EnergyLedger& ledger,
                           const RunPosition& at, const RunSummary& summary, const CheckpointExtras& extras,
                           MPI_Comm comm, const std::vector<double>* dashpot_velocity) {
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  Checkpoint c;
  c.peridrive_version = version();
  c.git_revision = git_revision();
  c.scene = emit_scene(scene);
  c.scene_hash = fnv1a64(c.scene.data(), c.scene.size());
  c.reference_hash = reference_geometry_hash(domain, comm);
  c.has_reference_hash = true;
  c.nodes = domain.global_nodes;
  c.ordered_bonds = summary.ordered_bonds;
  c.step = at.step;
  c.time = at.time;
  c.stage = static_cast<std::int64_t>(at.stage);
  c.stage_step = at.stage_step;
  c.initial_total_energy = summary.initial_total_energy;
  c.ranks = ranks;
  const bool root = rank == 0;
  c.dissipated.resize(root ? ranks : 0);
  c.damping_work.resize(root ? ranks : 0);
  c.external_work.resize(root ? ranks : 0);
  c.newly_broken.resize(root ? ranks : 0);
  c.owner_hash.resize(root ? ranks : 0);
  const std::uint64_t own = ownership_hash(domain);
  MPI_Gather(&ledger.bonds.dissipated, 1, MPI_DOUBLE, c.dissipated.data(), 1, MPI_DOUBLE, 0, comm);
  MPI_Gather(&ledger.damping_work, 1, MPI_DOUBLE, c.damping_work.data(), 1, MPI_DOUBLE, 0, comm);
  MPI_Gather(&ledger.external_work, 1, MPI_DOUBLE, c.external_work.data(), 1, MPI_DOUBLE, 0, comm);
  MPI_Gather(&ledger.bonds.newly_broken, 1, MPI_INT64_T, c.newly_broken.data(), 1, MPI_INT64_T, 0, comm);
  MPI_Gather(&own, 1, MPI_UINT64_T, c.owner_hash.data(), 1, MPI_UINT64_T, 0, comm);
  // This rank's rows of the natural-order arrays: its block of natural ids (State's natural
  // layout), the broken pairs and history rows whose first node lies in that block.
  c.node_first = state.natural_begin();
  const std::size_t n3 = 3 * static_cast<std::size_t>(state.natural_count());
  {
    const VecArrayRead u(state.displacement());
    const double* slice = state.to_natural(u.data(), 3);
    c.displacement.assign(slice, slice + n3);
  }
  {
    const VecArrayRead v(state.velocity());
    const double* slice = state.to_natural(v.data(), 3);
    c.velocity.assign(slice, slice + n3);
  }
  if (dashpot_velocity) {  // (a collective scatter: every rank or none)
    if (dashpot_velocity->size() != 3 * static_cast<std::size_t>(domain.owned))
      throw Error("checkpoint: the dashpots' velocity does not hold the owned nodes");
    const double* slice = state.to_natural(dashpot_velocity->data(), 3);
    c.dashpot_velocity.assign(slice, slice + n3);
    c.has_dashpot_velocity = true;
  }
  const std::vector<std::int64_t> blocks = natural_blocks(state.natural_begin(), domain.global_nodes, comm);
  c.broken = broken_pairs_of_block(domain, blocks, comm);
  if (domain.bonds.history_stride > 0)  // laws with per-bond history
    c.extras[kBondHistoryExtra] = history_rows_of_block(domain, blocks, comm);
  extras.save(c, root);
  // Summary figures of stages before the checkpoint, so that summary.json of a resumed run is
  // complete: pre-cracked and released bonds, and each quasi-static stage's figures.
  c.extras["summary.precrack_bonds"] = {double(summary.precrack_bonds)};
  c.extras["summary.run_initial_total_energy"] = {summary.run_initial_total_energy};
  for (std::size_t k = 0; k < summary.quasistatic.size(); ++k) {
    const auto& [name, q] = summary.quasistatic[k];
    double stage = -1;
    for (std::size_t s = 0; s < scene.stages.size(); ++s)
      if (scene.stages[s].name == name) stage = double(s);
    std::vector<double> v = {stage, double(q.cutbacks), double(q.newton_iterations), double(q.linear_iterations),
                             double(q.broken), q.external_work, q.seconds, summary.quasistatic_work_error[k]};
    for (const LoadIncrement& inc : q.increments)
      v.insert(v.end(), {inc.load_factor, double(inc.newton_iterations), double(inc.linear_iterations),
                         double(inc.break_passes), double(inc.broken), inc.residual});
    c.extras["summary.quasistatic." + std::to_string(k)] = std::move(v);
  }
  return c;
}

void check_restart(const Checkpoint& c, const Scene& scene, std::int64_t nodes, std::int64_t ordered_bonds,
                   const std::vector<std::int64_t>& stage_steps, std::uint64_t reference_hash) {
  const std::string what = "checkpoint (step " + std::to_string(c.step) + ")";
  // The physics must be the checkpoint's: only progress and checkpoint cadence may differ.
  Scene stored = parse_scene(c.scene, "checkpoint scene");
  Scene mine = scene;
  mine.output.progress_seconds = stored.output.progress_seconds;
  mine.output.checkpoint_every_steps = stored.output.checkpoint_every_steps;
  mine.output.checkpoint_every_seconds = stored.output.checkpoint_every_seconds;
  const std::string a = emit_scene(stored), b = emit_scene(mine);
  if (a != b) {
    std::istringstream sa(a), sb(b);
    std::string la, lb;
    int line = 0;
    while (true) {
      ++line;
      const bool ga = static_cast<bool>(std::getline(sa, la)), gb = static_cast<bool>(std::getline(sb, lb));
      if (!ga || !gb || la != lb) break;
    }
    throw InputError(what + " was written by a different scene: resolved scene line " + std::to_string(line) +
                     " is '" + la + "' in the checkpoint and '" + lb +
                     "' here (only output.progress_seconds and output.checkpoint_every_* may change on resume)");
  }
  if (c.nodes != nodes || c.ordered_bonds != ordered_bonds)
    throw InputError(what + " holds " + std::to_string(c.nodes) + " nodes and " + std::to_string(c.ordered_bonds) +
                     " ordered bonds; this scene has " + std::to_string(nodes) + " and " +
                     std::to_string(ordered_bonds));
  if (c.has_reference_hash && c.reference_hash != reference_hash)
    throw InputError(what + " was written with a different reference geometry: the nodes' reference positions or "
                     "measures differ from this run's (a body's mesh, points or polyline file changed since), "
                     "though the scene and the node and bond counts are the same");
  std::int64_t before = 0;
  const bool stage_ok = c.stage >= 0 && static_cast<std::size_t>(c.stage) < stage_steps.size() &&
                        c.stage_step <= stage_steps[c.stage];
  if (stage_ok)
    for (std::int64_t s = 0; s < c.stage; ++s) before += stage_steps[s];
  if (!stage_ok || before + c.stage_step != c.step || scene.stages[c.stage].kind != StageKind::Dynamic)
    throw InputError(what + ": stage " + std::to_string(c.stage) + " step " + std::to_string(c.stage_step) +
                     " does not fit this scene's stages");
}

void restore_state(const Checkpoint& c, Domain& domain, State& state, EnergyLedger& ledger, MPI_Comm comm,
                   std::vector<double>* dashpot_velocity) {
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  // Each rank reads its block of natural rows, then sends every owner the rows of its nodes.
  std::string error;
  std::vector<double> u_block, v_block, w_block;
  const bool dashpots = dashpot_velocity && c.has_dashpot_velocity;
  if (dashpot_velocity) dashpot_velocity->clear();
  try {
    if (c.path.empty()) throw InputError("checkpoint: no file to restore from");
    read_checkpoint_nodes(c, state.natural_begin(), state.natural_count(), u_block, v_block,
                          dashpots ? &w_block : nullptr);
  } catch (const std::exception& e) {
    error = e.what();
  }
  error = agree_on_message(error, comm);
  if (!error.empty()) throw InputError(error);
  const std::vector<std::int64_t> blocks = natural_blocks(state.natural_begin(), domain.global_nodes, comm);
  {
    // Requests: this rank's owned natural ids, grouped by the rank whose block holds them.
    std::vector<int> dest(domain.owned), send(ranks, 0), recv(ranks, 0);
    for (std::int32_t l = 0; l < domain.owned; ++l) ++send[dest[l] = natural_block_of(blocks, domain.natural[l])];
    MPI_Alltoall(send.data(), 1, MPI_INT, recv.data(), 1, MPI_INT, comm);
    std::vector<int> sd(ranks, 0), rd(ranks, 0);
    for (int r = 1; r < ranks; ++r) {
      sd[r] = sd[r - 1] + send[r - 1];
      rd[r] = rd[r - 1] + recv[r - 1];
    }
    const int asked = ranks > 0 ? rd[ranks - 1] + recv[ranks - 1] : 0;
    std::vector<std::int64_t> ids(domain.owned), wanted(asked);
    std::vector<std::int32_t> slot(domain.owned);
    {
      std::vector<int> at(sd);
      for (std::int32_t l = 0; l < domain.owned; ++l) {
        slot[at[dest[l]]] = l;
        ids[at[dest[l]]++] = domain.natural[l];
      }
    }
    MPI_Alltoallv(ids.data(), send.data(), sd.data(), MPI_INT64_T, wanted.data(), recv.data(), rd.data(), MPI_INT64_T,
                  comm);
    // Replies: 3 values per requested node, in the order asked; displacement, velocity, then the
    // dashpots' velocity, each block freed once its replies are packed.
    for (int r = 0; r < ranks; ++r) {
      send[r] *= 3;
      sd[r] *= 3;
      recv[r] *= 3;
      rd[r] *= 3;
    }
    for (int which = 0; which < (dashpots ? 3 : 2); ++which) {
      std::vector<double>& block = which == 0 ? u_block : which == 1 ? v_block : w_block;
      std::vector<double> reply(3 * static_cast<std::size_t>(asked));
      for (int k = 0; k < asked; ++k) {
        const std::size_t row = 3 * static_cast<std::size_t>(wanted[k] - state.natural_begin());
        std::copy(block.begin() + row, block.begin() + row + 3, reply.begin() + 3 * k);
      }
      block = std::vector<double>();
      std::vector<double> got(3 * static_cast<std::size_t>(domain.owned));
      MPI_Alltoallv(reply.data(), recv.data(), rd.data(), MPI_DOUBLE, got.data(), send.data(), sd.data(), MPI_DOUBLE,
                    comm);
      reply = std::vector<double>();
      const auto place = [&](double* x) {
        for (std::int32_t k = 0; k < domain.owned; ++k) {
          const std::size_t l = static_cast<std::size_t>(slot[k]);
          for (int a = 0; a < 3; ++a) x[3 * l + a] = got[3 * static_cast<std::size_t>(k) + a];
        }
      };
      if (which == 2) {
        dashpot_velocity->assign(got.size(), 0.0);
        place(dashpot_velocity->data());
      } else {
        const VecArray x(which == 0 ? state.displacement() : state.velocity());
        place(x.data());
      }
    }
  }
  // Broken pairs and history rows: every rank streams the stored lists and keeps those of its
  // owned nodes (memory: one chunk and what it keeps).
  std::vector<std::int64_t> owned(domain.natural.begin(), domain.natural.begin() + domain.owned);
  std::sort(owned.begin(), owned.end());
  const auto mine = [&](std::int64_t id) { return std::binary_search(owned.begin(), owned.end(), id); };
  std::vector<std::int64_t> pairs;
  std::vector<double> rows;
  const std::size_t width = 2 + static_cast<std::size_t>(std::max(domain.bonds.history_stride, 0));
  try {
    pairs = read_checkpoint_broken(c, [&](std::int64_t i, std::int64_t j) { return mine(i) || mine(j); });
    if (domain.bonds.history_stride > 0) rows = read_checkpoint_history(c, width, mine);
  } catch (const std::exception& e) {
    error = e.what();
  }
  error = agree_on_message(error, comm);
  if (!error.empty()) throw InputError(error);
  long long found = apply_broken_pairs(domain, pairs), found_all = 0;
  MPI_Allreduce(&found, &found_all, 1, MPI_LONG_LONG, MPI_SUM, comm);
  if (found_all != 2 * static_cast<long long>(c.broken_pairs))  // 2 ordered bonds per pair
    throw InputError("checkpoint (step " + std::to_string(c.step) + ") lists " + std::to_string(c.broken_pairs) +
                     " broken bonds, but only " + std::to_string(found_all / 2) + " are bonds of this scene");
  if (domain.bonds.history_stride > 0) {  // the laws' per-bond history (none kept: all zero)
    long long used = apply_history(domain, rows), used_all = 0;
    MPI_Allreduce(&used, &used_all, 1, MPI_LONG_LONG, MPI_SUM, comm);
    if (used_all * static_cast<long long>(width) != static_cast<long long>(c.history_values))
      throw InputError("checkpoint (step " + std::to_string(c.step) + ") holds the history of bonds that are not "
                       "bonds of this scene");
  }

  // Tallies: per rank when the ownership is the checkpoint's (sums continue bit for bit), else
  // their totals on rank 0.
  int same = c.ranks == ranks && c.owner_hash[rank] == ownership_hash(domain), all_same = 0;
  MPI_Allreduce(&same, &all_same, 1, MPI_INT, MPI_MIN, comm);
  if (all_same) {
    ledger.bonds.dissipated = c.dissipated[rank];
    ledger.damping_work = c.damping_work[rank];
    ledger.external_work = c.external_work[rank];
    ledger.bonds.newly_broken = c.newly_broken[rank];
  } else {
    ledger.bonds = BondTally{};
    ledger.damping_work = 0;
    ledger.external_work = 0;
    if (rank == 0)
      for (int r = 0; r < c.ranks; ++r) {
        ledger.bonds.dissipated += c.dissipated[r];
        ledger.damping_work += c.damping_work[r];
        ledger.external_work += c.external_work[r];
        ledger.bonds.newly_broken += c.newly_broken[r];
      }
  }
}

void restore_summary(const Checkpoint& c, const Scene& scene, RunSummary& summary) {
  // Written by make_checkpoint; absent extras leave the figures as the setup set them.
  if (const auto it = c.extras.find("summary.precrack_bonds"); it != c.extras.end() && it->second.size() == 1)
    summary.precrack_bonds = std::llround(it->second[0]);
  // (Checkpoints without it: the explicit part's start, as before quasi-static stages were counted.)
  summary.run_initial_total_energy = c.initial_total_energy;
  if (const auto it = c.extras.find("summary.run_initial_total_energy"); it != c.extras.end() && it->second.size() == 1)
    summary.run_initial_total_energy = it->second[0];
  for (std::size_t k = 0;; ++k) {
    const auto it = c.extras.find("summary.quasistatic." + std::to_string(k));
    if (it == c.extras.end()) break;
    const std::vector<double>& v = it->second;
    if (v.size() < 8 || (v.size() - 8) % 6 != 0 || !(v[0] >= 0 && v[0] < double(scene.stages.size()))) break;
    QuasiStaticStats q;
    q.cutbacks = static_cast<int>(v[1]);
    q.newton_iterations = static_cast<long>(v[2]);
    q.linear_iterations = static_cast<long>(v[3]);
    q.broken = static_cast<std::int64_t>(v[4]);
    q.external_work = v[5];
    q.seconds = v[6];
    for (std::size_t p = 8; p < v.size(); p += 6) {
      LoadIncrement inc;
      inc.load_factor = v[p];
      inc.newton_iterations = static_cast<int>(v[p + 1]);
      inc.linear_iterations = static_cast<int>(v[p + 2]);
      inc.break_passes = static_cast<int>(v[p + 3]);
      inc.broken = static_cast<std::int64_t>(v[p + 4]);
      inc.residual = v[p + 5];
      q.increments.push_back(inc);
    }
    summary.quasistatic.push_back({scene.stages[static_cast<std::size_t>(v[0])].name, q});
    summary.quasistatic_work_error.push_back(v[7]);
  }
}

CheckpointCadence::CheckpointCadence(const Output& output, bool enabled, MPI_Comm comm)
    : output_(output), enabled_(enabled), comm_(comm) {
  MPI_Comm_rank(comm, &rank_);
}

void CheckpointCadence::start(std::int64_t step) {
  last_ = std::chrono::steady_clock::now();
  last_step_ = step;
}

bool CheckpointCadence::due(std::int64_t step, bool poll) {
  bool due = output_.checkpoint_every_steps > 0 && step % output_.checkpoint_every_steps == 0;
  if (poll) {
    // One collective verdict: a signal on any rank stops all; rank 0's clock decides the cadence.
    const double since = std::chrono::duration<double>(std::chrono::steady_clock::now() - last_).count();
    int local[2] = {stop_signal() != 0,
                    rank_ == 0 && output_.checkpoint_every_seconds > 0 && since >= output_.checkpoint_every_seconds};
    int global[2];
    MPI_Allreduce(local, global, 2, MPI_INT, MPI_MAX, comm_);
    stopped_ = global[0] != 0;
    due = due || global[0] || global[1];
  }
  return due && enabled_ && step != last_step_;
}

void CheckpointCadence::written(std::int64_t step) {
  last_step_ = step;
  last_ = std::chrono::steady_clock::now();
}

}  // namespace peri
