#include "peri/io/summary.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "peri/core/build_info.hpp"
#include "peri/core/json.hpp"
#include "peri/core/resources.hpp"
#include "peri/kernels/forces.hpp"

namespace peri {

std::string RunSummary::to_json() const {
  // Rates over the steps this process timed (a resumed run: those after its checkpoint).
  const double updates = step_seconds > 0 ? double(ordered_bonds) * double(steps_timed) / step_seconds : 0;
  // The largest stage's; null where every quasi-static stage moved no support (no work to compare).
  double qs_error = quasistatic_work_error.empty() ? 0.0 : NAN;
  for (double e : quasistatic_work_error)
    if (std::isfinite(e)) qs_error = std::isfinite(qs_error) ? std::max(qs_error, e) : e;
  std::ostringstream j;
  j << "{\n"
    << "  \"peridrive_version\": " << json_string(version()) << ",\n"
    << "  \"git_revision\": " << json_string(git_revision()) << ",\n"
    << "  \"nodes\": " << nodes << ",\n"
    << "  \"bonds\": " << ordered_bonds / 2 << ",\n"
    << "  \"ordered_bonds\": " << ordered_bonds << ",\n"
    << "  \"ranks\": " << ranks << ",\n"
    << "  \"bond_kernel\": " << json_string(bond_kernel_isa()) << ",\n"
    << "  \"dt\": " << json_number(dt) << ",\n"
    << "  \"dt_stable\": " << json_number(dt_stable) << ",\n"
    << "  \"steps\": " << steps << ",\n"
    << "  \"steps_timed\": " << steps_timed << ",\n"
    << "  \"simulated_time\": " << json_number(simulated_time) << ",\n"
    << "  \"frames\": " << frames << ",\n"
    << "  \"wall_seconds\": " << json_number(wall_seconds) << ",\n"
    << "  \"setup_seconds\": " << json_number(setup_seconds) << ",\n"
    << "  \"step_seconds\": " << json_number(step_seconds) << ",\n"
    << "  \"output_seconds\": " << json_number(output_seconds) << ",\n"
    << "  \"checkpoint_seconds\": " << json_number(checkpoint_seconds) << ",\n"
    << "  \"checkpoints_written\": " << checkpoints_written << ",\n"
    << "  \"resume_seconds\": " << json_number(resume_seconds) << ",\n"
    << "  \"bond_updates_per_second\": " << json_number(updates) << ",\n"
    << "  \"bond_updates_per_second_per_rank\": " << json_number(updates / ranks) << ",\n"
    << "  \"bytes_per_bond\": " << json_number(bytes_per_bond) << ",\n"
    << "  \"bond_array_bytes_per_bond\": " << json_number(bytes_per_bond) << ",\n"
    << "  \"peak_bytes_per_bond\": " << json_number(peak_bytes_per_bond()) << ",\n"
    << "  \"partition_seconds\": " << json_number(partition_seconds) << ",\n"
    << "  \"edge_cut\": " << edge_cut << ",\n"
    << "  \"partition_method\": " << json_string(partition_method) << ",\n"
    << "  \"partition_balance\": " << json_number(partition_balance) << ",\n"
    << "  \"halo\": {\"max_ghosts\": " << halo.max_ghosts << ", \"mean_ghosts\": " << json_number(halo.mean_ghosts)
    << ", \"max_neighbour_ranks\": " << halo.max_neighbour_ranks
    << ", \"mean_neighbour_ranks\": " << json_number(halo.mean_neighbour_ranks)
    << ", \"max_owned_bonds\": " << halo.max_owned_bonds << ", \"max_boundary_bonds\": " << halo.max_boundary_bonds
    << ", \"mean_boundary_bonds\": " << json_number(halo.mean_boundary_bonds) << "},\n"
    << "  \"memory\": [";
  for (std::size_t k = 0; k < memory.size(); ++k)
    j << (k ? ", " : "") << "{\"phase\": " << json_string(memory[k].phase) << ", \"peak_bytes\": "
      << json_number(memory[k].peak) << ", \"rss_bytes\": " << json_number(memory[k].current)
      << ", \"peak_bytes_per_bond\": " << json_number(ordered_bonds > 0 ? memory[k].peak / double(ordered_bonds) : 0)
      << "}";
  j << "],\n"
    << "  \"precrack_bonds\": " << precrack_bonds << ",\n"
    << "  \"broken_bonds\": " << final_energy.broken_bonds << ",\n"
    << "  \"final\": {\"kinetic_energy\": " << json_number(final_energy.kinetic)
    << ", \"strain_energy\": " << json_number(final_energy.strain)
    << ", \"external_work\": " << json_number(final_energy.external_work)
    << ", \"dissipated_energy\": " << json_number(final_energy.dissipated)
    << ", \"total_energy\": " << json_number(final_energy.total()) << "},\n"
    << "  \"initial_total_energy\": " << json_number(initial_total_energy) << ",\n"
    << "  \"energy_balance_error\": " << json_number(energy_balance_error) << ",\n"
    << "  \"run_initial_total_energy\": " << json_number(run_initial_total_energy) << ",\n"
    << "  \"run_energy_balance_error\": " << json_number(run_energy_balance_error) << ",\n"
    << "  \"quasistatic_work_error\": " << json_number(qs_error) << ",\n";
  if (crack_tracking)
    j << "  \"crack_tips\": " << crack_tips_json << ",\n"
      << "  \"max_crack_speed\": " << json_number(max_crack_speed) << ",\n"
      << "  \"mean_crack_speed\": " << json_number(mean_crack_speed) << ",\n"
      << "  \"crack_speed_window\": " << json_number(crack_speed_window) << ",\n"
      << "  \"crack_tip_seconds\": " << json_number(crack_tip_seconds) << ",\n"
      << "  \"rayleigh_wave_speed\": " << json_number(rayleigh_wave_speed) << ",\n"
      << "  \"max_crack_speed_over_rayleigh\": " << json_number(max_crack_speed / rayleigh_wave_speed) << ",\n"
      << "  \"mean_crack_speed_over_rayleigh\": " << json_number(mean_crack_speed / rayleigh_wave_speed) << ",\n";
  j << "  \"quasistatic\": [";
  for (std::size_t k = 0; k < quasistatic.size(); ++k) {
    const QuasiStaticStats& q = quasistatic[k].second;
    j << (k ? ", " : "") << "{\"stage\": " << json_string(quasistatic[k].first) << ", \"increments\": " << q.increments.size()
      << ", \"cutbacks\": " << q.cutbacks << ", \"newton_iterations\": " << q.newton_iterations
      << ", \"linear_iterations\": " << q.linear_iterations << ", \"broken_bonds\": " << q.broken
      << ", \"seconds\": " << json_number(q.seconds) << ", \"residual_seconds\": " << json_number(q.residual_seconds)
      << ", \"tangent_seconds\": " << json_number(q.tangent_seconds) << ", \"tangent_assemblies\": " << q.tangent_assemblies
      << ", \"near_null_modes\": " << q.near_null_modes << ", \"unknowns\": " << q.unknowns
      << ", \"support_work\": " << json_number(q.external_work)
      << ", \"work_error\": " << json_number(k < quasistatic_work_error.size() ? quasistatic_work_error[k] : NAN)
      << "}";
  }
  j << "],\n"
    << "  \"derived\": {";
  for (std::size_t k = 0; k < derived.size(); ++k)
    j << (k ? ", " : "") << json_string(derived[k].first) << ": " << json_number(derived[k].second);
  j << "},\n"
    << "  \"output\": {";
  for (std::size_t k = 0; k < output.size(); ++k)
    j << (k ? ", " : "") << json_string(output[k].first) << ": " << json_number(output[k].second);
  j << "}\n}\n";
  return j.str();
}

void mark_memory(RunSummary& summary, const char* phase, MPI_Comm comm) {
  const ProcessMemory m = process_memory();
  double local[2] = {m.peak, m.current}, sum[2];
  MPI_Allreduce(local, sum, 2, MPI_DOUBLE, MPI_SUM, comm);
  summary.memory.push_back({phase, sum[0], sum[1]});
}

std::vector<std::string> derived_lines(const RunSummary& summary) {
  std::vector<std::string> lines;
  lines.push_back(std::string("derived by peridrive ") + version() + " (" + git_revision() + "):");
  for (const auto& [k, v] : summary.derived) {
    std::ostringstream s;
    s << k << " = " << std::setprecision(10) << v;
    lines.push_back(s.str());
  }
  for (const auto& [k, v] : summary.output) {  // what the run will write
    std::ostringstream s;
    s << "output." << k << " = " << std::setprecision(4) << v;
    lines.push_back(s.str());
  }
  return lines;
}

}  // namespace peri
