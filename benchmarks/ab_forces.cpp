// Two versions of the bond loop (src/kernels/forces.cpp) in one process, called alternately on the same
// domain: A B B A A B ... Built by benchmarks/ab_forces.sh, which compiles each version into its
// own namespace (periA, periB); both must compile against the current headers. Prints figures
// (medians over the pairs, the median and quartiles of the per-pair ratio A time / B time, the
// largest relative force difference); asserts nothing.
//   ab_forces MODEL N PAIRS NOISE   (MODEL membrane | pmb: N x N nodes of a sheet; solid: N x N x N
//                                    of a PMB block, horizon 3.015 dx, as compare_lammps.py;
//                                    dx = 1 mm; displacements uniform in +-NOISE m)
//   AB_CRITICAL=S0 (critical stretch; default 0.5 PMB and solid, 5 membrane), AB_STRAIN=EPS (a
//   uniform strain along x on top: AB_CRITICAL=0.0005 AB_STRAIN=0.002 breaks half the solid's
//   bonds, as late in compare_lammps.py's run), AB_STATE=PREFIX (displacements and broken flags
//   of a one-rank run: PREFIX_u.bin, PREFIX_broken.bin), AB_QUADRATURE=full, AB_NO_PAIRS, AB_ENERGY (the calls sum the strain energy).
#include <petscsys.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "peri/kernels/forces.hpp"
#include "peri/models/model.hpp"
#include "peri/stages/simulation.hpp"

// The two versions' entry points; their argument types are layout-identical to peri's (so is the
// plan each version makes, declared here as peri's: a return type is not part of the symbol).
namespace periA {
struct BondLaw;
struct BondView;
struct RowBlocks;
struct BondTally;
void bond_forces(const BondLaw&, const BondView&, const RowBlocks&, double*, bool, BondTally&);
peri::RowBlocks plan_rows(const BondView&, const std::int32_t*, std::size_t, bool);
}  // namespace periA
namespace periB {
struct BondLaw;
struct BondView;
struct RowBlocks;
struct BondTally;
void bond_forces(const BondLaw&, const BondView&, const RowBlocks&, double*, bool, BondTally&);
peri::RowBlocks plan_rows(const BondView&, const std::int32_t*, std::size_t, bool);
}  // namespace periB

