// The Stribeck curve g(v) and the static friction curve F = sgn(v) level g(v) + sigma2 v.
#include <gtest/gtest.h>

#include <ceres/jet.h>

#include <cmath>
#include <random>
#include <vector>

#include "friction/static_friction.hpp"
#include "friction/stribeck.hpp"
#include "support/model_properties.hpp"

namespace test_static_friction {
namespace {

using friction::StaticFriction;
using friction::StaticFrictionParameters;
using friction::StribeckCurve;

StaticFrictionParameters<double> stribeck_viscous() {
  return {{/*coulomb=*/1.0, /*static_force=*/1.5, /*vs=*/1e-3, /*q=*/2.0}, /*viscous=*/0.4};
}

TEST(StribeckCurve, ValuesAtRestAtTheStribeckVelocityAndFarAbove) {
  const StribeckCurve<double> g{1.0, 1.5, 1e-3, 2.0};
  EXPECT_DOUBLE_EQ(g(0.0), 1.5);
  EXPECT_NEAR(g(1e-3), 1.0 + 0.5 * std::exp(-1.0), 1e-15);
  EXPECT_NEAR(g(-2e-3), 1.0 + 0.5 * std::exp(-4.0), 1e-15);
  EXPECT_NEAR(g(1.0), 1.0, 1e-15);
  const StribeckCurve<double> g1{2.0, 3.0, 1e-2, 1.0};  // q = 1: exponential decay
  EXPECT_NEAR(g1(5e-3), 2.0 + std::exp(-0.5), 1e-15);
}

TEST(StribeckCurve, JetDerivativesAreFiniteAtRestAndMatchTheCurveAway) {
  using Jet = ceres::Jet<double, 4>;
  const StribeckCurve<Jet> g{Jet(1.0, 0), Jet(1.5, 1), Jet(1e-3, 2), Jet(0.7, 3)};
  const Jet at_rest = g(Jet(0.0));
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(std::isfinite(at_rest.v[i]));
  EXPECT_DOUBLE_EQ(at_rest.v[1], 1.0);  // dg/dFs = 1 at rest
  // Away from rest: d g / d q against a central difference.
  const double v = 2.5e-3, h = 1e-7;
  auto gq = [&](double q) { return StribeckCurve<double>{1.0, 1.5, 1e-3, q}(v); };
  EXPECT_NEAR(g(Jet(v)).v[3], (gq(0.7 + h) - gq(0.7 - h)) / (2 * h), 1e-7);
}

// Far above vs the weight's Jet is formed without its two exponentials (stribeck.hpp): the
// same value and lanes as exp(-exp(q log(|v| / vs))) written here, to the bit and to the sign of
// every zero, on both sides of the cut (|v|/vs)^q = e^6.62 and with lanes of either sign and +-0.
TEST(StribeckCurve, TheWeightFarAboveVsIsTheTwoExponentialsToTheBit) {
  using Jet = ceres::Jet<double, 6>;
  std::mt19937_64 rng(61206);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int cut = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const double q = 0.5 + 3.0 * (u(rng) + 1.0);
    const double ratio = std::exp((0.5 + 0.5 * u(rng)) * 20.0 / q);  // (|v|/vs)^q up to e^20
    const double sign = trial % 2 ? 1.0 : -1.0;
    Jet v(sign * 1e-3 * ratio), vs(1e-3), qj(q);
    for (int l = 0; l < 6; ++l) {
      const int pick = (trial + l) % 5;
      const double lane = pick == 0 ? 0.0 : pick == 1 ? -0.0 : u(rng);
      (l % 3 == 0 ? v : l % 3 == 1 ? vs : qj).v[l] = lane;
    }
    const Jet w = friction::stribeck_weight(v, vs, qj);
    using std::exp;
    using std::log;
    const Jet want = exp(-exp(qj * log(Jet(sign * v) / vs)));
    cut += qj.a * std::log(ratio) > 6.62 ? 1 : 0;
    ASSERT_EQ(std::signbit(w.a), std::signbit(want.a)) << trial;
    ASSERT_EQ(w.a, want.a) << trial;
    for (int l = 0; l < 6; ++l) {
      ASSERT_EQ(w.v[l], want.v[l]) << trial << " " << l;
      ASSERT_EQ(std::signbit(w.v[l]), std::signbit(want.v[l])) << trial << " " << l;
    }
  }
  EXPECT_GT(cut, 1000) << "too few samples beyond the cut to test it";
  EXPECT_LT(cut, 3000) << "too few samples before the cut";
}

TEST(StaticFriction, CurveValuesSignAndLevel) {
  StaticFriction<double> model(stribeck_viscous());
  EXPECT_DOUBLE_EQ(model.force(0.0), 0.0);
  EXPECT_NEAR(model.force(1e-3), 1.0 + 0.5 * std::exp(-1.0) + 0.4e-3, 1e-15);
  EXPECT_NEAR(model.force(-1e-3), -(1.0 + 0.5 * std::exp(-1.0) + 0.4e-3), 1e-15);
  EXPECT_NEAR(model.force(0.1), 1.0 + 0.04, 1e-12);
  EXPECT_NEAR(model.force(1e-9), 1.5, 1e-6);  // breakaway level just above rest
  // The level scales the Coulomb-Stribeck part only.
  EXPECT_NEAR(model.force(0.1, 2.0), 2.0 + 0.04, 1e-12);
  // Stribeck dip: friction falls with speed below a few vs, then rises with the viscous term.
  EXPECT_GT(model.force(1e-4), model.force(3e-3));
  EXPECT_GT(model.force(10.0), model.force(3e-3));
  // step uses the sample's velocity and level.
  EXPECT_NEAR(model.step({1e-6, 1e-3, 1e-3, 1.5}), 1.5 * (1.0 + 0.5 * std::exp(-1.0)) + 0.4e-3,
              1e-15);
}

TEST(StaticFriction, RejectsNonPhysicalParameters) {
  auto bad = stribeck_viscous();
  bad.viscous = -1.0;
  EXPECT_THROW(StaticFriction<double>{bad}, friction::InvalidParameter);
  bad = stribeck_viscous();
  bad.curve.coulomb = 0.0;
  EXPECT_THROW(StaticFriction<double>{bad}, friction::InvalidParameter);
  bad = stribeck_viscous();
  bad.curve.stribeck_velocity = -1e-3;
  EXPECT_THROW(StaticFriction<double>{bad}, friction::InvalidParameter);
  bad = stribeck_viscous();
  bad.curve.stribeck_exponent = NAN;
  EXPECT_THROW(StaticFriction<double>{bad}, friction::InvalidParameter);
}

TEST(StaticFriction, JetDerivativesMatchFiniteDifferencesAndStepDoesNotAllocate) {
  auto factory = [](const auto& theta) {
    using T = typename std::decay_t<decltype(theta)>::value_type;
    return StaticFriction<T>({{theta[0], theta[1], theta[2], theta[3]}, theta[4]});
  };
  std::vector<double> time, x;
  friction::testing::test_excitation(2000, 1e-3, 2e-3, time, x);  // speeds around vs
  const std::vector<double> theta{1.0, 1.5, 1e-2, 1.5, 0.4};
  friction::testing::expect_derivatives_match_finite_differences(factory, theta, time, x, 1e-5);
  auto model = factory(theta);
  friction::testing::expect_step_does_not_allocate(model, time, x);
}

}  // namespace
}  // namespace test_static_friction
