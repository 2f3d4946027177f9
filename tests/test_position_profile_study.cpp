// The other five cases of test_position_profile (position_profile_cases.hpp): 11.5-15.5 periods
// over the travel.  A study of the same code paths, labelled long: the Release pass runs it, the
// sanitizer pass does not.
#include "position_profile_cases.hpp"

namespace friction {
namespace test_position_profile_study {
namespace {

TEST(PositionProfileStudy, ManyPeriodsOverTheTravelStartInTheRightBasin) {
  for (std::uint64_t k = 2; k <= 6; ++k) position_profile_cases::expect_right_basin(k);
}

}  // namespace
}  // namespace test_position_profile_study
}  // namespace friction
