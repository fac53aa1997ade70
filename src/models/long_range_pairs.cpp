// The long-range pair sums (models/long_range.hpp): the force density of each row from its pairs
// (eq. 35's second term with eq. 31's quadrature) and their shifted energy (eq. 33).
//
// Two passes per row. First the pairs' factors, several pairs at once (simd::Simd8 or Simd4
// where the build has AVX-512 or AVX2, one pair at a time otherwise): with d = x_q - x_p,
// r2 = a^2 / y^2 and r6 = r2^3,
//   s = w2'(y) / y V_q = ((6 beta - 12 alpha r6) r6 / y^2) V_q,   e = (alpha r6 - beta) r6 - w2(cutoff),
// and 0 for a pair beyond its cutoff (or of coincident nodes). Then the sums f += s d and
// E += e V_q over the row's pairs one after the other, in the list's order (ascending table
// index), so a row's sums have the same order, and bits, whatever the lanes and the ranks. A
// pair beyond the cutoff adds 0 exactly (f never is -0: it starts at +0 and a sum of finite terms
// that cancels is +0), as skipping it did.
//
// Compiled without contraction (CMakeLists.txt: peri_bond_law_sources): each fused operation is
// written out where the scalar loop, compiled with contraction for FMA machines, fused it:
// y^2 = fma(d2, d2, fma(d0, d0, d1 d1)), 6 beta - 12 alpha r6 and alpha r6 - beta and
// (..) r6 - w2(cutoff) fused, the sums fused; so the results are those bits (a build without FMA
// fuses nothing, as that loop did not).
#include <algorithm>
#include <cstdint>
#include <vector>

#include "peri/core/simd.hpp"
#include "peri/models/long_range.hpp"

namespace peri {
namespace {

using simd::Scalar;

// Per pack: a vector of W 32-bit indices, loaded from the list (whole lanes: the list has
// LongRangeList::kPad entries past its end), times 3 or times the rules' stride; gathers by it;
// lanes kept where 0 < y2 <= cut2 (the others 0).
#if defined(PERI_AVX512VL)
using Lanes = simd::Simd8;
using Index = __m256i;
Index load_index(const std::int32_t* at) { return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(at)); }
Index load_index(const std::uint16_t* at) { return _mm256_cvtepu16_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(at))); }
Index times(Index i, int k) { return _mm256_mullo_epi32(i, _mm256_set1_epi32(k)); }
Lanes::V gather(const double* a, Index i) { return _mm512_i32gather_pd(i, a, 8); }
// Eight lanes keep only the pairs within the cutoff (and the row): packed to the front, so the
// sums skip the others (which add exact zeros) as the scalar loop did.
constexpr bool kPack = true;
__mmask8 within(Lanes::V y2, Lanes::V cut2, std::int64_t left) {
  const __mmask8 row = left >= 8 ? 0xff : static_cast<__mmask8>((1u << left) - 1);
  return _mm512_cmp_pd_mask(y2, _mm512_setzero_pd(), _CMP_GT_OQ) & _mm512_cmp_pd_mask(y2, cut2, _CMP_LE_OQ) & row;
}
void store_packed(double* at, __mmask8 in, Lanes::V a) { _mm512_storeu_pd(at, _mm512_maskz_compress_pd(in, a)); }
#elif defined(PERI_AVX2)
constexpr bool kPack = false;
using Lanes = simd::Simd4;
using Index = __m128i;
Index load_index(const std::int32_t* at) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(at)); }
Index load_index(const std::uint16_t* at) { return _mm_cvtepu16_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(at))); }
Index times(Index i, int k) { return _mm_mullo_epi32(i, _mm_set1_epi32(k)); }
Lanes::V gather(const double* a, Index i) { return _mm256_i32gather_pd(a, i, 8); }
Lanes::V keep_within(Lanes::V y2, Lanes::V cut2, Lanes::V a) {
  const __m256d in = _mm256_and_pd(_mm256_cmp_pd(y2, _mm256_setzero_pd(), _CMP_GT_OQ), _mm256_cmp_pd(y2, cut2, _CMP_LE_OQ));
  return _mm256_and_pd(in, a);
}
#else
constexpr bool kPack = false;
using Lanes = Scalar;
using Index = std::int32_t;
Index load_index(const std::int32_t* at) { return *at; }
Index load_index(const std::uint16_t* at) { return *at; }
Index times(Index i, int k) { return i * k; }
double gather(const double* a, Index i) { return a[i]; }
double keep_within(double y2, double cut2, double a) { return y2 > 0 && y2 <= cut2 ? a : 0.0; }
#endif
constexpr int W = Lanes::W;

