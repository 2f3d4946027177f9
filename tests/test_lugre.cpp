// LuGre model (paper eqs. 1-3): exact step, CVODES integration and sensitivities, differentiator.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "friction/differentiator.hpp"
#include "friction/lugre.hpp"
#include "friction/lugre_cvodes.hpp"
#include "friction/lugre_transition_table.hpp"
#include "friction/simulate.hpp"
#include "support/model_properties.hpp"

namespace test_lugre {
namespace {

using friction::CvodesMethod;
using friction::CvodesOptions;
using friction::LuGre;
using friction::LuGreParameters;
using friction::Motion;
using friction::StribeckShape;

LuGreParameters<double> paper_like(double sigma0 = 1e5,
                                   StribeckShape shape = StribeckShape::Rational) {
  return {sigma0, std::sqrt(sigma0), 0.5, 1.0, 1.5, 1e-3, 2.0, shape};
}

// Presliding sinusoids of a few micrometres, then sliding sweeps (+-12 mm/s), at 1 kHz.
void presliding_then_sliding(std::size_t n, std::vector<double>& time, std::vector<double>& x) {
  time.resize(n);
  x.resize(n);
  const double ts = 1e-3, t_switch = 0.3 * static_cast<double>(n) * ts;
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * ts;
    time[k] = t;
    x[k] = t < t_switch ? 3e-6 * std::sin(2 * M_PI * 2 * t)
                        : 3e-6 * std::sin(2 * M_PI * 2 * t_switch) +
                              2e-3 * std::sin(2 * M_PI * (t - t_switch));
  }
}

std::vector<double> exact(const LuGreParameters<double>& p, const std::vector<double>& time,
                          const std::vector<double>& x, double z0 = 0.0,
                          std::vector<double>* state = nullptr) {
  LuGre<double> model(p);
  model.reset(z0);
  std::vector<double> force(x.size());
  if (state) state->resize(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    Motion<double> m{0.0, 0.0, 0.0};
    if (k > 0) {
      m.dt = time[k] - time[k - 1];
      m.dx = x[k] - x[k - 1];
      m.velocity = m.dx / m.dt;
    }
    force[k] = model.step(m);
    if (state) (*state)[k] = model.state();
  }
  return force;
}

// A sensitivity column against the central difference (fp - fm) / 2h of the exact step: the
// norms of their difference and of the difference quotient.
struct ColumnCheck {
  double difference = 0, reference = 0;
};
template <typename Column>
ColumnCheck against_central_difference(const std::vector<double>& fp,
                                       const std::vector<double>& fm, double h, Column column) {
  double num = 0, den = 0;
  for (std::size_t k = 0; k < fp.size(); ++k) {
    const double fd = (fp[k] - fm[k]) / (2 * h);
    num += (column(k) - fd) * (column(k) - fd);
    den += fd * fd;
  }
  return {std::sqrt(num), std::sqrt(den)};
}

// Column j of an N x 7 row-major Jacobian dF/dtheta against central differences of the exact
// step in theta_j (step 1e-5 theta_j).
ColumnCheck parameter_column_check(const LuGreParameters<double>& p,
                                   const std::vector<double>& time, const std::vector<double>& x,
                                   double z0, const std::vector<double>& jacobian, std::size_t j) {
  const auto theta = p.to_array();
  const double h = 1e-5 * theta[j];
  auto plus = theta, minus = theta;
  plus[j] += h;
  minus[j] -= h;
  return against_central_difference(
      exact(LuGreParameters<double>::from_array(plus, p.shape), time, x, z0),
      exact(LuGreParameters<double>::from_array(minus, p.shape), time, x, z0), h,
      [&](std::size_t k) { return jacobian[7 * k + j]; });
}

// Steady state written out independently of the library's helpers.
double expected_steady_force(const LuGreParameters<double>& p, double v) {
  const double r = std::abs(v) / p.stribeck_velocity;
  const double w = p.shape == StribeckShape::Rational
                       ? 1.0 / (1.0 + std::pow(r, p.stribeck_exponent))
                       : std::exp(-std::pow(r, p.stribeck_exponent));
  const double slip = p.coulomb + (p.static_force - p.coulomb) * w;
  return (v > 0 ? slip : -slip) + p.viscous * v;
}

TEST(LuGre, SteadyStateAtConstantVelocityIsTheStribeckCurve) {
  for (StribeckShape shape : {StribeckShape::Rational, StribeckShape::Exponential}) {
    const auto p = paper_like(1e5, shape);
    for (double speed : {2e-4, 1e-3, 3e-3, 2e-2, 0.3}) {
      for (double v : {speed, -speed}) {
        LuGre<double> model(p);
        model.reset();
        // Long enough for the slowest case: z relaxes with time constant s(v)/|v| <= 0.075 s.
        const double dt = 1e-3;
        double f = 0;
        for (int k = 0; k < 2000; ++k) f = model.step(Motion<double>{v * dt, v, dt});
        const double expected = expected_steady_force(p, v);
        EXPECT_NEAR(f, expected, 1e-9 * std::abs(expected)) << "v = " << v;
        EXPECT_NEAR(friction::steady_state_force(p, v), expected, 1e-12 * std::abs(expected));
        EXPECT_GT(f * v, 0.0) << "the force must resist the motion";
      }
    }
  }
  // The Stribeck dip is there: Fs at rest, Fc + sigma2 v far above vs.
  const auto p = paper_like();
  EXPECT_NEAR(friction::steady_state_force(p, 1e-9), 1.5, 1e-6);
  EXPECT_NEAR(friction::steady_state_force(p, 1.0), 1.0 + 0.5 / (1.0 + 1e6) + 0.5, 1e-12);
}

TEST(LuGre, PreslidingStiffnessIsSigma0PlusDampingTerm) {
  // From rest, a creep of 1 nm per ms: z ~ x while |x| << s(v) = 1.5e-5 m, and
  // F = sigma0 z + sigma1 dz/dt + sigma2 v with dz/dt ~ v, so F ~ sigma0 x + (sigma1 + sigma2) v.
  // The neglected slip term |v| z / s is below x/s = 1e-3 relative after 10 samples.
  const auto p = paper_like(1e5);
  LuGre<double> model(p);
  model.reset();
  const double dt = 1e-3, dx = 1e-9, v = dx / dt;
  double x = 0, previous = 0;
  for (int k = 1; k <= 10; ++k) {
    x += dx;
    const double f = model.step(Motion<double>{dx, v, dt});
    const double expected = p.stiffness * x + (p.micro_damping + p.viscous) * v;
    EXPECT_NEAR(f, expected, 2e-3 * expected) << "sample " << k;
    if (k > 1) {
      EXPECT_NEAR((f - previous) / dx, p.stiffness, 2e-3 * p.stiffness);
    }
    previous = f;
  }
  // Standing still keeps the deflection, and the force drops to the spring part sigma0 z.
  const double z = model.state();
  EXPECT_NEAR(model.step(Motion<double>{0.0, 0.0, dt}), p.stiffness * z, 1e-15);
  EXPECT_EQ(model.state(), z);
}

TEST(LuGre, LevelScalesTheSlipForceNotTheViscousTerm) {
  const auto p = paper_like();
  LuGre<double> model(p);
  const double v = 5e-3, dt = 1e-3;
  double f = 0;
  for (int k = 0; k < 500; ++k) f = model.step(Motion<double>{v * dt, v, dt, 1.3});
  EXPECT_NEAR(f, 1.3 * (expected_steady_force(p, v) - p.viscous * v) + p.viscous * v, 1e-9);
}

TEST(LuGre, RejectsNonPhysicalParameters) {
  auto bad = [](auto change) {
    auto p = paper_like();
    change(p);
    return p;
  };
  using P = LuGreParameters<double>;
  EXPECT_THROW(LuGre<double>(bad([](P& p) { p.stiffness = 0; })), friction::InvalidParameter);
  EXPECT_THROW(LuGre<double>(bad([](P& p) { p.micro_damping = -1; })), friction::InvalidParameter);
  EXPECT_THROW(LuGre<double>(bad([](P& p) { p.viscous = NAN; })), friction::InvalidParameter);
  EXPECT_THROW(LuGre<double>(bad([](P& p) { p.coulomb = 0; })), friction::InvalidParameter);
  EXPECT_THROW(LuGre<double>(bad([](P& p) { p.static_force = -1; })), friction::InvalidParameter);
  EXPECT_THROW(LuGre<double>(bad([](P& p) { p.stribeck_velocity = 0; })),
               friction::InvalidParameter);
  EXPECT_THROW(LuGre<double>(bad([](P& p) { p.stribeck_exponent = INFINITY; })),
               friction::InvalidParameter);
  EXPECT_NO_THROW(LuGre<double>(bad([](P& p) { p.micro_damping = p.viscous = 0; })));
}

TEST(LuGre, JetDerivativesMatchFiniteDifferencesAndStepDoesNotAllocate) {
  for (StribeckShape shape : {StribeckShape::Rational, StribeckShape::Exponential}) {
    auto factory = [shape](const auto& theta) {
      using T = typename std::decay_t<decltype(theta)>::value_type;
      return LuGre<T>(LuGreParameters<T>{theta[0], theta[1], theta[2], theta[3], theta[4], theta[5],
                                         theta[6], shape});
    };
    // Reversals through the Stribeck region (|v| up to ~2.5e-2 m/s) and rests at v = 0 exactly.
    std::vector<double> time, x;
    friction::testing::test_excitation(3000, 1e-3, 2e-3, time, x);
    for (std::size_t k = 1000; k < 1100; ++k) x[k] = x[999];
    const std::vector<double> theta{1e5, 300.0, 0.5, 1.0, 1.5, 1e-3, 2.0};
    friction::testing::expect_derivatives_match_finite_differences(factory, theta, time, x, 1e-5);
    auto model = factory(theta);
    friction::testing::expect_step_does_not_allocate(model, time, x);
  }
}

TEST(LuGre, JetDerivativesAreFiniteAtRest) {
  using Jet = ceres::Jet<double, 7>;
  const auto theta = paper_like().to_array();
  std::array<Jet, 7> tj;
  for (int j = 0; j < 7; ++j) tj[j] = Jet(theta[j], j);
  for (StribeckShape shape : {StribeckShape::Rational, StribeckShape::Exponential}) {
    auto p = LuGreParameters<Jet>::from_array(tj, shape);
    p.stribeck_exponent = Jet(0.5, 6);  // d/dv |v|^mu is infinite at 0 for mu < 1
    LuGre<Jet> model(p);
    model.reset(Jet(1e-6));
    const Jet f = model.step(Motion<Jet>{Jet(0), Jet(0), Jet(1e-3)});
    EXPECT_DOUBLE_EQ(f.a, 0.1);
    for (int j = 0; j < 7; ++j) EXPECT_TRUE(std::isfinite(f.v[j])) << "direction " << j;
    EXPECT_DOUBLE_EQ(f.v[0], 1e-6);  // dF/dsigma0 = z
  }
}

// --- CVODES ---------------------------------------------------------------------------------

TEST(LuGreCvodes, AgreesWithTheExactStep) {
  std::vector<double> time, x;
  presliding_then_sliding(3000, time, x);
  std::vector<double> level(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) level[k] = 1.0 + 0.2 * std::sin(1e-3 * k);
  for (double sigma0 : {1e5, 1e6}) {
    for (CvodesMethod method : {CvodesMethod::Adams, CvodesMethod::BDF}) {
      const auto p = paper_like(sigma0, StribeckShape::Exponential);
      CvodesOptions options;
      options.method = method;
      const double z0 = 3e-7;
      const auto r = friction::simulate_lugre_cvodes(p, time, x, options, z0, level);
      // Reference: the exact step with the same level.
      LuGre<double> model(p);
      model.reset(z0);
      std::vector<double> f_exact(x.size());
      friction::simulate(model, std::span<const double>(time), std::span<const double>(x),
                         std::span<double>(f_exact), std::span<const double>(level));
      double z_err = 0, f_err = 0, z_scale = 0;
      LuGre<double> stepper(p);
      stepper.reset(z0);
      for (std::size_t k = 0; k < x.size(); ++k) {
        Motion<double> m{0.0, 0.0, 0.0, level[k]};
        if (k > 0) {
          m.dt = time[k] - time[k - 1];
          m.dx = x[k] - x[k - 1];
          m.velocity = m.dx / m.dt;
        }
        stepper.step(m);
        z_err = std::max(z_err, std::abs(r.state[k] - stepper.state()));
        z_scale = std::max(z_scale, std::abs(stepper.state()));
        f_err = std::max(f_err, std::abs(r.force[k] - f_exact[k]));
      }
      // Defaults rtol = 1e-6, atol = 1e-8 N: the state error stays within a few rtol of the
      // largest deflection (per-interval local errors of order rtol, relaxed by the dissipation),
      // and the force error within sigma0 times that plus the damping term's share.
      EXPECT_LT(z_err, 1e-4 * z_scale) << "sigma0 " << sigma0;
      EXPECT_LT(f_err, 1e-3) << "sigma0 " << sigma0;
      EXPECT_GT(r.statistics.steps, 0);
      EXPECT_EQ(r.force[0], sigma0 * z0);
    }
  }
}

TEST(LuGreCvodes, TighterTolerancesConvergeToTheExactStep) {
  std::vector<double> time, x;
  presliding_then_sliding(1500, time, x);
  const auto p = paper_like();
  const auto f_exact = exact(p, time, x);
  auto max_error = [&](double rtol) {
    CvodesOptions o;
    o.relative_tolerance = rtol;
    o.absolute_tolerance = rtol * 1e-2;
    const auto r = friction::simulate_lugre_cvodes(p, time, x, o);
    double e = 0;
    for (std::size_t k = 0; k < x.size(); ++k) e = std::max(e, std::abs(r.force[k] - f_exact[k]));
    return e;
  };
  const double coarse = max_error(1e-4), fine = max_error(1e-8);
  EXPECT_LT(fine, 1e-6);
  EXPECT_LT(fine, 1e-2 * coarse);  // the difference is integration error, not a model mismatch
}

TEST(LuGreCvodes, SensitivitiesMatchFiniteDifferencesOfTheExactStep) {
  std::vector<double> time, x;
  presliding_then_sliding(1500, time, x);
  const auto p = paper_like(1e5, StribeckShape::Rational);
  const double z0 = -2e-6;
  CvodesOptions o;
  o.sensitivities = true;
  o.relative_tolerance = 1e-8;
  o.absolute_tolerance = 1e-10;
  const auto r = friction::simulate_lugre_cvodes(p, time, x, o, z0);
  ASSERT_EQ(r.jacobian.size(), 7 * x.size());
  ASSERT_EQ(r.initial_state_derivative.size(), x.size());

  auto compare = [&](const ColumnCheck& c, const std::string& what) {
    EXPECT_GT(c.reference, 0.0) << what;
    // Integration error at rtol 1e-8 and the O(h^2) finite difference: 1e-4 relative is 100x
    // above what was seen and far below the effect of a wrong term (order 1).
    EXPECT_LE(c.difference, 1e-4 * c.reference) << what;
  };
  for (std::size_t j = 0; j < 7; ++j)
    compare(parameter_column_check(p, time, x, z0, r.jacobian, j),
            friction::kLuGreParameterNames[j]);
  const double h = 1e-8;
  compare(against_central_difference(exact(p, time, x, z0 + h), exact(p, time, x, z0 - h), h,
                                     [&](std::size_t k) { return r.initial_state_derivative[k]; }),
          "z0");

  // Log parametrisation: column j scaled by theta_j.
  const auto theta = p.to_array();
  o.log_parameters = true;
  const auto rl = friction::simulate_lugre_cvodes(p, time, x, o, z0);
  for (std::size_t k = 0; k < x.size(); k += 97)
    for (std::size_t j = 0; j < 7; ++j)
      EXPECT_NEAR(rl.jacobian[7 * k + j], theta[j] * r.jacobian[7 * k + j],
                  1e-12 * std::abs(theta[j] * r.jacobian[7 * k + j]) + 1e-15);
}

// Strokes at constant speeds with rests between them, on an axis 0.1 m from the origin with
// decimal time stamps: the velocities of one stroke differ only in their last bits.  CVODES
// restarts where the velocity jumps, not at every sample, and integrates each stroke in one go;
// its force, state and sensitivities must still agree with the exact step (forces and states as
// in AgreesWithTheExactStep; the Jacobian against central differences of the exact step, as in
// SensitivitiesMatchFiniteDifferencesOfTheExactStep but at the default tolerances).
TEST(LuGreCvodes, IntegratesAStrokeAtConstantSpeedInOneGo) {
  const std::vector<double> speeds{0.5e-3, -2e-3, 4e-3, -1e-3, 8e-3, -0.2e-3};
  std::vector<double> time, x;
  double position = 0.1;
  std::size_t strokes = 0;
  auto hold = [&](std::size_t samples, double speed) {
    for (std::size_t i = 0; i < samples; ++i) {
      time.push_back(static_cast<double>(time.size()) * 1e-3);
      x.push_back(position);
      position += speed * 1e-3;
    }
  };
  for (double v : speeds) {
    hold(400, v);
    ++strokes;
    hold(100, 0.0);
  }
  const auto p = paper_like(1e6);
  const double z0 = 4e-7;
  CvodesOptions o;
  o.sensitivities = true;
  const auto r = friction::simulate_lugre_cvodes(p, time, x, o, z0);
  // A stroke's first interval starts from the rest before it, so each stroke is one stretch.
  EXPECT_EQ(r.statistics.restarts, static_cast<long>(strokes));
  EXPECT_EQ(r.statistics.intervals_integrated, static_cast<long>(400 * strokes));

  std::vector<double> z_exact;
  const auto f_exact = exact(p, time, x, z0, &z_exact);
  double z_err = 0, z_scale = 0, f_err = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    z_err = std::max(z_err, std::abs(r.state[k] - z_exact[k]));
    z_scale = std::max(z_scale, std::abs(z_exact[k]));
    f_err = std::max(f_err, std::abs(r.force[k] - f_exact[k]));
  }
  EXPECT_LT(z_err, 1e-4 * z_scale);
  EXPECT_LT(f_err, 1e-3);

