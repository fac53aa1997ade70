// make_law_entry<L>: a registry entry (models/law.hpp) for bond law L, its functions instantiated
// from L's one definition: one bond on the Scalar pack (coefficient, slope, energy, failure), the
// portable walk and, for laws with a vector form, the SIMD accelerator (forces), the energy pass
// and the SNES tangent's block rows.
//
// What a law L provides (models/laws/pmb.hpp is the model to copy):
//   template <class P, class Shape, bool Energy> struct Lanes   the law on pack P's lanes
//   template <class F> decltype(auto) visit_shape(F&& f) const  f(Shape{}) with its compile-time shape
//   double critical_energy(double xi2) const                    w at failure, per unit measure
//   double reference_stiffness(double xi2) const                df/dy at y = |xi| (stable step)
//   void make_intact()                                          switch failure off
//   static constexpr bool kVectorized                           Lanes works on vector packs
//   static constexpr int kHistory (optional)                    values kept per ordered bond; its
//                                                               Lanes' Bonds are HistoryBondLanes and
//                                                               it runs in the portable walk
//   Lanes::kReadsInverseLength (optional, default true)         whether its lanes read 1/|xi| (free
//                                                               rows: bond_loop.hpp free_slot)
#pragma once
#include <string>
#include <type_traits>

#include "peri/kernels/bond_loop.hpp"
#include "peri/kernels/fast_loop.hpp"
#include "peri/models/law.hpp"
#include "peri/models/laws/bond_lanes.hpp"

namespace peri {
namespace law_entry {

// One bond of law L (shape Shape) on the Scalar pack, per unit measure: the bond lanes and front.
template <class E>
struct OneBond {
  typename E::Bonds b;
  typename E::Front p;
  OneBond(const E& law, double xi2, double y2) {
    b.d0 = std::sqrt(y2);
    b.d1 = b.d2 = 0.0;
    b.xi2 = xi2;
    b.inv_xi = 1.0 / std::sqrt(xi2);
    b.measure = 1.0;
    b.measure_per_xi2 = 1.0 / xi2;
    fill_slots<simd::Scalar>(law, b);
    b.dead = 0;
    p = law.front(b, y2);
  }
};

template <class L, class F>
decltype(auto) with_lanes(const void* constants, bool energy, F&& f) {
  const L& law = *static_cast<const L*>(constants);
  return law.visit_shape([&](auto shape) -> decltype(auto) {
    using Shape = decltype(shape);
    if (energy) return f(law, typename L::template Lanes<simd::Scalar, Shape, true>(law), shape, std::true_type{});
    return f(law, typename L::template Lanes<simd::Scalar, Shape, false>(law), shape, std::false_type{});
  });
}

// The rows of a plan in plan order (runs, the rest, the free rows), as the portable walk takes them.
template <class F>
void each_row(const RowBlocks& rows, F&& f) {
  for (const RowRun& run : rows.runs)
    for (std::int32_t l = 0; l < run.count; ++l) f(run.first + l * run.stride);
  for (std::int32_t i : rows.rest) f(i);
  for (std::int32_t i : rows.free) f(i);
}

}  // namespace law_entry

template <class L>
LawEntry make_law_entry(std::string name, std::string description) {
  static_assert(std::is_trivially_copyable_v<L>, "a law's constants are copied by value");
  static_assert(!(L::kVectorized && law_history<L>() > 0), "a law with per-bond history runs in the portable walk");
  using namespace law_entry;
  LawEntry e;
  e.name = std::move(name);
  e.description = std::move(description);
  e.history = law_history<L>();
#if defined(PERI_AVX2)
  e.vectorized = L::kVectorized;
#endif
  e.coefficient = [](const void* c, double xi2, double y2) {
    return with_lanes<L>(c, false, [&](const L&, const auto& law, auto, auto) {
      const OneBond one(law, xi2, y2);
      double w = 0;
      unsigned fresh = 0;
      return law.row_factor() * law.coefficient(one.b, one.p, w, fresh);
    });
  };
  e.slope = [](const void* c, double xi2, double y2) {
    return with_lanes<L>(c, false, [&](const L&, const auto& law, auto, auto) {
      const OneBond one(law, xi2, y2);
      return law.row_factor() * law.slope(one.b, one.p);
    });
  };
  e.energy = [](const void* c, double xi2, double y2) {
    L intact = *static_cast<const L*>(c);
    intact.make_intact();
    return with_lanes<L>(&intact, true, [&](const L&, const auto& law, auto, auto) {
      const OneBond one(law, xi2, y2);
      double w = 0;
      unsigned fresh = 0;
      law.coefficient(one.b, one.p, w, fresh);
      return w;
    });
  };
  e.broken_at = [](const void* c, double xi2, double y2) {
    return with_lanes<L>(c, false, [&](const L&, const auto& law, auto, auto) {
      const OneBond one(law, xi2, y2);
      double w = 0;
      unsigned fresh = 0;
      law.coefficient(one.b, one.p, w, fresh);
      return fresh != 0;
    });
  };
  e.critical_energy = [](const void* c, double xi2) { return static_cast<const L*>(c)->critical_energy(xi2); };
  e.reference_stiffness = [](const void* c, double xi2) { return static_cast<const L*>(c)->reference_stiffness(xi2); };
  e.make_intact = [](void* c) { static_cast<L*>(c)->make_intact(); };
  e.forces = [](const void* c, const BondView& v, const RowBlocks& rows, double* force, bool energy, BondTally& t) {
    with_lanes<L>(c, energy, [&](const L& constants, const auto& law, auto shape, auto with_energy) {
#if defined(PERI_AVX2)
      if constexpr (L::kVectorized)
        if (v.patterns) return fast::forces<L, decltype(shape), decltype(with_energy)::value>(constants, v, rows, force, t);
#endif
      (void)shape;
      (void)with_energy;
      each_row(rows, [&](std::int32_t i) { law_loop::forces(law, constants, v, &i, 1, force, t); });
    });
  };
  e.portable_forces = [](const void* c, const BondView& v, const RowBlocks& rows, double* force, bool energy,
                          BondTally& t) {
    with_lanes<L>(c, energy, [&](const L& constants, const auto& law, auto, auto) {
      each_row(rows, [&](std::int32_t i) { law_loop::forces(law, constants, v, &i, 1, force, t); });
    });
  };
  e.energy_sum = [](const void* c, const BondView& v, const std::int32_t* rows, std::size_t n, double* density) {
    L intact = *static_cast<const L*>(c);
    intact.make_intact();
    return with_lanes<L>(&intact, true, [&](const L&, const auto& law, auto, auto) {
      return law_loop::energy(law, v, rows, n, density);
    });
  };
  e.row_tangent = [](const void* c, const BondView& v, std::int32_t row, std::vector<std::int32_t>& cols,
                     std::vector<double>& blocks) {
    with_lanes<L>(c, false, [&](const L&, const auto& law, auto, auto) { law_loop::row_tangent(law, v, row, cols, blocks); });
  };
  return e;
}

}  // namespace peri
