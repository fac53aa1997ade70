// Every registered bond law passes the checks of tests/law_checks.hpp (SIMD and portable loops
// the same bits, gradient and slope, the SNES tangent's rows, calibration), each from a sample
// material below. A law registered without a sample material fails EverySampleIsRegistered.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "law_checks.hpp"
#include "peri/core/simd.hpp"

namespace peri {
namespace {

using law_checks::Sample;

const std::vector<Sample>& samples() {
  static const std::vector<Sample> s{
      {"membrane", "model: membrane, density: 1200, bulk_modulus: 8.0e8, critical_stretch: 1.004", "1.002"},
      {"membrane_hardening",
       "model: membrane, density: 1200, bulk_modulus: 8.0e8, critical_stretch: 1.004, "
       "hardening: {coefficient: 3.0e16, exponent: 3}",
       "1.002"},
      {"pmb", "model: pmb, density: 2200, bulk_modulus: 1.49e10, critical_stretch: 0.005", "0.0025"},
  };
  return s;
}

const Sample& sample(const std::string& law) {
  for (const Sample& s : samples())
    if (s.law == law) return s;
  throw std::runtime_error("no sample material for law " + law);
}

std::vector<std::string> law_names() {
  std::vector<std::string> names;
  for (const LawEntry* e : registered_laws()) names.push_back(e->name);
  return names;
}

class EveryLaw : public ::testing::TestWithParam<std::string> {};

TEST(Laws, EverySampleIsRegistered) {
  for (const std::string& name : law_names()) EXPECT_NO_THROW(sample(name)) << "law " << name << " has no sample";
  for (const Sample& s : samples()) EXPECT_NE(find_law(s.law), nullptr) << s.law;
}

TEST_P(EveryLaw, SimdAndPortableLoopsGiveTheSameBits) {
  law_checks::simd_and_portable_loops_give_the_same_bits(sample(GetParam()));
}

TEST_P(EveryLaw, CoefficientIsTheEnergyGradientAndSlopeItsDerivative) {
  law_checks::coefficient_is_the_energy_gradient_and_slope_its_derivative(sample(GetParam()));
}

TEST_P(EveryLaw, TangentRowIsTheDerivativeOfTheForces) {
  law_checks::tangent_row_is_the_derivative_of_the_forces(sample(GetParam()));
}

TEST_P(EveryLaw, CalibrationStoresTheContinuumEnergy) {
  law_checks::calibration_stores_the_continuum_energy(sample(GetParam()));
}

// simd::Root, the laws' 1/|y| and |y| and free rows' 1/|xi|, against the exact values over y^2 from
// 1e-200 to 1e200: on AVX-512 (rsqrt14 and the series) 1/y within 1.1 ulp and y = y^2 (1/y) within
// 2.6 ulp; elsewhere (a square root and a division) 1/y within 1.5 ulp and y correctly rounded; and
// the vector pack's lanes the same bits as the scalar pack's.
TEST(Root, WithinAnUlpAndTheSameBitsInEveryPack) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> mantissa(1.0, 2.0);
  std::uniform_int_distribution<int> exponent(-664, 664);
  const simd::Root<simd::Scalar> scalar;
  double worst_inv = 0, worst_y = 0;
  auto ulps = [](double got, long double exact) {
    const double e = static_cast<double>(exact);
    return static_cast<double>(std::fabs(static_cast<long double>(got) - exact) /
                               static_cast<long double>(std::nextafter(e, INFINITY) - e));
  };
  constexpr int kSamples = 400000;
  std::vector<double> y2s(kSamples), inv(kSamples), len(kSamples);
  for (int n = 0; n < kSamples; ++n) {
    const double y2 = std::ldexp(mantissa(rng), exponent(rng));
    y2s[n] = y2;
    scalar.finish(y2, scalar.front(y2), len[n], inv[n]);
    const long double root = std::sqrt(static_cast<long double>(y2));
    worst_inv = std::max(worst_inv, ulps(inv[n], 1.0L / root));
    worst_y = std::max(worst_y, ulps(len[n], root));
  }
#if defined(PERI_AVX512VL)
  EXPECT_LE(worst_inv, 1.1);  // the series' truncation (below 0.55 ulp) and the last rounding: 1.05 at most
  EXPECT_LE(worst_y, 2.6);    // y^2 (1/y) rounded once more
#else
  EXPECT_LE(worst_inv, 1.5);  // 1 / (sqrt rounded), rounded: 1.47 measured
  EXPECT_LE(worst_y, 0.5);    // sqrt, correctly rounded
#endif
  std::printf("Root: 1/y within %.3f ulp, y within %.3f ulp over %d samples\n", worst_inv, worst_y, kSamples);
#if defined(PERI_AVX2)
#if defined(PERI_AVX512VL)
  using Pack = simd::Simd8;
#else
  using Pack = simd::Simd4;
#endif
  const simd::Root<Pack> vector;
  int differ = 0;
  for (int n = 0; n + Pack::W <= kSamples; n += Pack::W) {
    typename Pack::V y, inv_y;
    const typename Pack::V y2 = Pack::loadu(&y2s[n]);
    vector.finish(y2, vector.front(y2), y, inv_y);
    double ys[Pack::W], invs[Pack::W];
    Pack::storeu(ys, y);
    Pack::storeu(invs, inv_y);
    for (int l = 0; l < Pack::W; ++l) differ += (ys[l] != len[n + l]) + (invs[l] != inv[n + l]);
  }
  EXPECT_EQ(differ, 0);
#endif
}

INSTANTIATE_TEST_SUITE_P(Registered, EveryLaw, ::testing::ValuesIn(law_names()),
                         [](const auto& info) { return info.param; });

}  // namespace
}  // namespace peri