namespace {

template <class T, class U>
const T& as(const U& x) {
  return *reinterpret_cast<const T*>(&x);
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5)];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: ab_forces MODEL N PAIRS NOISE (e.g. membrane 400 200 1e-5)\n");
    return 2;
  }
  const std::string model = argv[1];
  const int n = std::atoi(argv[2]), pairs = std::atoi(argv[3]);
  const double noise = std::atof(argv[4]);
  if ((model != "membrane" && model != "pmb" && model != "solid") || n < 8 || pairs < 1 || !(noise >= 0)) {
    std::fprintf(stderr, "ab_forces: bad arguments (MODEL membrane|pmb|solid, N >= 8, PAIRS >= 1, NOISE >= 0)\n");
    return 2;
  }
  int pargc = 1;
  if (PetscInitialize(&pargc, &argv, nullptr, nullptr)) return 1;
  using namespace peri;
  char text[1024];
  const char* critical = std::getenv("AB_CRITICAL");
  if (model == "solid")
    std::snprintf(text, sizeof text,
                  "name: ab\nmaterials:\n  m: {model: pmb, density: 2200, bulk_modulus: 14.9e9, critical_stretch: %s}\n"
                  "bodies:\n  block: {kind: solid, material: m, origin: [0, 0, 0], size: [%.17g, %.17g, %.17g], "
                  "spacing: 0.001, horizon: 0.003015, quadrature: taper}\nstages:\n  - {name: run, steps: 1}\n",
                  critical ? critical : "0.5", n * 1e-3, n * 1e-3, n * 1e-3);
  else
    std::snprintf(text, sizeof text,
                  "name: ab\nmaterials:\n  m: {model: %s, density: 1200, bulk_modulus: 800.0e6, critical_stretch: %s}\n"
                  "bodies:\n  sheet: {material: m, origin: [0, 0, 0], size: [%.17g, %.17g], thickness: 0.0005, "
                  "spacing: 0.001, quadrature: %s}\nstages:\n  - {name: run, steps: 1}\n",
                  model.c_str(), critical ? critical : model == "pmb" ? "0.5" : "5.0", n * 1e-3, n * 1e-3,
                  std::getenv("AB_QUADRATURE") ? std::getenv("AB_QUADRATURE") : "partial_area");
  {
    const Scene scene = parse_scene(text, "ab_forces");
    const Nodes nodes = discretize(scene);
    const CellList cells(nodes, reach(nodes.bodies[0]));
    const Partition part = partition_from_parts(nodes, std::vector<int>(nodes.size(), 0), 1);
    Domain d = build_domain(scene, nodes, cells, part, 0);
    const BondLaw law = calibrate(scene.materials[0], nodes.bodies[0], "ab_forces");
    const std::int64_t stride = position_plane_stride(d.local());
    std::vector<double> u(3 * static_cast<std::size_t>(d.local())), x(3 * static_cast<std::size_t>(stride));
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> U(-noise, noise);
    for (double& c : u) c = U(rng);
    // AB_STRAIN: a uniform strain along x on top (with AB_CRITICAL, bonds break in the warm-up
    // calls, and the timed ones run blocks holding broken bonds).
    const double strain = std::getenv("AB_STRAIN") ? std::atof(std::getenv("AB_STRAIN")) : 0.0;
    for (std::int32_t i = 0; i < d.local(); ++i) u[3 * static_cast<std::size_t>(i)] += strain * d.X[3 * static_cast<std::size_t>(i)];
    // AB_STATE=PREFIX: displacements and broken flags of a one-rank run of the same body instead
    // (PREFIX_u.bin: 3 N doubles; PREFIX_broken.bin: a byte per ordered bond).
    if (const char* state = std::getenv("AB_STATE")) {
      auto load = [](const std::string& path, void* to, std::size_t bytes) {
        FILE* f = std::fopen(path.c_str(), "rb");
        const bool ok = f && std::fread(to, 1, bytes, f) == bytes && std::fgetc(f) == EOF;
        if (f) std::fclose(f);
        if (!ok) {
          std::fprintf(stderr, "ab_forces: %s is not %zu bytes of this body's state\n", path.c_str(), bytes);
          std::exit(2);
        }
      };
      load(std::string(state) + "_u.bin", u.data(), u.size() * sizeof(double));
      load(std::string(state) + "_broken.bin", d.bonds.broken.data(), d.bonds.broken.size());
      d.bonds.summarize_rows();
    }
    current_positions(d.X.data(), u.data(), 0, d.local(), stride, x.data());
    std::vector<std::int32_t> rows(d.owned);
    for (std::int32_t i = 0; i < d.owned; ++i) rows[i] = i;
    const BondView v{d.X.data(), u.data(), d.volume.data(), d.bonds.offsets.data(), d.bonds.neighbor.data(),
                     d.bonds.broken.data(), &d.bonds.patterns, x.data(), stride, d.bonds.row_broken.data()};
    // Each version plans the rows its own way.
    const bool pairs_on = !std::getenv("AB_NO_PAIRS");
    const bool energy = std::getenv("AB_ENERGY") != nullptr;  // the strain-energy variant of the loop
    const RowBlocks plan_a = periA::plan_rows(as<periA::BondView>(v), rows.data(), rows.size(), pairs_on);
    const RowBlocks plan_b = periB::plan_rows(as<periB::BondView>(v), rows.data(), rows.size(), pairs_on);
    std::vector<double> fa(3 * static_cast<std::size_t>(d.owned)), fb(fa.size());
    BondTally ta, tb;
    auto run_a = [&] {
      periA::bond_forces(as<periA::BondLaw>(law), as<periA::BondView>(v), as<periA::RowBlocks>(plan_a), fa.data(),
                         energy, reinterpret_cast<periA::BondTally&>(ta));
    };
    auto run_b = [&] {
      periB::bond_forces(as<periB::BondLaw>(law), as<periB::BondView>(v), as<periB::RowBlocks>(plan_b), fb.data(),
                         energy, reinterpret_cast<periB::BondTally&>(tb));
    };
    auto seconds = [](auto&& f) {
      const auto t0 = std::chrono::steady_clock::now();
      f();
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    };
    for (int w = 0; w < 3; ++w) run_a(), run_b();
    double diff = 0, diff_abs = 0, scale = 0;  // per component; and over the largest component
    for (std::size_t k = 0; k < fa.size(); ++k) {
      diff = std::max(diff, std::fabs(fa[k] - fb[k]) / std::max(std::fabs(fa[k]), 1e-300));
      diff_abs = std::max(diff_abs, std::fabs(fa[k] - fb[k]));
      scale = std::max(scale, std::fabs(fa[k]));
    }
    std::vector<double> sa, sb, ratio;
    for (int p = 0; p < pairs; ++p) {
      double a, b;
      if (p % 2) {  // alternate which goes first
        b = seconds(run_b);
        a = seconds(run_a);
      } else {
        a = seconds(run_a);
        b = seconds(run_b);
      }
      sa.push_back(a);
      sb.push_back(b);
      ratio.push_back(a / b);
    }
    const double bonds = static_cast<double>(d.bonds.size());
    std::printf("%s %d x %d%s, %.0f ordered bonds, %d pairs:\n", model.c_str(), n, n,
                model == "solid" ? (" x " + std::to_string(n)).c_str() : "", bonds, pairs);
    std::printf("  bond updates/s, median   A %.3e   B %.3e\n", bonds / quantile(sa, 0.5), bonds / quantile(sb, 0.5));
    std::printf("  bond updates/s, fastest  A %.3e   B %.3e\n", bonds / quantile(sa, 0.0), bonds / quantile(sb, 0.0));
    std::printf("  speed-up B over A per pair: median %.3f, quartiles %.3f - %.3f\n", quantile(ratio, 0.5),
                quantile(ratio, 0.25), quantile(ratio, 0.75));
    std::printf("  largest relative force difference %.2e (%.2e of the largest force component)\n", diff,
                diff_abs / std::max(scale, 1e-300));
    if (energy)
      std::printf("  strain energy A %.17g, B %.17g (relative difference %.2e)\n", ta.strain_energy, tb.strain_energy,
                  std::fabs(ta.strain_energy - tb.strain_energy) / std::max(std::fabs(ta.strain_energy), 1e-300));
  }
  PetscFinalize();
  return 0;
}
