// Every registered bond law passes the checks of tests/law_checks.hpp (SIMD and portable loops
// the same bits, gradient and slope, the SNES tangent's rows, calibration), each from a sample
// material below. A law registered without a sample material fails EverySampleIsRegistered.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "law_checks.hpp"

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

INSTANTIATE_TEST_SUITE_P(Registered, EveryLaw, ::testing::ValuesIn(law_names()),
                         [](const auto& info) { return info.param; });

}  // namespace
}  // namespace peri