  for (std::size_t j = 0; j < 7; ++j) {
    const ColumnCheck c = parameter_column_check(p, time, x, z0, r.jacobian, j);
    // Measured: at most 2.2e-6 relative (sigma0) with the sensitivities in the error test across
    // a stretch, 4.9e-5 without it (and 2.7e-5 restarting at every sample): a sensitivity left
    // out of the error test over a stretch fails here, as would a wrong term (order 1).
    EXPECT_LE(c.difference, 1e-5 * c.reference) << friction::kLuGreParameterNames[j];
  }
}

TEST(LuGreCvodes, ReportsIntegratorFailureAndBadInput) {
  std::vector<double> time, x;
  presliding_then_sliding(500, time, x);
  CvodesOptions o;
  o.max_steps_per_sample = 1;
  try {
    friction::simulate_lugre_cvodes(paper_like(), time, x, o);
    FAIL() << "expected a NumericalError";
  } catch (const friction::NumericalError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("CV_TOO_MUCH_WORK"), std::string::npos) << what;
    EXPECT_NE(what.find("t = "), std::string::npos) << what;
  }
  std::vector<double> bad_time = time;
  bad_time[10] = bad_time[9];
  EXPECT_THROW(friction::simulate_lugre_cvodes(paper_like(), bad_time, x),
               friction::InvalidParameter);
  auto p = paper_like();
  p.coulomb = -1;
  EXPECT_THROW(friction::simulate_lugre_cvodes(p, time, x), friction::InvalidParameter);
}

