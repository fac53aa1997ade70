// Lane packs: the operations a bond law and the bond loop use, on one double (Scalar), four
// (Simd4: AVX2 + FMA) or eight lanes (Simd8: AVX-512 F + VL). Laws are written once against this
// interface (models/laws/) and run on any pack; the packs of one build agree bit for bit lane by
// lane (the same operations, fused where the build has FMA, and the same 1/sqrt method), so a
// bond's coefficient is the same bits whichever loop evaluates it.
//
// Why not a SIMD library: the bond loop needs mask-register forms (AVX-512's maskz fnmadd), the
// rsqrt14 estimate, and control over every rounding (no contraction, a fixed operation order), and
// xsimd 8 / Highway 1.0 (Debian 12) give either no rsqrt14 or no per-operation control; these
// three packs are the whole ISA layer (about 150 lines).
#pragma once
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <new>
#include <vector>

#if defined(__AVX2__) && defined(__FMA__)
#define PERI_AVX2 1
#include <immintrin.h>
#if defined(__AVX512F__) && defined(__AVX512VL__)
#define PERI_AVX512VL 1  // eight-lane blocks, and 1/sqrt from the rsqrt14 estimate
#endif
#endif

namespace peri::simd {

/// Allocator of cache-line aligned storage (64 bytes: an eight-lane vector never straddles two
/// lines when its offset is a multiple of eight).
template <class T>
struct CacheAligned {
  using value_type = T;
  CacheAligned() = default;
  template <class U>
  CacheAligned(const CacheAligned<U>&) noexcept {}
  T* allocate(std::size_t n) {
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t{64}));
  }
  void deallocate(T* p, std::size_t) noexcept { ::operator delete(p, std::align_val_t{64}); }
  template <class U>
  bool operator==(const CacheAligned<U>&) const noexcept { return true; }
};
template <class T>
using AlignedVector = std::vector<T, CacheAligned<T>>;

/// 1/sqrt(y2) and sqrt(y2) in two stages (the first has the long latency; the bond loop starts it
/// for the next bond before finishing this one). AVX-512: the 14-bit estimate r and one
/// correction of third order: with e = 1 - y^2 r^2 (|e| < 2^-13), 1/y = r (1 - e)^-1/2 =
/// r (1 + e (1/2 + e (3/8 + e 5/16))) + O(e^4 r) (truncation 2^-54: round-off), y = y^2 / y.
/// Otherwise a square root and a division. A law holds one Root as a member: its constants are
/// then loop invariants the compiler keeps in registers (written as P::set1 inside the loop,
/// GCC 12 reloaded two of them from memory every slot: the PMB sheet at 0.95 of its speed).
template <class P>
struct Root {
  using V = typename P::V;
#if defined(PERI_AVX512VL)
  V one = P::set1(1.0), half = P::set1(0.5), c2 = P::set1(0.375), c3 = P::set1(0.3125);
#endif
  V front(V y2) const {
#if defined(PERI_AVX512VL)
    return P::rsqrt14(y2);
#else
    return P::sqrt(y2);
#endif
  }
  void finish([[maybe_unused]] V y2, V front, V& y, V& inv_y) const {
#if defined(PERI_AVX512VL)
    const V e = P::fnmadd(y2, P::mul(front, front), one);
    const V series = P::fmadd(e, P::fmadd(e, c3, c2), half);
    inv_y = P::fmadd(P::mul(front, e), series, front);
    y = P::mul(y2, inv_y);
#else
    y = front;
    inv_y = P::div(P::set1(1.0), y);
#endif
  }
};

/// One lane: a double. fmadd is fused where the build has FMA (as the vector packs are).
struct Scalar {
  static constexpr int W = 1;
  using V = double;
  using M = bool;
  static V zero() { return 0.0; }
  static V set1(double a) { return a; }
  static V broadcast(const double* a) { return *a; }
  static V loadu(const double* a) { return *a; }
  static void storeu(double* a, V x) { *a = x; }
  static V add(V a, V b) { return a + b; }
  static V sub(V a, V b) { return a - b; }
  static V mul(V a, V b) { return a * b; }
  static V div(V a, V b) { return a / b; }
  static V min(V a, V b) { return a < b ? a : b; }  // as minpd: b where unordered
  static V max(V a, V b) { return a > b ? a : b; }
  static V sqrt(V a) { return std::sqrt(a); }
#if defined(__FMA__)
  static V fmadd(V a, V b, V c) { return std::fma(a, b, c); }
  static V fnmadd(V a, V b, V c) { return std::fma(-a, b, c); }
#else
  static V fmadd(V a, V b, V c) { return a * b + c; }
  static V fnmadd(V a, V b, V c) { return c - a * b; }
#endif
#if defined(PERI_AVX512VL)
  static V rsqrt14(V a) { return _mm_cvtsd_f64(_mm_rsqrt14_sd(_mm_setzero_pd(), _mm_set_sd(a))); }
#endif
  static M ge(V a, V b) { return a >= b; }
  static M le(V a, V b) { return a <= b; }
  static unsigned bits(M m) { return m ? 1u : 0u; }
  static M with_lanes(M m, unsigned lanes) { return m || (lanes & 1u); }
  static V zero_where(M m, V a) { return m ? 0.0 : a; }
  static V fnmadd_or_zero(M m, V a, V b, V c) { return m ? 0.0 : fnmadd(a, b, c); }
  static V gather(const double* a, const std::int64_t* at) { return a[at[0]]; }
  static V gather(const double* a, const std::int32_t* at) { return a[at[0]]; }
};

