// The other five cases of test_position_profile (position_profile_cases.hpp): 11.5-15.5 periods
// over the travel.  A study of the same code paths, labelled long: the Release pass runs it, the
// sanitizer pass does not.
#include <set>
#include <string>

#include "friction/diagnose.hpp"
#include "position_profile_cases.hpp"

namespace friction {
namespace test_position_profile_study {
namespace {

TEST(PositionProfileStudy, ManyPeriodsOverTheTravelStartInTheRightBasin) {
  for (std::uint64_t k = 2; k <= 6; ++k) position_profile_cases::expect_right_basin(k);
}

// `diagnose` fits its position-dependence candidate about the record's first position and
// reports the phase about the origin (position_origin.hpp): a record 10^4 travels from the origin
// is diagnosed as the same record at the origin -- the same findings, wavelength and amplitude to
// a small fraction of their standard errors, the phases related by 2 pi x0 / lambda -- and the
// final model as reported, run on the far record as given, validates within 2 % of the near
// record's on the near record.  Fitted about the origin (the shift disabled), the far record's
// wavelength ended 4000 standard errors from the near one's and the phases 0.013 rad apart.
// Three and a half periods over the travel: the diagnosis starts its candidates from the coarse
// profile (extension_profile.cpp), which stays in phase over a few periods only.
TEST(PositionProfileStudy, DiagnoseFitsAFarRecordAsANearOne) {
  const position_profile_cases::Case c =
      position_profile_cases::make_case(position_profile_cases::case_seed(3).first, 3.5);
  const auto [near, far, x0] = position_profile_cases::near_and_far(c);
  const Diagnosis a = diagnose(near, near), b = diagnose(far, far);
  const auto names = [](const Diagnosis& d) {
    std::set<std::string> s;
    for (const auto& f : d.findings) s.insert(f.name());
    return s;
  };
  ASSERT_EQ(names(a), names(b)) << a.to_table() << "\n" << b.to_table();
  ASSERT_TRUE(names(a).count("position-dependence")) << a.to_table();
  const auto piece = [](const Diagnosis& d, const std::string& name) {
    for (const auto& p : d.final_pieces)
      if (p.effect == Effect::position_dependence && p.name == name) return p;
    ADD_FAILURE() << "no " << name << " among the final pieces";
    return ExtensionEstimate{};
  };
  const ExtensionEstimate lambda = piece(a, "wavelength"), amplitude = piece(a, "amplitude");
  ASSERT_GT(lambda.standard_error, 0.0);
  EXPECT_LE(std::abs(lambda.value - c.wavelength), 4.0 * lambda.standard_error)
      << lambda.value << " m for " << c.wavelength;
  EXPECT_NEAR(piece(b, "wavelength").value, lambda.value, 0.05 * lambda.standard_error);
  EXPECT_NEAR(piece(b, "amplitude").value, amplitude.value, 0.05 * amplitude.standard_error);
  double dphi = piece(b, "phase").value - piece(a, "phase").value +
                2.0 * M_PI * x0 / piece(b, "wavelength").value;
  dphi -= 2.0 * M_PI * std::round(dphi / (2.0 * M_PI));
  EXPECT_NEAR(dphi, 0.0, 1e-3) << "phase at the origin " << piece(b, "phase").value;
  // The phase at the origin is as uncertain as the wavelength makes it there.
  EXPECT_GT(piece(b, "phase").standard_error,
            0.5 * 2.0 * M_PI * x0 / (lambda.value * lambda.value) * lambda.standard_error);
  // The final models as reported, each run on its record as given.
  const auto on = [](const Diagnosis& d, const Record& r) {
    const auto& m = std::get<Extended<MaxwellSlip<double>>>(d.final_model->variant());
    return extended_validation_percent(m.base().parameters(), m.extensions(), r);
  };
  const double on_near = on(a, near), on_far = on(b, far);
  EXPECT_NEAR(on_far, on_near, 0.02 * on_near);
  EXPECT_NEAR(b.final_validation_percent, a.final_validation_percent,
              0.02 * a.final_validation_percent);
}

}  // namespace
}  // namespace test_position_profile_study
}  // namespace friction
