// The bond loop's entry points: each dispatches to the law's registry entry (models/law.hpp),
// whose functions make_law_entry instantiated from the law's one definition; and the passes that
// need no law (damage) or only a law's scalar functions (the stable step), on the one walk.
#include "peri/kernels/forces.hpp"

#include <cmath>
#include <limits>
#include <vector>

#include "peri/kernels/bond_loop.hpp"

namespace peri {

const char* bond_kernel_isa() {
#if defined(PERI_AVX512VL)
  return "avx512";
#elif defined(PERI_AVX2)
  return "avx2";
#else
  return "portable";
#endif
}

std::int64_t position_plane_stride(std::int64_t n) {
  constexpr std::int64_t kPeriod = 512, kOffset = 168;  // 4 KiB, and about a third of it
  return n + ((kOffset - n % kPeriod) + kPeriod) % kPeriod;
}

void current_positions(const double* X, const double* u, std::int32_t begin, std::int32_t end,
                       std::int64_t stride, double* x) {
  // One pass over X and u (a pass per plane re-read both from memory three times).
  double* __restrict px = x;
  double* __restrict py = x + stride;
  double* __restrict pz = x + 2 * stride;
  for (std::int64_t i = begin; i < end; ++i) {
    px[i] = X[3 * i] + u[3 * i];
    py[i] = X[3 * i + 1] + u[3 * i + 1];
    pz[i] = X[3 * i + 2] + u[3 * i + 2];
  }
}

void bond_forces(const BondLaw& law, const BondView& view, const RowBlocks& rows, double* force,
                 bool with_energy, BondTally& tally) {
  law.entry().forces(law.constants(), view, rows, force, with_energy, tally);
}

void bond_forces(const BondLaw& law, const BondView& view, const std::int32_t* rows, std::size_t nrows,
                 double* force, bool with_energy, BondTally& tally) {
  bond_forces(law, view, plan_rows(view, rows, nrows), force, with_energy, tally);
}

double bond_energy(const BondLaw& law, const BondView& v, const std::int32_t* rows, std::size_t nrows,
                   double* density) {
  return law.entry().energy_sum(law.constants(), v, rows, nrows, density);
}

void node_damage(const BondView& v, const std::int32_t* rows, std::size_t nrows, double* damage) {
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    // A row without a broken bond has no damage: its byte of row_broken, else its flags, say so
    // without the measures (a frame or a crack-tip sample of a sheet with one crack reads a few
    // rows' measures, not every row's).
    bool lost_any = !v.row_broken || v.row_broken[i];
    if (lost_any) {
      std::uint8_t flags = 0;
      for (std::int64_t b = v.offsets[i]; b < v.offsets[i + 1]; ++b) flags |= v.broken[b] & kBrokenFlag;
      lost_any = flags != 0;
    }
    if (!lost_any) {
      damage[i] = 0.0;  // (lost / all = 0 / all)
      continue;
    }
    double all = 0, lost = 0;
    for (const FamilyBond& bond : family(v, i)) {
      const double m = bond.measure();
      all += m;
      lost += bond.broken() ? m : 0.0;
    }
    damage[i] = all > 0 ? lost / all : 0.0;
  }
}

double stable_time_step(const BondLaw& law, double density, const BondView& v, const std::int32_t* rows,
                        std::size_t nrows) {
  double dt = std::numeric_limits<double>::infinity();
  // A row's stiffness sum depends on its family pattern alone: each pattern's is summed once.
  std::vector<char> pattern_done(v.patterns ? static_cast<std::size_t>(v.patterns->patterns()) : 0, 0);
  for (std::size_t r = 0; r < nrows; ++r) {
    const std::int32_t i = rows[r];
    if (v.patterned(i)) {
      char& done = pattern_done[v.patterns->of_row[i]];
      if (done) continue;
      done = 1;
    }
    double sum = 0;
    for (const FamilyBond& bond : family(v, i)) sum += law.reference_stiffness(bond.xi2()) * bond.measure();
    if (sum > 0) dt = std::min(dt, std::sqrt(2.0 * density / sum));
  }
  return dt;
}

}  // namespace peri