#if defined(PERI_AVX2)
// All-ones lanes where bit l of the index is set.
struct LaneMasks {
  alignas(32) std::int64_t bits[16][4];
  constexpr LaneMasks() : bits{} {
    for (int m = 0; m < 16; ++m)
      for (int l = 0; l < 4; ++l) bits[m][l] = (m >> l & 1) ? -1 : 0;
  }
};
inline constexpr LaneMasks kLaneMasks;

/// Four lanes (AVX2; lane masks as vectors).
struct Simd4 {
  static constexpr int W = 4;
  using V = __m256d;
  using M = __m256d;
  static V zero() { return _mm256_setzero_pd(); }
  static V set1(double a) { return _mm256_set1_pd(a); }
  static V broadcast(const double* a) { return _mm256_broadcast_sd(a); }
  static V loadu(const double* a) { return _mm256_loadu_pd(a); }
  static void storeu(double* a, V x) { _mm256_storeu_pd(a, x); }
  static V add(V a, V b) { return _mm256_add_pd(a, b); }
  static V sub(V a, V b) { return _mm256_sub_pd(a, b); }
  static V mul(V a, V b) { return _mm256_mul_pd(a, b); }
  static V div(V a, V b) { return _mm256_div_pd(a, b); }
  static V min(V a, V b) { return _mm256_min_pd(a, b); }
  static V max(V a, V b) { return _mm256_max_pd(a, b); }
  static V sqrt(V a) { return _mm256_sqrt_pd(a); }
  static V fmadd(V a, V b, V c) { return _mm256_fmadd_pd(a, b, c); }
  static V fnmadd(V a, V b, V c) { return _mm256_fnmadd_pd(a, b, c); }
#if defined(PERI_AVX512VL)
  static V rsqrt14(V a) { return _mm256_rsqrt14_pd(a); }
#endif
  static M ge(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_GE_OQ); }
  static M le(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_LE_OQ); }
  static unsigned bits(M m) { return static_cast<unsigned>(_mm256_movemask_pd(m)); }
  static M with_lanes(M m, unsigned lanes) {
    return _mm256_or_pd(m, _mm256_load_pd(reinterpret_cast<const double*>(kLaneMasks.bits[lanes])));
  }
  static V zero_where(M m, V a) { return _mm256_andnot_pd(m, a); }
  static V fnmadd_or_zero(M m, V a, V b, V c) { return zero_where(m, fnmadd(a, b, c)); }
  /// a[at[0]], ..., a[at[3]], element by element.
  template <class I>
  static V gather(const double* a, const I* at) { return _mm256_setr_pd(a[at[0]], a[at[1]], a[at[2]], a[at[3]]); }
  /// a[at], a[at + t], a[at + 2t], a[at + 3t].
  static V strided(const double* a, std::int64_t at, std::int64_t t) {
    return _mm256_setr_pd(a[at], a[at + t], a[at + 2 * t], a[at + 3 * t]);
  }
};
#endif

#if defined(PERI_AVX512VL)
/// Eight lanes (AVX-512; lane masks as mask registers). Every lane computes what a Simd4 lane
/// does, in the same order (on AMD Zen 4 one eight-lane operation is one instruction over two
/// cycles: twice the bonds in flight for the same scheduler entries).
struct Simd8 {
  static constexpr int W = 8;
  using V = __m512d;
  using M = __mmask8;
  static V zero() { return _mm512_setzero_pd(); }
  static V set1(double a) { return _mm512_set1_pd(a); }
  static V broadcast(const double* a) { return _mm512_set1_pd(*a); }
  static V loadu(const double* a) { return _mm512_loadu_pd(a); }
  static void storeu(double* a, V x) { _mm512_storeu_pd(a, x); }
  static V add(V a, V b) { return _mm512_add_pd(a, b); }
  static V sub(V a, V b) { return _mm512_sub_pd(a, b); }
  static V mul(V a, V b) { return _mm512_mul_pd(a, b); }
  static V div(V a, V b) { return _mm512_div_pd(a, b); }
  static V min(V a, V b) { return _mm512_min_pd(a, b); }
  static V max(V a, V b) { return _mm512_max_pd(a, b); }
  static V sqrt(V a) { return _mm512_sqrt_pd(a); }
  static V fmadd(V a, V b, V c) { return _mm512_fmadd_pd(a, b, c); }
  static V fnmadd(V a, V b, V c) { return _mm512_fnmadd_pd(a, b, c); }
  static V rsqrt14(V a) { return _mm512_rsqrt14_pd(a); }
  static M ge(V a, V b) { return _mm512_cmp_pd_mask(a, b, _CMP_GE_OQ); }
  static M le(V a, V b) { return _mm512_cmp_pd_mask(a, b, _CMP_LE_OQ); }
  static unsigned bits(M m) { return m; }
#if defined(__AVX512DQ__)
  // Mask arithmetic as mask-register instructions (knotb, korb): written as integer operations,
  // the compiler moved the mask to a general register and back on every bond.
  static M with_lanes(M m, unsigned lanes) { return lanes ? _kor_mask8(m, _cvtu32_mask8(lanes)) : m; }
  static M invert(M m) { return _knot_mask8(m); }
#else
  static M with_lanes(M m, unsigned lanes) { return static_cast<M>(m | lanes); }
  static M invert(M m) { return static_cast<M>(~m); }
#endif
  static V zero_where(M m, V a) { return _mm512_maskz_mov_pd(invert(m), a); }
  static V fnmadd_or_zero(M m, V a, V b, V c) { return _mm512_maskz_fnmadd_pd(invert(m), a, b, c); }
};
using Wide = Simd8;
#elif defined(PERI_AVX2)
using Wide = Simd4;
#endif

}  // namespace peri::simd
