// The start of a position-dependence fit on a record whose travel holds many periods, judged on a
// record of the independent simulator (position_profile_cases.hpp says what and why).  One case
// here, which the sanitizer pass runs too; the other five are a study, labelled long
// (test_position_profile_study.cpp: under ASan the six took 42-55 s, a quarter of that pass's
// test time, on code paths this one covers).
#include "position_profile_cases.hpp"

namespace friction {
namespace test_position_profile {
namespace {

TEST(PositionProfile, ManyPeriodsOverTheTravelStartInTheRightBasin) {
  position_profile_cases::expect_right_basin(1);
}

// The level sin(2 pi x / lambda + phi) sees the absolute position.  A record 10^4 travels from
// the origin (as a study record at -0.078 m with a travel of 1e-5 m) must be fitted as well as the
// same record at the origin: the same wavelength and amplitude, the phases related by
// 2 pi x0 / lambda, the wavelength within four standard errors of the truth.  (Fitted as it was,
// the phase at the origin and the wavelength were correlated to 1 - 1e-10: on that study record
// the wavelength stopped 3 % off, at 4x the noise floor, with a phase standard error of 846 rad.)
TEST(PositionProfile, AFarPositionOriginChangesOnlyThePhase) {
  const auto [seed, periods] = position_profile_cases::case_seed(2);
  const position_profile_cases::Case c = position_profile_cases::make_case(seed, periods);
  const auto [near, far, x0] = position_profile_cases::near_and_far(c);
  MethodOptions o;
  o.extensions = {Effect::position_dependence};
  const auto fit = [&](const Record& r) {
    const IdentifiedModel id = identify_model("maxwell-slip", r, o);
    return id.extensions["pieces"]["position-dependence"];
  };
  const Json a = fit(near), b = fit(far);
  const double lambda = a["wavelength"]["value"].get<double>();
  const double se = a["wavelength"]["standard_error"].get<double>();
  ASSERT_GT(se, 0.0);
  EXPECT_LE(std::abs(lambda - c.wavelength), 4.0 * se) << lambda << " m for " << c.wavelength;
  EXPECT_NEAR(b["wavelength"]["value"].get<double>(), lambda, 1e-3 * se);
  EXPECT_NEAR(b["amplitude"]["value"].get<double>(), a["amplitude"]["value"].get<double>(),
              1e-3 * a["amplitude"]["standard_error"].get<double>());
  double dphi = b["phase"]["value"].get<double>() - a["phase"]["value"].get<double>() +
                2.0 * M_PI * x0 / b["wavelength"]["value"].get<double>();
  dphi -= 2.0 * M_PI * std::round(dphi / (2.0 * M_PI));
  EXPECT_NEAR(dphi, 0.0, 1e-3) << "phase at the origin " << b["phase"]["value"].get<double>();
}

}  // namespace
}  // namespace test_position_profile
}  // namespace friction