TEST(LuGreCvodes, UsesAGivenVelocityInsteadOfTheBackwardDifference) {
  std::vector<double> time, x;
  presliding_then_sliding(800, time, x);
  const auto p = paper_like();
  const auto v = friction::smoothed_interval_velocity(time, x, 4);
  const auto r = friction::simulate_lugre_cvodes(p, time, x, {}, 0.0, {}, v);
  LuGre<double> model(p);
  double err = 0;
  for (std::size_t k = 1; k < x.size(); ++k) {
    const double dt = time[k] - time[k - 1];
    err =
        std::max(err, std::abs(model.step(Motion<double>{x[k] - x[k - 1], v[k], dt}) - r.force[k]));
  }
  EXPECT_LT(err, 1e-3);
}

// --- Stick-slip of a mass pulled through a spring (Canudas de Wit et al. 1995) ----------------

// The tabulated transitions (LG's search objective) against the exact step: random parameters
// over LG's search box (sigma0 1e3..1e7 N/m, mu 0.3..6, vs over five decades, both shapes) on
// records whose speeds span many decades (a smooth presliding-then-sliding motion plus a small
// random walk, so that the speeds near reversals are tiny), at three sampling rates, time stamps
// written as decimals.  The free-run force must agree to 1e-5 of its largest value (the header's
// statement); a record at irregular intervals gets no table.
TEST(LuGreTransitionTable, FreeRunsAgreeWithTheExactStep) {
  std::mt19937 gen(90417);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto log_uniform = [&](double lo, double hi) { return lo * std::pow(hi / lo, unit(gen)); };
  double worst = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const double ts = std::array<double, 3>{1e-3, 2e-4, 5e-5}[trial % 3];
    const std::size_t n = 6000;
    std::vector<double> time(n), x(n);
    std::normal_distribution<double> step(0.0, log_uniform(1e-10, 1e-7));
    double walk = 0;
    for (std::size_t k = 0; k < n; ++k) {
      time[k] = std::stod(std::to_string(static_cast<double>(k) * ts));  // as a CSV holds it
      const double t = static_cast<double>(k) / static_cast<double>(n);
      walk += step(gen);
      x[k] =
          (t < 0.3 ? 3e-6 * std::sin(2 * M_PI * 4 * t) : 2e-3 * std::sin(2 * M_PI * 3 * t)) + walk;
    }
    LuGreParameters<double> p;
    p.stiffness = log_uniform(1e3, 1e7);
    p.micro_damping = log_uniform(1e-3, 30.0) * std::sqrt(p.stiffness);
    p.viscous = log_uniform(1e-2, 1e2);
    p.coulomb = log_uniform(0.3, 30.0);
    p.static_force = p.coulomb * log_uniform(0.5, 3.0);
    p.stribeck_velocity = log_uniform(1e-6, 1e-1);
    p.stribeck_exponent = 0.3 + 5.7 * unit(gen);
    p.shape = trial % 2 ? StribeckShape::Exponential : StribeckShape::Rational;
    std::vector<Motion<double>> motions(n);
    for (std::size_t k = 0; k < n; ++k) motions[k] = friction::motion_at<double>(time, x, k);
    const friction::LuGreTransitionTable table(motions);
    ASSERT_TRUE(table.usable()) << trial;
    const double z0 = 0.3 * p.static_force / p.stiffness;
    LuGre<double> model(p);
    model.reset(z0);
    std::vector<double> tabulated(n);
    table.run(model, tabulated.data());
    const std::vector<double> reference = exact(p, time, x, z0);
    double largest = 0, error = 0;
    for (std::size_t k = 0; k < n; ++k) {
      largest = std::max(largest, std::abs(reference[k]));
      error = std::max(error, std::abs(tabulated[k] - reference[k]));
    }
    worst = std::max(worst, error / largest);
    EXPECT_LT(error, 1e-5 * largest) << "trial " << trial << " nodes " << table.nodes();
  }
  std::cout << "largest relative force error " << worst << "\n";
  std::vector<double> time(4000), x(4000);
  std::mt19937 jitter_gen(5);
  std::vector<Motion<double>> motions(time.size());
  for (std::size_t k = 0; k < time.size(); ++k) {
    time[k] = 1e-3 * static_cast<double>(k) + (k ? 2e-4 * unit(jitter_gen) : 0.0);
    x[k] = 1e-3 * std::sin(0.01 * static_cast<double>(k));
  }
  for (std::size_t k = 0; k < time.size(); ++k)
    motions[k] = friction::motion_at<double>(time, x, k);
  EXPECT_FALSE(friction::LuGreTransitionTable(motions).usable());
}

