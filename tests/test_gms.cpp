// The Generalized Maxwell Slip model (methods.md section 5).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "friction/gms.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/simulate.hpp"
#include "support/model_properties.hpp"

namespace test_gms {
namespace {

using friction::Gms;
using friction::GmsParameters;
using friction::MaxwellSlip;
using friction::Motion;
using friction::StribeckCurve;

GmsParameters<double> three_elements(double attraction, double fs = 1.5, double viscous = 0.0) {
  return {{6e4, 3e4, 1e4}, {0.5, 0.3, 0.2}, {1.0, fs, 1e-3, 2.0}, attraction, viscous};
}

double steady_sliding_force(const GmsParameters<double>& p, double v, double ts = 1e-3) {
  Gms<double> m(p);
  double f = 0;
  for (int k = 0; k < 20000; ++k) f = m.step({v * ts, v, ts});
  return f;
}

TEST(Gms, ReducesToMaxwellSlipForLargeAttractionAndNoStribeck) {
  auto p = three_elements(/*C=*/1e12, /*Fs=*/1.0);
  const auto ms_parameters = p.maxwell_slip_limit();
  EXPECT_NEAR(ms_parameters.threshold[0], 0.5 * 1.0 / 6e4, 1e-20);
  Gms<double> gms(p);
  MaxwellSlip<double> ms(ms_parameters);
  std::vector<double> time, x;
  // Amplitude such that the reversals stay inside some thresholds (nonlocal memory) and slides.
  friction::testing::test_excitation(4000, 1e-3, 30e-6, time, x);
  // Also a stretch at rest (dx = 0 samples) in the middle.
  x.insert(x.begin() + 2000, 200, x[2000]);
  time.resize(x.size());
  for (std::size_t k = 0; k < time.size(); ++k) time[k] = 1e-3 * static_cast<double>(k);
  gms.reset();
  ms.reset();
  const auto f_gms =
      friction::simulate(gms, std::span<const double>(time), std::span<const double>(x));
  // GMS steps on the increments (its elements integrate a rate law over the interval); the Maxwell
  // Slip limit of it is the operators stepped on the increments alone, without the turns between
  // samples that a record-level Maxwell Slip run passes through (motion.hpp).
  std::vector<double> f_ms(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    const Motion<double> m =
        friction::motion_at(std::span<const double>(time), std::span<const double>(x), k);
    f_ms[k] = ms.step(Motion<double>{m.dx, m.velocity, m.dt});
  }
  double largest = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    ASSERT_NEAR(f_gms[k], f_ms[k], 1e-12) << "sample " << k;
    largest = std::max(largest, std::abs(f_ms[k]));
  }
  EXPECT_NEAR(largest, 1.0, 1e-9);  // the record slides (reaches the sliding force)
}

TEST(Gms, VirginPreslidingIsTheParallelSprings) {
  Gms<double> m(three_elements(1e3));
  // 0.5 um: below every element's breakaway displacement alpha_i Fs / k_i (>= 12.5 um).
  double f = 0;
  for (int k = 0; k < 10; ++k) f = m.step({0.05e-6, 0.05e-3, 1e-3});
  EXPECT_NEAR(f, 1e5 * 0.5e-6, 1e-12);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(m.slip_state(i), 0);
  // Rest holds the force.
  EXPECT_NEAR(m.step({0.0, 0.0, 1e-3}), f, 1e-15);
}

TEST(Gms, SteadySlidingForceIsTheStaticCurve) {
  const auto p = three_elements(/*C=*/2e3, /*Fs=*/1.5, /*sigma2=*/10.0);
  std::vector<double> forces;
  for (double v : {3e-4, 1e-3, 2e-3, 5e-3, 2e-2}) {
    const double expected = p.curve(v) + 10.0 * v;
    EXPECT_NEAR(steady_sliding_force(p, v), expected, 1e-9) << "v = " << v;
    EXPECT_NEAR(steady_sliding_force(p, -v), -expected, 1e-9) << "v = " << -v;
    forces.push_back(steady_sliding_force(p, v));
  }
  // The Stribeck dip (friction falls with speed) and the viscous rise.
  EXPECT_GT(forces[0], forces[1] + 0.1);
  EXPECT_GT(forces[1], forces[3] + 0.1);
  EXPECT_GT(forces[4], forces[3]);
}

// Area of the loop F(v) over the last period of a sliding velocity v0 (1 + 0.5 sin(w t)).
double lag_loop_area(double attraction) {
  Gms<double> m(three_elements(attraction));
  const double ts = 1e-3, period = 1.0, v0 = 1e-3;
  const int per_period = static_cast<int>(period / ts);
  double area = 0, v_prev = 0, f_prev = 0;
  for (int k = 1; k <= 4 * per_period; ++k) {
    const double t = k * ts;
    const double v = v0 * (1 + 0.5 * std::sin(2 * M_PI * t / period));
    const double f = m.step({v * ts, v, ts});
    if (k > 3 * per_period) area += 0.5 * (f + f_prev) * (v - v_prev);  // trapezoid of F dv
    v_prev = v;
    f_prev = f;
  }
  return std::abs(area);
}

TEST(Gms, FrictionalLagLoopShrinksAsTheAttractionGrows) {
  const double a10 = lag_loop_area(10.0);  // time constant g/C ~ 0.12 s: a wide loop
  const double a100 = lag_loop_area(100.0);
  const double a1000 = lag_loop_area(1000.0);
  const double a1e6 = lag_loop_area(1e6);  // follows the curve: no loop
  EXPECT_GT(a10, a100);
  EXPECT_GT(a100, a1000);
  EXPECT_LT(a1e6, 1e-3 * a10);
  // For a lag much shorter than the period (but longer than a sample) the area is proportional to
  // the time constant g/C: ten times the attraction, a tenth of the area (up to ~30 %).
  const double ratio = lag_loop_area(30.0) / lag_loop_area(300.0);
  EXPECT_GT(ratio, 7.0);
  EXPECT_LT(ratio, 14.0);
}

TEST(Gms, LevelScalesTheSlipForces) {
  const auto p = three_elements(1e3);
  Gms<double> m(p);
  double f = 0;
  for (int k = 0; k < 20000; ++k) f = m.step({1e-6, 1e-3, 1e-3, 0.7});
  EXPECT_NEAR(f, 0.7 * p.curve(1e-3), 1e-9);
}

TEST(Gms, RejectsNonPhysicalParameters) {
  auto bad = three_elements(1e3);
  bad.share = {0.5, 0.3, 0.3};  // sums to 1.1
  EXPECT_THROW(Gms<double>{bad}, friction::InvalidParameter);
  bad = three_elements(1e3);
  bad.share = {0.5, 0.6, -0.1};
  EXPECT_THROW(Gms<double>{bad}, friction::InvalidParameter);
  bad = three_elements(1e3);
  bad.stiffness = {6e4, 3e4};
  EXPECT_THROW(Gms<double>{bad}, friction::InvalidParameter);
  bad = three_elements(0.0);
  EXPECT_THROW(Gms<double>{bad}, friction::InvalidParameter);
  bad = three_elements(1e3, 1.5, -1.0);
  EXPECT_THROW(Gms<double>{bad}, friction::InvalidParameter);
  bad = three_elements(1e3);
  bad.curve.static_force = 0.0;
  EXPECT_THROW(Gms<double>{bad}, friction::InvalidParameter);
}

TEST(Gms, JetDerivativesMatchFiniteDifferencesAndStepDoesNotAllocate) {
  // k (3), unnormalised shares (3), Fc, Fs, vs, q, C, sigma2.
  auto factory = [](const auto& theta) {
    using T = typename std::decay_t<decltype(theta)>::value_type;
    GmsParameters<T> p;
    p.stiffness = {theta[0], theta[1], theta[2]};
    const T total = theta[3] + theta[4] + theta[5];
    p.share = {theta[3] / total, theta[4] / total, theta[5] / total};
    p.curve = StribeckCurve<T>{theta[6], theta[7], theta[8], theta[9]};
    p.attraction = theta[10];
    p.viscous = theta[11];
    return Gms<T>(p);
  };
  std::vector<double> time, x;
  friction::testing::test_excitation(3000, 1e-3, 20e-6, time, x);
  const std::vector<double> theta{1e5, 4e4, 1.5e4, 0.5, 0.3, 0.2, 1.0, 1.4, 1e-4, 1.5, 50.0, 2e3};
  friction::testing::expect_derivatives_match_finite_differences(factory, theta, time, x, 1e-4);
  auto model = factory(theta);
  friction::testing::expect_step_does_not_allocate(model, time, x);
}

}  // namespace
}  // namespace test_gms