// One rule for every pair of the list (kOneRule: its coefficients broadcast, else gathered by
// each pair's rule); with the energies or not.
template <bool kOneRule, bool kEnergy>
double sum_rows(const PairLaw& law, const PairNodes& nodes, const std::int64_t* rows, std::int64_t row_count,
                double* force, const LongRangeList& list, double* energy_density) {
  using V = Lanes::V;
  const std::vector<PairLaw::Coefficients> c = law.coefficients();
  const double* coefficient = &c[0].alpha;  // 6 per rule
  constexpr int kStride = sizeof(PairLaw::Coefficients) / sizeof(double);
  static_assert(kStride == 6);
  const double* x = nodes.x;
  const double* volume = nodes.volume;
  std::int64_t longest = 0;
  for (std::int64_t m = 0; m < row_count; ++m) longest = std::max(longest, list.begin[m + 1] - list.begin[m]);
  static_assert(W <= LongRangeList::kPad);
  const std::size_t room = static_cast<std::size_t>((longest + W - 1) / W * W);
  // Per pair of the row: the factors and d (lanes past the row's end are computed and not read;
  // packed, only the pairs within the cutoff).
  std::vector<double> s(room), d0(room), d1(room), d2(room), e(kEnergy ? room : 0), vq(kEnergy ? room : 0);
  const int rule = kOneRule ? list.shared_rule : 0;
  const V a2 = Lanes::set1(law.length * law.length), one = Lanes::set1(1.0), minus_one = Lanes::set1(-1.0);
  double energy = 0;
  for (std::int64_t m = 0; m < row_count; ++m) {
    const std::int64_t p = rows[m], b = list.begin[m], n = list.begin[m + 1] - b;
    const V xp0 = Lanes::set1(x[3 * p]), xp1 = Lanes::set1(x[3 * p + 1]), xp2 = Lanes::set1(x[3 * p + 2]);
    std::int64_t used = kPack ? 0 : n;  // pairs for the sums
    for (std::int64_t k = 0; k < n; k += W) {
      const Index q = load_index(&list.partner[b + k]), q3 = times(q, 3);
      const Index r = kOneRule ? q : times(load_index(&list.rule[b + k]), kStride);
      const V e0 = Lanes::sub(gather(x, q3), xp0);
      const V e1 = Lanes::sub(gather(x + 1, q3), xp1);
      const V e2 = Lanes::sub(gather(x + 2, q3), xp2);
      const V y2 = Lanes::fmadd(e2, e2, Lanes::fmadd(e0, e0, Lanes::mul(e1, e1)));
      auto coeff = [&](int field) {
        return kOneRule ? Lanes::set1(coefficient[kStride * rule + field]) : gather(coefficient + field, r);
      };
      const V inv_y2 = Lanes::div(one, y2), r2 = Lanes::mul(a2, inv_y2), r6 = Lanes::mul(Lanes::mul(r2, r2), r2);
      const V v = gather(volume, q), cut2 = coeff(4);
      const V t = Lanes::fnmadd(coeff(2), r6, coeff(3));  // 6 beta - 12 alpha r6
      const V factor = Lanes::mul(Lanes::mul(Lanes::mul(t, r6), inv_y2), v);
      V w{};
      if constexpr (kEnergy)  // (-1 x: an exact negation, -0 for +0)
        w = Lanes::fmadd(Lanes::fmadd(coeff(0), r6, Lanes::mul(minus_one, coeff(1))), r6, Lanes::mul(minus_one, coeff(5)));
#if defined(PERI_AVX512VL)
      const __mmask8 in = within(y2, cut2, n - k);
      store_packed(&s[used], in, factor);
      store_packed(&d0[used], in, e0);
      store_packed(&d1[used], in, e1);
      store_packed(&d2[used], in, e2);
      if constexpr (kEnergy) {
        store_packed(&e[used], in, w);
        store_packed(&vq[used], in, v);
      }
      used += __builtin_popcount(in);
#else
      Lanes::storeu(&s[k], keep_within(y2, cut2, factor));
      Lanes::storeu(&d0[k], e0);
      Lanes::storeu(&d1[k], e1);
      Lanes::storeu(&d2[k], e2);
      if constexpr (kEnergy) {
        Lanes::storeu(&e[k], keep_within(y2, cut2, w));
        Lanes::storeu(&vq[k], v);
      }
#endif
    }
    double f0 = 0, f1 = 0, f2 = 0, e_p = 0;
    for (std::int64_t k = 0; k < used; ++k) {
      f0 = Scalar::fmadd(s[k], d0[k], f0);
      f1 = Scalar::fmadd(s[k], d1[k], f1);
      f2 = Scalar::fmadd(s[k], d2[k], f2);
      if constexpr (kEnergy) e_p = Scalar::fmadd(e[k], vq[k], e_p);
    }
    force[3 * m] += f0;
    force[3 * m + 1] += f1;
    force[3 * m + 2] += f2;
    if constexpr (kEnergy) {
      const double half = 0.5 * e_p;
      energy = Scalar::fmadd(half, volume[p], energy);
      if (energy_density) energy_density[m] += half;
    }
  }
  return energy;
}

}  // namespace

double long_range_pair_forces(const PairLaw& law, const PairNodes& nodes, const std::int64_t* rows,
                              std::int64_t row_count, double* force, const LongRangeList& list, bool with_energy,
                              double* energy_density) {
  if (row_count == 0) return 0.0;
  const bool one_rule = list.shared_rule >= 0;
  if (with_energy)
    return one_rule ? sum_rows<true, true>(law, nodes, rows, row_count, force, list, energy_density)
                    : sum_rows<false, true>(law, nodes, rows, row_count, force, list, energy_density);
  return one_rule ? sum_rows<true, false>(law, nodes, rows, row_count, force, list, nullptr)
                  : sum_rows<false, false>(law, nodes, rows, row_count, force, list, nullptr);
}

}  // namespace peri