TEST(LuGre, StickSlipOfASpringPulledMassIsPeriodic) {
  // m x'' = k (V t - x) - F(x', z), with the published parameters and the exponential curve.
  const auto p = paper_like(1e5, StribeckShape::Exponential);  // sigma1 = sqrt(1e5), mu = 2
  const double mass = 1.0, k = 2.0, drive = 0.1;
  struct State {
    double x, u, z;
  };
  auto derivative = [&](double t, const State& s) {
    const double dz = friction::lugre_rhs(p, s.z, s.u);
    const double f = p.stiffness * s.z + p.micro_damping * dz + p.viscous * s.u;
    return State{s.u, (k * (drive * t - s.x) - f) / mass, dz};
  };
  // Classical RK4 with h = 2e-5 s: the fastest rate is |v|/s(v) <= 0.36 / 1e-5 = 3.6e4 1/s while
  // slipping (peak slip speed ~0.35 m/s), so h * rate <= 0.72, inside RK4's stability limit (2.8);
  // the bristle oscillation during stick (sqrt(sigma0/m) = 316 rad/s) gets 1000 steps per cycle.
  // The first break-away comes at ~7.6 s, then one every ~6.2 s: 45 s gives 7 of them.
  const double h = 2e-5, t_end = 45.0;
  State s{0, 0, 0};
  std::vector<double> peak_time, peak_force, min_speed, max_speed;
  double previous_spring = 0, period_min_speed = 1e9, period_max_speed = 0;
  bool rising = false;
  const auto steps = static_cast<long>(t_end / h);
  for (long i = 0; i < steps; ++i) {
    const double t = static_cast<double>(i) * h;
    const State k1 = derivative(t, s);
    const State k2 =
        derivative(t + h / 2, {s.x + h / 2 * k1.x, s.u + h / 2 * k1.u, s.z + h / 2 * k1.z});
    const State k3 =
        derivative(t + h / 2, {s.x + h / 2 * k2.x, s.u + h / 2 * k2.u, s.z + h / 2 * k2.z});
    const State k4 = derivative(t + h, {s.x + h * k3.x, s.u + h * k3.u, s.z + h * k3.z});
    s.x += h / 6 * (k1.x + 2 * k2.x + 2 * k3.x + k4.x);
    s.u += h / 6 * (k1.u + 2 * k2.u + 2 * k3.u + k4.u);
    s.z += h / 6 * (k1.z + 2 * k2.z + 2 * k3.z + k4.z);
    const double spring = k * (drive * (t + h) - s.x);
    period_min_speed = std::min(period_min_speed, std::abs(s.u));
    period_max_speed = std::max(period_max_speed, s.u);
    // A peak of the spring force is the breakaway that ends a stick phase.
    if (rising && spring < previous_spring) {
      peak_time.push_back(t);
      peak_force.push_back(previous_spring);
      min_speed.push_back(period_min_speed);
      max_speed.push_back(period_max_speed);
      period_min_speed = 1e9;
      period_max_speed = 0;
    }
    rising = spring > previous_spring;
    previous_spring = spring;
  }
  ASSERT_TRUE(std::isfinite(s.x) && std::isfinite(s.u) && std::isfinite(s.z));
  ASSERT_GE(peak_time.size(), 5u) << "no sustained stick-slip";
  // Skip the first two cycles (transient from rest); compare the rest with each other.
  const std::size_t first = 2;
  const double period = peak_time[first + 1] - peak_time[first];
  for (std::size_t i = first + 1; i < peak_time.size(); ++i) {
    // Same period to 1 ms (50 integration steps; the peak time is located to one step) and the
    // same breakaway force to 1e-3 N: a limit cycle, not a decaying or growing oscillation.
    EXPECT_NEAR(peak_time[i] - peak_time[i - 1], period, 1e-3) << "cycle " << i;
    EXPECT_NEAR(peak_force[i], peak_force[i - 1], 1e-3) << "cycle " << i;
    // Each cycle contains a stick (the mass nearly at rest: below 1 % of the drive speed) and a
    // slip (faster than the drive).
    EXPECT_LT(min_speed[i], 1e-2 * drive) << "cycle " << i;
    EXPECT_GT(max_speed[i], drive) << "cycle " << i;
  }
  // Break-away happens near the static force.  The slow force rate (k V = 0.2 N/s) lets the
  // bristles creep: the peak lies between Fc and Fs, within 5 % of Fs.
  EXPECT_NEAR(peak_force.back(), p.static_force, 0.05 * p.static_force);
  EXPECT_GT(peak_force.back(), p.coulomb);
  // The period is set by the force drop (Fs - Fc ~ 0.5 N twice over) at 0.2 N/s: a few seconds.
  EXPECT_GT(period, 1.0);
  EXPECT_LT(period, 10.0);
}

