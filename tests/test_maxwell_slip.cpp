// Physics of the basic Maxwell Slip model (paper eqs. 4-5).
#include <gtest/gtest.h>

#include <ceres/jet.h>

#include <cmath>
#include <random>
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

// The step forms a slip limit's product only when the limit binds (scalar.hpp: clamp_to_limits).
// Against the step as eqs. 4-5 write it, both limits formed and clamped, in Jets whose lanes carry
// the level, the asymmetry, the increments and each threshold: the same force and deflections,
// value and every derivative to the bit, on random motions with turns, a moving level and
// asymmetry (a change in the order of an operation would show here, not in a tolerance).
TEST(MaxwellSlip, TheStepIsEqs4And5ToTheBitWithJets) {
  using J = ceres::Jet<double, 8>;
  std::mt19937_64 rng(20261206);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const std::size_t m = 1 + trial % 5;
    MaxwellSlipParameters<J> p;
    for (std::size_t i = 0; i < m; ++i) {
      p.stiffness.push_back(J(1e4 * (1.5 + u(rng)), static_cast<int>(i % 8)));
      p.threshold.push_back(J(1e-6 * (i + 1) * (1.2 + u(rng)), static_cast<int>((i + 3) % 8)));
    }
    MaxwellSlip<J> model(p);
    std::vector<J> delta(m, J(0));
    for (int k = 0; k < 2000; ++k) {
      Motion<J> mo{J(3e-7 * u(rng), 5), J(0), J(1e-3)};
      mo.level = J(1.0 + 0.4 * u(rng), 6);
      mo.asymmetry = J(0.2 * u(rng), 7);
      if (k % 7 == 0) {
        mo.turn = J(2e-7 * u(rng), 4);
        if (k % 14 == 0) mo.turn_level = J(1.0 + 0.3 * u(rng), 2);
      }
      // Eqs. 4-5 with both limits formed.
      const J up = mo.level * (J(1) + mo.asymmetry), down = mo.level * (J(1) - mo.asymmetry);
      J force(0);
      for (std::size_t i = 0; i < m; ++i) {
        const J lo = -down * p.threshold[i], hi = up * p.threshold[i];
        if (mo.turn.a != 0.0) {
          const J at_turn = mo.turn_level.a > 0.0 ? mo.turn_level : mo.level;
          const J up_turn = at_turn * (J(1) + mo.asymmetry);
          const J down_turn = at_turn * (J(1) - mo.asymmetry);
          const J turned = friction::clamp(J(delta[i] + mo.turn), J(-down_turn * p.threshold[i]),
                                           J(up_turn * p.threshold[i]));
          delta[i] = friction::clamp(J(turned + (mo.dx - mo.turn)), lo, hi);
        } else {
          delta[i] = friction::clamp(J(delta[i] + mo.dx), lo, hi);
        }
        force += p.stiffness[i] * delta[i];
      }
      const J stepped = model.step(mo);
      ASSERT_EQ(stepped.a, force.a) << trial << " " << k;
      for (int l = 0; l < 8; ++l)
        ASSERT_EQ(stepped.v[l], force.v[l]) << trial << " " << k << " " << l;
      for (std::size_t i = 0; i < m; ++i) {
        ASSERT_EQ(model.deflections()[i].a, delta[i].a);
        for (int l = 0; l < 8; ++l) ASSERT_EQ(model.deflections()[i].v[l], delta[i].v[l]);
      }
    }
  }
}

}  // namespace
}  // namespace test_maxwell_slip
