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

}  // namespace
}  // namespace test_position_profile
}  // namespace friction