// --- Differentiator -------------------------------------------------------------------------

TEST(Differentiator, HalfWidthOneIsTheBackwardDifference) {
  std::vector<double> time, x;
  presliding_then_sliding(300, time, x);
  const auto a = friction::backward_difference_velocity(time, x);
  const auto b = friction::smoothed_interval_velocity(time, x, 1);
  ASSERT_EQ(a.size(), x.size());
  EXPECT_EQ(a[0], 0.0);
  for (std::size_t k = 1; k < x.size(); ++k) {
    EXPECT_DOUBLE_EQ(a[k], (x[k] - x[k - 1]) / (time[k] - time[k - 1]));
    EXPECT_NEAR(b[k], a[k], 1e-12 * std::abs(a[k]) + 1e-15);
  }
}

TEST(Differentiator, SmoothedVelocityIsExactForAQuadraticAtTheIntervalMidpoint) {
  // Non-uniform sample times: the fit uses them.
  std::vector<double> time(60), x(60);
  for (std::size_t k = 0; k < time.size(); ++k) {
    time[k] = 1e-3 * static_cast<double>(k) + 2e-4 * std::sin(static_cast<double>(k));
    x[k] = 0.3 * time[k] * time[k] - 0.01 * time[k] + 1e-4;
  }
  for (std::size_t half_width : {2u, 5u}) {
    const auto v = friction::smoothed_interval_velocity(time, x, half_width);
    // With jittered times the window is not symmetric about the interval's midpoint, so a
    // quadratic's slope is off by its curvature (0.6 m/s^2) times that asymmetry (< m Ts).
    for (std::size_t k = 1; k < x.size(); ++k) {
      const double mid = 0.5 * (time[k - 1] + time[k]);
      EXPECT_NEAR(v[k], 0.6 * mid - 0.01, 0.6 * 1e-3 * static_cast<double>(half_width));
    }
  }
  for (std::size_t k = 0; k < time.size(); ++k) {
    time[k] = 1e-3 * static_cast<double>(k);
    x[k] = 0.3 * time[k] * time[k] - 0.01 * time[k] + 1e-4;
  }
  const auto v = friction::smoothed_interval_velocity(time, x, 5);
  for (std::size_t k = 1; k < x.size(); ++k)
    EXPECT_NEAR(v[k], 0.6 * (0.5 * (time[k - 1] + time[k])) - 0.01, 1e-12);
}

