// Physics of the basic Maxwell Slip model (paper eqs. 4-5).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "friction/maxwell_slip.hpp"
#include "friction/simulate.hpp"
#include "support/model_properties.hpp"

namespace test_maxwell_slip {
namespace {

using friction::MaxwellSlip;
using friction::MaxwellSlipParameters;
using friction::Motion;

MaxwellSlip<double> four_operators() {
  return MaxwellSlip<double>({{4e4, 3e4, 2e4, 1e4}, {1e-6, 3e-6, 7e-6, 15e-6}});
}

// Drive the model through the displacement points, linearly, in small steps.
double drive(MaxwellSlip<double>& m, double& x, double target, int steps = 200) {
  double f = m.force();
  const double dx = (target - x) / steps;
  for (int i = 0; i < steps; ++i) f = m.step(Motion<double>{dx, 0.0, 0.0});
  x = target;
  return f;
}

TEST(MaxwellSlip, SlidingForceIsSumOfStiffnessTimesThreshold) {
  auto m = four_operators();
  double x = 0;
  const double f = drive(m, x, 1e-4);
  EXPECT_NEAR(f, 4e4 * 1e-6 + 3e4 * 3e-6 + 2e4 * 7e-6 + 1e4 * 15e-6, 1e-12);
  EXPECT_TRUE(m.sliding());
  EXPECT_NEAR(m.parameters().sliding_force(), f, 1e-12);
  EXPECT_NEAR(drive(m, x, -1e-4), -f, 1e-12);
}

TEST(MaxwellSlip, OddSymmetryFromVirginState) {
  auto a = four_operators();
  auto b = four_operators();
  for (int k = 0; k < 500; ++k) {
    const double dx = 2e-7 * std::sin(0.05 * k) * (1 + 0.5 * std::cos(0.013 * k));
    const double fa = a.step(Motion<double>{dx, 0, 0});
    const double fb = b.step(Motion<double>{-dx, 0, 0});
    ASSERT_NEAR(fa, -fb, 1e-15);
  }
}

TEST(MaxwellSlip, ClosedMinorLoopReturnsToItsStartingForce) {
  auto m = four_operators();
  double x = 0;
  drive(m, x, 20e-6);                      // slide to the right
  const double start = drive(m, x, 8e-6);  // reverse into presliding
  drive(m, x, 12e-6);                      // reversal at 8 um, inner excursion ...
  const double back = drive(m, x, 8e-6);   // ... and back to the reversal point: the loop closes
  EXPECT_NEAR(back, start, 1e-12);
  EXPECT_FALSE(m.sliding());
}

TEST(MaxwellSlip, LargerReversalWipesOutInnerLoops) {
  // Path A has an inner loop between 8 and 4 um; path B goes straight.  Once the excursion passes
  // the inner loop's extremes, both have forgotten it: same force from then on.
  auto a = four_operators();
  auto b = four_operators();
  double xa = 0, xb = 0;
  drive(a, xa, 20e-6);
  drive(b, xb, 20e-6);
  drive(a, xa, 8e-6);
  drive(a, xa, 12e-6);
  drive(a, xa, 4e-6);
  drive(b, xb, 4e-6);
  // Going below 4 um then back up past 20 um wipes out every inner reversal.
  for (double target : {-3e-6, 6e-6, 25e-6}) {
    EXPECT_NEAR(drive(a, xa, target), drive(b, xb, target), 1e-12) << "at x = " << target;
  }
}

TEST(MaxwellSlip, LevelScalesTheSlipForce) {
  auto m = four_operators();
  const double f = m.parameters().sliding_force();
  double last = 0;
  for (int k = 0; k < 400; ++k) last = m.step(Motion<double>{1e-7, 0, 0, 1.3});
  EXPECT_NEAR(last, 1.3 * f, 1e-12);
}

TEST(MaxwellSlip, RejectsNonPhysicalParameters) {
  using P = MaxwellSlipParameters<double>;
  EXPECT_THROW(MaxwellSlip<double>(P{{1.0}, {-1e-6}}), friction::InvalidParameter);
  EXPECT_THROW(MaxwellSlip<double>(P{{-1.0}, {1e-6}}), friction::InvalidParameter);
  EXPECT_THROW(MaxwellSlip<double>(P{{1.0, 2.0}, {1e-6}}), friction::InvalidParameter);
  EXPECT_THROW(MaxwellSlip<double>(P{{}, {}}), friction::InvalidParameter);
  EXPECT_THROW(MaxwellSlip<double>(P{{NAN}, {1e-6}}), friction::InvalidParameter);
  EXPECT_NO_THROW(MaxwellSlip<double>(P{{-1.0}, {1e-6}}, /*allow_negative_stiffness=*/true));
}

TEST(MaxwellSlip, JetDerivativesMatchFiniteDifferencesAndStepDoesNotAllocate) {
  auto factory = [](const auto& theta) {
    using T = typename std::decay_t<decltype(theta)>::value_type;
    MaxwellSlipParameters<T> p;
    for (std::size_t i = 0; i < theta.size() / 2; ++i) {
      p.stiffness.push_back(theta[2 * i]);
      p.threshold.push_back(theta[2 * i + 1]);
    }
    return MaxwellSlip<T>(p);
  };
  std::vector<double> time, x;
  friction::testing::test_excitation(3000, 1e-3, 20e-6, time, x);
  const std::vector<double> theta{4e4, 1e-6, 3e4, 3e-6, 2e4, 7e-6, 1e4, 15e-6};
  friction::testing::expect_derivatives_match_finite_differences(factory, theta, time, x, 1e-4);
  auto model = factory(theta);
  friction::testing::expect_step_does_not_allocate(model, time, x);
}

}  // namespace
}  // namespace test_maxwell_slip