TEST(Differentiator, NoiseGainMatchesTheStatedFigures) {
  EXPECT_NEAR(friction::velocity_noise_gain(1), std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(friction::velocity_noise_gain(5), 0.1101, 1e-4);
  EXPECT_NEAR(friction::velocity_noise_gain(10), 0.0388, 1e-4);
  // Monte Carlo on white displacement noise (Ts = 1 ms): the velocity's standard deviation.
  const std::size_t n = 100000;
  const double ts = 1e-3, sx = 1e-7;
  std::vector<double> time(n), x(n);
  std::mt19937 rng(12345);
  std::normal_distribution<double> noise(0.0, sx);
  for (std::size_t k = 0; k < n; ++k) {
    time[k] = ts * static_cast<double>(k);
    x[k] = noise(rng);
  }
  for (std::size_t half_width : {1u, 2u, 5u, 10u}) {
    const auto v = friction::smoothed_interval_velocity(time, x, half_width);
    double sum2 = 0;
    for (std::size_t k = 100; k + 100 < n; ++k) sum2 += v[k] * v[k];
    const double sv = std::sqrt(sum2 / static_cast<double>(n - 200));
    // 1e5 correlated samples: the estimate is good to well under 2 %.
    EXPECT_NEAR(sv, friction::velocity_noise_gain(half_width) * sx / ts,
                0.02 * friction::velocity_noise_gain(half_width) * sx / ts)
        << "half width " << half_width;
  }
}

TEST(Differentiator, RejectsBadInput) {
  std::vector<double> time{0.0, 1e-3, 1e-3}, x{0.0, 1.0, 2.0};
  EXPECT_THROW(friction::backward_difference_velocity(time, x), friction::InvalidParameter);
  time[2] = 2e-3;
  EXPECT_THROW(friction::smoothed_interval_velocity(time, x, 0), friction::InvalidParameter);
  std::vector<double> short_x{0.0};
  EXPECT_THROW(friction::backward_difference_velocity(time, short_x), friction::InvalidParameter);
}

}  // namespace
}  // namespace test_lugre
