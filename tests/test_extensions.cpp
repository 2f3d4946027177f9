// The extension pieces of methods.md section 7 around the base models.
#include <gtest/gtest.h>

#include <ceres/jet.h>

#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "friction/dnlrx.hpp"
#include "friction/extension_fit.hpp"
#include "friction/extensions.hpp"
#include "friction/gms.hpp"
#include "friction/lugre.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/simulate.hpp"
#include "friction/static_friction.hpp"
#include "support/model_properties.hpp"

namespace test_extensions {
namespace {

using friction::Effect;
using friction::Extended;
using friction::ExtendedSlipJacobian;
using friction::ExtensionParameters;
using friction::MaxwellSlip;
using friction::MaxwellSlipParameters;
using friction::Motion;
using friction::Record;

const MaxwellSlipParameters<double> kFour{{4e4, 3e4, 2e4, 1e4}, {1e-6, 3e-6, 7e-6, 15e-6}};
const double kF0 = 0.42;        // sum k_i Delta_i of kFour [N]
const double kStiffness = 1e5;  // sum k_i [N/m]

using ExtendedMs = Extended<MaxwellSlip<double>>;

ExtendedMs extended(const ExtensionParameters<double>& p) {
  return ExtendedMs(MaxwellSlip<double>(kFour), p);
}

// A record sliding at constant speed v (m/s) from x0, n samples at period ts.
void ramp(double v, std::size_t n, double ts, std::vector<double>& time, std::vector<double>& x,
          double x0 = 0.0) {
  time.resize(n);
  x.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    time[k] = ts * static_cast<double>(k);
    x[k] = x0 + v * time[k];
  }
}

std::vector<double> base_force(const std::vector<double>& time, const std::vector<double>& x) {
  MaxwellSlip<double> ms(kFour);
  return friction::simulate(ms, std::span<const double>(time), std::span<const double>(x));
}

// The base stepped on the increments alone, as a causal (per-sample) step does: no turn between
// samples (motion.hpp).
std::vector<double> base_force_on_increments(const std::vector<double>& time,
                                             const std::vector<double>& x) {
  MaxwellSlip<double> ms(kFour);
  std::vector<double> f(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    const Motion<double> m =
        friction::motion_at(std::span<const double>(time), std::span<const double>(x), k);
    f[k] = ms.step(Motion<double>{m.dx, m.velocity, m.dt});
  }
  return f;
}

std::vector<double> run(ExtendedMs& m, const std::vector<double>& time,
                        const std::vector<double>& x, const std::vector<double>& normal = {}) {
  m.reset();
  return friction::simulate_extended(m, std::span<const double>(time), std::span<const double>(x),
                                     std::span<const double>(normal));
}

TEST(Extensions, NamesAreThoseOfMethodsSection7) {
  EXPECT_EQ(friction::effect_name(Effect::frictional_lag), "frictional-lag");
  EXPECT_EQ(friction::effect_name(Effect::position_dependence), "position-dependence");
  EXPECT_EQ(friction::effect_name(Effect::normal_load), "normal-load");
  for (Effect e : friction::kAllEffects)
    EXPECT_EQ(friction::effect_from_name(friction::effect_name(e)), e);
  EXPECT_FALSE(friction::effect_from_name("nonlocal-memory").has_value());

  ExtensionParameters<double> p;
  for (Effect e : friction::kAllEffects) p.enable(e);
  std::vector<std::string> names;
  p.for_each_parameter([&](Effect, std::string_view n, double&) { names.emplace_back(n); });
  const std::vector<std::string> expected{"viscous",
                                          "static",
                                          "stribeck_velocity",
                                          "stribeck_exponent",
                                          "lag_time",
                                          "asymmetry",
                                          "offset",
                                          "mass",
                                          "amplitude",
                                          "wavelength",
                                          "phase",
                                          "relative_rate",
                                          "delay",
                                          "friction_coefficient"};
  EXPECT_EQ(names, expected);
  EXPECT_EQ(p.parameter_count(), expected.size());
  p.disable(Effect::stribeck);
  EXPECT_FALSE(p.has(Effect::stribeck));
  EXPECT_EQ(p.parameter_count(), expected.size() - 3);

  p.offset->offset = 0.25;
  const auto q = p.cast<float>([](double v) { return static_cast<float>(v); });
  EXPECT_FALSE(q.has(Effect::stribeck));
  EXPECT_FLOAT_EQ(q.offset->offset, 0.25f);
}

TEST(Extensions, OffsetAddsAConstantEvenAtRest) {
  ExtensionParameters<double> p;
  p.offset = {{0.05}};
  auto m = extended(p);
  m.reset();
  EXPECT_DOUBLE_EQ(m.step(Motion<double>{0, 0, 0}), 0.05);  // virgin, at rest
  std::vector<double> time, x;
  friction::testing::test_excitation(1000, 1e-3, 20e-6, time, x);
  const auto f = run(m, time, x);
  const auto f0 = base_force(time, x);
  for (std::size_t k = 0; k < x.size(); ++k) ASSERT_NEAR(f[k] - f0[k], 0.05, 1e-15);
}

TEST(Extensions, InertiaAddsMassTimesAcceleration) {
  ExtensionParameters<double> p;
  p.inertia = {{2.0}};
  auto m = extended(p);
  const double ts = 1e-3, w = 2 * M_PI * 5.0, amplitude = 30e-6;
  std::vector<double> time(400), x(400);
  for (std::size_t k = 0; k < x.size(); ++k) {
    time[k] = ts * static_cast<double>(k);
    x[k] = amplitude * std::sin(w * time[k]);
  }
  const auto f = run(m, time, x);
  const auto f0 = base_force(time, x);
  const double peak = 2.0 * amplitude * w * w;
  for (std::size_t k = 1; k + 1 < x.size(); ++k)  // central difference: O((w ts)^2) relative
    ASSERT_NEAR(f[k] - f0[k], -2.0 * w * w * x[k], 1e-3 * peak) << k;
  // Per sample (step(Motion)) the backward difference estimates a one sample late.
  m.reset();
  const auto g = friction::simulate(m, std::span<const double>(time), std::span<const double>(x));
  for (std::size_t k = 2; k < x.size(); ++k)
    ASSERT_NEAR(g[k] - f0[k], -2.0 * w * w * x[k - 1], 1e-3 * peak) << k;
}

TEST(Extensions, ViscousAddsSigma2TimesVelocity) {
  ExtensionParameters<double> p;
  p.viscous = {{30.0}};
  for (double v : {1e-3, -4e-3}) {
    auto m = extended(p);
    std::vector<double> time, x;
    ramp(v, 200, 1e-3, time, x);
    EXPECT_NEAR(run(m, time, x).back(), std::copysign(kF0, v) + 30.0 * v, 1e-12) << v;
  }
}

TEST(Extensions, StribeckScalesTheSlidingLevelFromStaticToCoulomb) {
  ExtensionParameters<double> p;
  p.stribeck = {{/*static=*/0.6, /*vs=*/1e-3, /*q=*/2.0}};
  for (double v : {2e-4, 1e-3, -1.5e-3, 1e-2}) {
    auto m = extended(p);
    std::vector<double> time, x;
    ramp(v, 300, 1e-3, time, x);
    const double g = kF0 + (0.6 - kF0) * std::exp(-(v / 1e-3) * (v / 1e-3));
    EXPECT_NEAR(run(m, time, x).back(), std::copysign(g, v), 1e-12) << v;
  }
}

TEST(Extensions, FrictionalLagDelaysTheVelocityOfTheViscousTerm) {
  ExtensionParameters<double> p;
  p.viscous = {{50.0}};
  p.frictional_lag = {{0.02}};
  auto m = extended(p);
  m.reset();
  const double ts = 1e-3, v1 = 1e-3, v2 = 3e-3;
  double f = 0;
  for (int k = 0; k < 300; ++k) f = m.step(Motion<double>{v1 * ts, v1, ts});
  EXPECT_NEAR(f, kF0 + 50.0 * v1, 1e-12);  // steady: no lag left
  for (int k = 1; k <= 100; ++k) {
    f = m.step(Motion<double>{v2 * ts, v2, ts});
    const double lagged = v2 + (v1 - v2) * std::exp(-k * ts / 0.02);
    ASSERT_NEAR(f, kF0 + 50.0 * lagged, 1e-12) << k;
  }
}

// Direction-dependent slip limits: sliding levels (1 +- a) F0, no jump anywhere, and, while the
// level is constant, exactly the symmetric model plus a F0 once every operator has slipped
// (presliding and rests included); a changing level (here a drift) tells the two apart.
TEST(Extensions, AsymmetryIsDirectionalSlipLimitsAndAnOffsetWhileTheLevelIsConstant) {
  const double a = 0.2;
  ExtensionParameters<double> p;
  p.asymmetry = {{a}};
  auto m = extended(p);
  std::vector<double> time, x;
  // Slide +, then -, then + again (triangle wave of +-60 um, well beyond the largest threshold),
  // then presliding loops of decreasing amplitude and a rest.
  const double ts = 1e-3, step = 1e-7;
  double pos = 0;
  for (int k = 0; k < 3000; ++k) {
    time.push_back(ts * k);
    const int phase = (k / 600) % 2;
    pos += (k < 300 ? step : (phase ? -step : step));
    x.push_back(pos);
  }
  for (int k = 0; k < 3000; ++k) {
    time.push_back(ts * (3000 + k));
    x.push_back(pos + 6e-6 * (1 - k / 3000.0) * std::sin(2 * M_PI * k / 400.0));
  }
  const auto f = run(m, time, x);
  const double f_plus = f[1799], f_minus = f[1199];  // the ends of a + and of a - slide
  EXPECT_NEAR(f_plus, (1 + a) * kF0, 1e-12);
  EXPECT_NEAR(f_minus, -(1 - a) * kF0, 1e-12);
  EXPECT_NEAR((f_plus - (-f_minus)) / (f_plus + (-f_minus)), a, 1e-12);
  // No jump anywhere, reversals included: the force moves by at most the stiffness times the path
  // from x_{k-1} to x_k (through the turn between them, when there is one: motion.hpp).
  for (std::size_t k = 1; k < f.size(); ++k) {
    const double turn = friction::turn_increment(std::span<const double>(x), k);
    const double path = std::abs(turn) + std::abs(x[k] - x[k - 1] - turn);
    ASSERT_LE(std::abs(f[k] - f[k - 1]), kStiffness * path * (1 + 1e-9)) << "sample " << k;
  }
  // The symmetric model plus a F0, from the first full slide on.
  ExtensionParameters<double> offset;
  offset.offset = {{a * kF0}};
  auto o = extended(offset);
  const auto g = run(o, time, x);
  for (std::size_t k = 700; k < f.size(); ++k) ASSERT_NEAR(f[k], g[k], 1e-12) << k;
  // With a drift the asymmetry scales with the level and the offset does not.
  p.drift = {{0.2}};
  offset.drift = {{0.2}};
  auto md = extended(p);
  auto od = extended(offset);
  const auto fd = run(md, time, x), gd = run(od, time, x);
  double worst = 0;
  for (std::size_t k = 700; k < f.size(); ++k) worst = std::max(worst, std::abs(fd[k] - gd[k]));
  EXPECT_GT(worst, 0.1 * a * kF0);
}

TEST(Extensions, PositionDependenceFollowsTheTravel) {
  ExtensionParameters<double> p;
  p.position_dependence = {{/*amplitude=*/0.1, /*wavelength=*/100e-6, /*phase=*/0.3}};
  auto m = extended(p);
  std::vector<double> time, x;
  ramp(1e-4, 3000, 1e-3, time, x, /*x0=*/-20e-6);
  const auto f = run(m, time, x);
  for (std::size_t k = 500; k < x.size(); ++k)
    ASSERT_NEAR(f[k], kF0 + 0.1 * std::sin(2 * M_PI * x[k] / 100e-6 + 0.3), 1e-12) << k;
}

// The velocity stage recorded on one run and replayed on another whose pieces differ only after
// it (a profile's grid points, extension_profile.cpp) gives the force that run computes, bit for
// bit; a replay shorter than the run hands over to computing with the lag's state intact.
TEST(Extensions, AReplayedVelocityStageGivesTheComputedForceBitForBit) {
  std::vector<double> time(3000), x(3000);
  for (std::size_t k = 0; k < x.size(); ++k) {
    time[k] = 1e-3 * static_cast<double>(k);
    // Reversals, rests near the turns and speeds through the Stribeck curve's range.
    x[k] = 40e-6 * std::sin(2 * M_PI * 0.7 * time[k]) + 5e-6 * std::sin(2 * M_PI * 3.1 * time[k]);
  }
  ExtensionParameters<double> p;
  p.frictional_lag = {{0.01}};
  p.stribeck = {{/*static=*/1.5 * kF0, /*vs=*/1e-4, /*q=*/1.7}};
  p.viscous = {{30.0}};
  p.position_dependence = {{/*amplitude=*/0.05, /*wavelength=*/30e-6, /*phase=*/0.3}};
  ExtensionParameters<double> q = p;  // another grid point of the position profile
  q.position_dependence = {{/*amplitude=*/0.1, /*wavelength=*/17e-6, /*phase=*/2.0}};

  std::vector<double> lagged, factor;
  auto recording = extended(p);
  recording.record_velocity_stage(lagged, factor);
  const auto recorded_force = run(recording, time, x);
  ASSERT_EQ(lagged.size(), x.size());
  ASSERT_EQ(factor.size(), x.size());
  auto plain_p = extended(p);
  EXPECT_EQ(run(plain_p, time, x), recorded_force);

  auto plain = extended(q);
  const auto computed = run(plain, time, x);
  ASSERT_NE(computed, recorded_force);  // the position piece moved the force
  auto replaying = extended(q);
  replaying.replay_velocity_stage(lagged, factor);
  EXPECT_EQ(run(replaying, time, x), computed);
  // Half the stage replayed, the rest computed.
  auto half = extended(q);
  half.replay_velocity_stage(std::span<const double>(lagged).first(1500),
                             std::span<const double>(factor).first(1500));
  EXPECT_EQ(run(half, time, x), computed);
  // A replay of another lag is a different force: the replay is what the run reads.
  ExtensionParameters<double> other_lag = q;
  other_lag.frictional_lag = {{0.002}};
  auto wrong = extended(other_lag);
  wrong.replay_velocity_stage(lagged, factor);
  auto right = extended(other_lag);
  EXPECT_NE(run(wrong, time, x), run(right, time, x));
}

TEST(Extensions, DriftScalesTheLevelWithTime) {
  ExtensionParameters<double> p;
  p.drift = {{-0.05}};
  auto m = extended(p);
  std::vector<double> time, x;
  ramp(-1e-4, 4000, 1e-3, time, x);
  const auto f = run(m, time, x);
  for (std::size_t k = 500; k < x.size(); k += 250)
    EXPECT_NEAR(f[k], -kF0 * (1 - 0.05 * time[k]), 1e-12) << k;
}

TEST(Extensions, NormalLoadMakesFrictionProportionalToTheNormalForce) {
  ExtensionParameters<double> p;
  p.normal_load = {{/*friction_coefficient=*/0.21}};  // N_ref = F0 / mu = 2 N
  auto m = extended(p);
  std::vector<double> time, x, normal;
  ramp(1e-4, 3000, 1e-3, time, x);
  for (double t : time) normal.push_back(2.0 + std::sin(2 * M_PI * t / 3.0));
  const auto f = run(m, time, x, normal);
  for (std::size_t k = 500; k < x.size(); ++k) ASSERT_NEAR(f[k], 0.21 * normal[k], 1e-12) << k;
  EXPECT_THROW(run(m, time, x), friction::InvalidParameter);  // needs the normal force
}

// The quadratic through the first sample whose slope and curvature fit the first `length` samples
// by least squares, evaluated at t (held at its value length - 1 samples before the record beyond
// that): what a delay's displacement before the record must be (extensions.hpp, Delay), written
// here with Eigen's QR.
double front_quadratic(const std::vector<double>& time, const std::vector<double>& x,
                       std::size_t length, double t) {
  Eigen::MatrixXd v(static_cast<Eigen::Index>(length - 1), 2);
  Eigen::VectorXd y(static_cast<Eigen::Index>(length - 1));
  for (std::size_t i = 1; i < length; ++i) {
    const double u = time[i] - time[0];
    v.row(static_cast<Eigen::Index>(i - 1)) << u, u * u;
    y(static_cast<Eigen::Index>(i - 1)) = x[i] - x[0];
  }
  const Eigen::Vector2d c = v.householderQr().solve(y);
  const double u = std::max(t - time[0], time[0] - time[length - 1]);
  return x[0] + u * (c(0) + u * c(1));
}

TEST(Extensions, DelayShiftsTheForceInTime) {
  std::vector<double> time, x;
  friction::testing::test_excitation(1500, 1e-3, 20e-6, time, x);
  const std::size_t edge =
      friction::delay_edge_length(friction::record_derivative_windows(time, x));
  ASSERT_GE(edge, 3u);
  // Five samples: the base on x[k - 5], and before the record on the motion the record's first
  // samples extrapolate.
  ExtensionParameters<double> p;
  p.delay = {{5e-3}};
  auto m = extended(p);
  const auto f = run(m, time, x);
  std::vector<double> shifted(x.size());
  for (std::size_t k = 0; k < x.size(); ++k)
    shifted[k] = k >= 5 ? x[k - 5] : front_quadratic(time, x, edge, time[k] - 5e-3);
  const auto f5 = base_force(time, shifted);
  for (std::size_t k = 0; k < x.size(); ++k) ASSERT_NEAR(f[k], f5[k], 1e-14) << k;

  // A fractional delay on a record is the base on the displacement interpolated by cubics (midway
  // between samples: (-x_{j-1} + 9 x_j + 9 x_{j+1} - x_{j+2}) / 16; linearly in the first
  // interval); the per-sample (causal, ring-buffer) path interpolates linearly and holds the first
  // sample before the record.
  p.delay->delay = 2.5e-3;
  auto fractional = extended(p);
  const auto fr = run(fractional, time, x);
  std::vector<double> cubic(x.size()), linear(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    linear[k] = k < 3 ? x[0] : 0.5 * (x[k - 2] + x[k - 3]);
    cubic[k] = k < 3   ? front_quadratic(time, x, edge, time[k] - 2.5e-3)
               : k < 4 ? linear[k]
                       : (-x[k - 4] + 9 * x[k - 3] + 9 * x[k - 2] - x[k - 1]) / 16;
  }
  const auto expected = base_force(time, cubic);
  for (std::size_t k = 0; k < x.size(); ++k) ASSERT_NEAR(fr[k], expected[k], 1e-12) << k;
  fractional.reset();
  const auto per_sample =
      friction::simulate(fractional, std::span<const double>(time), std::span<const double>(x));
  const auto expected_causal = base_force_on_increments(time, linear);
  for (std::size_t k = 0; k < x.size(); ++k)
    ASSERT_NEAR(per_sample[k], expected_causal[k], 1e-14) << k;
}

// The motion before (and, for a negative delay, after) the record is the quadratic its edge
// samples fit: exact on a quadratic motion, for either sign of D, within the fit's own length;
// beyond it the value there is held.  Held at the edge sample, the first D / Ts forces of a record
// stood still where the recorded ones moved.
TEST(Extensions, ADelayExtrapolatesTheMotionBeyondTheRecord) {
  const double ts = 1e-3;
  auto motion = [](double t) { return 1e-5 + 2e-4 * t - 3e-2 * t * t; };
  std::vector<double> time(200), x(200);
  for (std::size_t k = 0; k < x.size(); ++k) {
    time[k] = 0.3 + ts * static_cast<double>(k);
    x[k] = motion(time[k]);
  }
  const std::size_t edge = 7;
  for (double d : {4.5e-3, -3.25e-3, 6e-3}) {
    const auto xs = friction::delayed_displacement(std::span<const double>(time),
                                                   std::span<const double>(x), d, edge);
    for (std::size_t k = 0; k < x.size(); ++k) {
      const double target = time[k] - d;
      // Linear in the first and last interval (a quadratic's chord there), exact elsewhere.
      const bool first = target > time[0] && target < time[1];
      const bool last = target > time[x.size() - 2] && target < time.back();
      const std::size_t j = first ? 0 : x.size() - 2;
      const double w = (target - time[j]) / ts;
      const double expected = first || last ? x[j] + w * (x[j + 1] - x[j]) : motion(target);
      ASSERT_NEAR(xs[k], expected, 1e-15) << "D " << d << " k " << k;
    }
  }
  // Twelve samples before the record with a 7-sample fit: held at t_0 - 6 Ts.
  const auto far = friction::delayed_displacement(std::span<const double>(time),
                                                  std::span<const double>(x), 12e-3, edge);
  for (std::size_t k = 0; k <= 6; ++k) EXPECT_NEAR(far[k], motion(time[0] - 6 * ts), 1e-15) << k;
  for (std::size_t k = 7; k < 12; ++k) EXPECT_NEAR(far[k], motion(time[k] - 12e-3), 1e-15) << k;
  // edge_length 0: the old hold at the edge sample.
  const auto held = friction::delayed_displacement(std::span<const double>(time),
                                                   std::span<const double>(x), 4.5e-3);
  for (std::size_t k = 0; k <= 4; ++k) EXPECT_EQ(held[k], x[0]) << k;
}

TEST(Extensions, NoPiecesIsTheBaseModel) {
  std::vector<double> time, x;
  friction::testing::test_excitation(1000, 1e-3, 20e-6, time, x);
  auto m = extended({});
  const auto f = run(m, time, x);
  EXPECT_EQ(f, base_force(time, x));
}

TEST(Extensions, RejectsInvalidPieces) {
  ExtensionParameters<double> p;
  p.asymmetry = {{1.0}};
  EXPECT_THROW(extended(p), friction::InvalidParameter);
  p = {};
  p.stribeck = {{-0.5, 1e-3, 2.0}};
  EXPECT_THROW(extended(p), friction::InvalidParameter);
  p = {};
  p.position_dependence = {{0.5, 1e-4, 0.0}};  // |amplitude| >= F0 = 0.42 N
  EXPECT_THROW(extended(p), friction::InvalidParameter);
  p = {};
  p.frictional_lag = {{-1.0}};
  EXPECT_THROW(extended(p), friction::InvalidParameter);
  p = {};
  p.offset = {{NAN}};
  EXPECT_THROW(extended(p), friction::InvalidParameter);
  p = {};
  p.normal_load = {{0.0}};
  EXPECT_THROW(extended(p), friction::InvalidParameter);
}

// Every base model takes every piece; the wrapper is itself a model that does not allocate.
template <class Base>
void expect_wraps(Base base) {
  ExtensionParameters<double> p;
  for (Effect e : friction::kAllEffects) p.enable(e);
  p.viscous->viscous = 5.0;
  p.stribeck->static_force = 1.3 * friction::detail::base_sliding_force(base);
  p.frictional_lag->lag_time = 0.01;
  p.asymmetry->asymmetry = 0.1;
  p.offset->offset = 0.01;
  p.inertia->mass = 0.5;
  p.position_dependence->amplitude = 0.05 * friction::detail::base_sliding_force(base);
  p.position_dependence->wavelength = 50e-6;
  p.drift->relative_rate = 0.02;
  p.delay->delay = 1.5e-3;
  Extended<Base> m(base, p, 16);
  static_assert(friction::FrictionModel<Extended<Base>>);
  std::vector<double> time, x, normal;
  friction::testing::test_excitation(2000, 1e-3, 20e-6, time, x);
  for (double t : time) normal.push_back(10.0 + t);
  m.reset();
  const auto f =
      friction::simulate_extended(m, std::span<const double>(time), std::span<const double>(x),
                                  std::span<const double>(normal));
  for (double v : f) ASSERT_TRUE(std::isfinite(v));
  friction::testing::expect_step_does_not_allocate(m, time, x);
}

TEST(Extensions, WrapEveryBaseModel) {
  expect_wraps(MaxwellSlip<double>(kFour));
  auto d = friction::DnlrxParameters<double>::from_maxwell_slip(kFour);
  d.input_filter = {100.0, 50.0};
  expect_wraps(friction::Dnlrx<double>(d));
  expect_wraps(
      friction::Gms<double>({{6e4, 3e4, 1e4}, {0.5, 0.3, 0.2}, {0.4, 0.5, 1e-4, 2.0}, 100.0, 0.0}));
  friction::LuGreParameters<double> lugre;
  lugre.stiffness = 1e5;
  lugre.micro_damping = 30.0;
  lugre.viscous = 0.4;
  lugre.coulomb = 0.4;
  lugre.static_force = 0.5;
  lugre.stribeck_velocity = 1e-4;
  lugre.stribeck_exponent = 2.0;
  expect_wraps(friction::LuGre<double>(lugre));
  expect_wraps(friction::StaticFriction<double>({{0.4, 0.5, 1e-4, 2.0}, 1.0}));
}

TEST(Extensions, JetDerivativesMatchFiniteDifferences) {
  // Two Maxwell Slip operators (k, Delta) and every piece but normal-load (no normal force in the
  // harness's simulate): viscous, static, vs, q, lag_time, asymmetry, offset, mass, amplitude,
  // wavelength, phase, relative_rate, delay.
  auto factory = [](const auto& theta) {
    using T = typename std::decay_t<decltype(theta)>::value_type;
    MaxwellSlipParameters<T> ms{{theta[0], theta[2]}, {theta[1], theta[3]}};
    ExtensionParameters<T> p;
    p.viscous = {{theta[4]}};
    p.stribeck = {{theta[5], theta[6], theta[7]}};
    p.frictional_lag = {{theta[8]}};
    p.asymmetry = {{theta[9]}};
    p.offset = {{theta[10]}};
    p.inertia = {{theta[11]}};
    p.position_dependence = {{theta[12], theta[13], theta[14]}};
    p.drift = {{theta[15]}};
    p.delay = {{theta[16]}};
    return Extended<MaxwellSlip<T>>(MaxwellSlip<T>(ms), p, 32);
  };
  std::vector<double> time, x;
  friction::testing::test_excitation(3000, 1e-3, 20e-6, time, x);
  const std::vector<double> theta{4e4,  2e-6, 1e4, 12e-6, 300.0, 0.35, 5e-5, 1.5,   0.01,
                                  0.15, 0.02, 5.0, 0.03,  40e-6, 0.4,  0.1,  2.3e-3};
  friction::testing::expect_derivatives_match_finite_differences(factory, theta, time, x, 1e-4);
}

TEST(Extensions, JetDerivativesOfTheNormalLoadPieceOnARecord) {
  using Jet = ceres::Jet<double, 1>;
  std::vector<double> time, x, normal;
  friction::testing::test_excitation(1000, 1e-3, 20e-6, time, x);
  for (double t : time) normal.push_back(2.0 + t);
  auto simulate_mu = [&](auto mu) {
    using T = decltype(mu);
    ExtensionParameters<T> p;
    p.normal_load = {{mu}};
    MaxwellSlipParameters<T> ms{{T(4e4), T(1e4)}, {T(2e-6), T(12e-6)}};
    Extended<MaxwellSlip<T>> m(MaxwellSlip<T>(ms), p);
    m.reset();
    std::vector<T> xt(x.begin(), x.end());
    return friction::simulate_extended(m, std::span<const double>(time), std::span<const T>(xt),
                                       std::span<const double>(normal));
  };
  const double mu = 0.1, h = 1e-7;
  const auto fj = simulate_mu(Jet(mu, 0));
  const auto fp = simulate_mu(mu + h), fm = simulate_mu(mu - h);
  double worst = 0, norm = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double fd = (fp[k] - fm[k]) / (2 * h);
    worst = std::max(worst, std::abs(fj[k].v[0] - fd));
    norm = std::max(norm, std::abs(fd));
  }
  EXPECT_GT(norm, 0.0);
  EXPECT_LT(worst, 1e-5 * norm);
}

// The fit's Jacobian (extension_fit.cpp: the pieces over the record once, then operator by
// operator) against forward-mode derivatives through the whole model, with piece sets that take
// each pair of lane widths, an initial state on a slip limit, a delay (the increments carry
// derivatives), a normal force and the lag's initial offset (a lane of the pieces' pass that
// belongs to the initial state); and sets that must take the whole-model path (F0 from the base;
// every piece at once, 14 piece parameters + the lag's offset + 2 = 17 lanes).
TEST(ExtendedSlipFit, StructuredJacobianIsTheWholeModels) {
  Record r;
  friction::testing::test_excitation(2000, 1e-3, 20e-6, r.time, r.displacement);
  for (double t : r.time) {
    r.normal.push_back(2.0 + t);
    r.force.push_back(0.3 * std::sin(40.0 * t) + 0.05);
  }
  const MaxwellSlipParameters<double> base{{4e4, 1e4, 3e3, 800.0}, {2e-6, 12e-6, 3e-5, 8e-5}};
  const std::vector<double> rho{0.3, -0.5, 1.0, -0.2};
  const double f0 = base.sliding_force();

  auto with = [&](std::initializer_list<Effect> effects, double reference) {
    ExtensionParameters<double> p;
    for (Effect e : effects) p.enable(e);
    if (p.viscous) p.viscous->viscous = 30.0;
    if (p.stribeck) p.stribeck = {{1.3 * f0, 4e-4, 1.5}};
    if (p.frictional_lag) p.frictional_lag->lag_time = 0.004;
    if (p.asymmetry) p.asymmetry->asymmetry = 0.1;
    if (p.offset) p.offset->offset = 0.02;
    if (p.inertia) p.inertia->mass = 2.0;
    if (p.position_dependence) p.position_dependence = {{0.1 * f0, 3e-4, 0.7}};
    if (p.drift) p.drift->relative_rate = 0.05;
    if (p.delay) p.delay->delay = 1.7e-3;
    if (p.normal_load) p.normal_load->friction_coefficient = f0 / 2.5;
    p.reference_force = reference;
    return p;
  };
  using enum Effect;
  struct Case {
    const char* name;
    ExtensionParameters<double> ext;
    bool structured;
  };
  const std::vector<Case> cases{
      {"no piece", with({}, f0), true},
      {"viscous (4 lanes)", with({viscous}, f0), true},
      {"stribeck (4 + 8 lanes)", with({stribeck}, f0), true},
      {"stribeck, lag, viscous (8 lanes)", with({stribeck, frictional_lag, viscous}, f0), true},
      {"11 piece parameters with a delay (16 lanes)",
       with({viscous, stribeck, frictional_lag, asymmetry, offset, inertia, drift, delay,
             normal_load},
            f0),
       true},
      {"stribeck, lag, viscous, offset, drift (8 + 16 lanes)",
       with({stribeck, frictional_lag, viscous, offset, drift}, f0), true},
      {"every piece (17 lanes: the whole model)",
       with({viscous, stribeck, frictional_lag, asymmetry, offset, inertia, position_dependence,
             drift, delay, normal_load},
            f0),
       false},
      {"stribeck with F0 from the base", with({stribeck}, 0.0), false},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::vector<double> state = rho;
    if (c.ext.frictional_lag) state.push_back(3e-4);  // u [m/s], of the record's speeds
    const ExtendedSlipJacobian fast =
        friction::extended_slip_jacobian(r, base, state, c.ext, false);
    const ExtendedSlipJacobian whole = friction::extended_slip_jacobian(r, base, state, c.ext, true);
    ASSERT_TRUE(fast.ok);
    ASSERT_TRUE(whole.ok);
    EXPECT_EQ(fast.structured, c.structured);
    EXPECT_LE((fast.residual - whole.residual).cwiseAbs().maxCoeff(),
              1e-13 * whole.residual.cwiseAbs().maxCoeff());
    for (const auto* pair : {&fast.theta, &fast.rho}) {
      const Eigen::MatrixXd& a = *pair;
      const Eigen::MatrixXd& b = pair == &fast.theta ? whole.theta : whole.rho;
      ASSERT_EQ(a.rows(), b.rows());
      ASSERT_EQ(a.cols(), b.cols());
      for (Eigen::Index j = 0; j < b.cols(); ++j) {
        const double scale = b.col(j).cwiseAbs().maxCoeff();
        EXPECT_GT(scale, 0.0) << "column " << j << " carries no derivative";
        EXPECT_LE((a.col(j) - b.col(j)).cwiseAbs().maxCoeff(), 1e-11 * scale) << "column " << j;
      }
    }
  }
}

// The stepping streams the record through a ring a few windows long (extensions.hpp,
// for_each_extended_step); every motion it hands over must be the one the whole-record arithmetic
// gives: the shifted displacement of delayed_displacement, its increments and turns on the whole
// vector, the pieces' velocity and acceleration filtered over the whole (delayed, measured)
// record.  Bit for bit, on irregular time stamps, with windows as wide as the record, a delay
// with and without derivatives, a measured displacement beside the model's, a record of Jets and
// one of doubles, and the second pass over the same record (which reuses the first's filter).
template <typename T>
void expect_streamed_motions(const std::vector<double>& time, const std::vector<T>& x,
                             const std::vector<double>& measured,
                             const friction::DerivativeWindows& w, const T& delay,
                             const std::string& what) {
  const std::size_t n = x.size();
  const std::size_t edge = friction::delay_edge_length(w);
  const std::vector<T> xs =
      friction::delayed_displacement(std::span<const double>(time), std::span<const T>(x), delay,
                                     edge);
  std::vector<T> source(n);
  for (std::size_t k = 0; k < n; ++k) source[k] = measured.empty() ? x[k] : T(measured[k]);
  const std::vector<T> ds = friction::delayed_displacement(
      std::span<const double>(time), std::span<const T>(source), delay, edge);
  std::vector<T> v(n), a(n);
  friction::apply_local_derivatives<T>(std::span<const double>(time), std::span<const T>(ds), w,
                                       std::span<T>(v), std::span<T>(a));
  auto same = [](const T& p, const T& q) {
    if constexpr (std::is_same_v<T, double>) {
      return p == q;
    } else {
      return p.a == q.a && p.v == q.v;
    }
  };
  ExtensionParameters<T> p;
  p.delay = {{delay}};
  p.viscous = {{T(10.0)}};
  MaxwellSlipParameters<T> base;
  base.stiffness = {T(4e4), T(1e4)};
  base.threshold = {T(2e-6), T(3e-5)};
  for (int pass = 0; pass < 2; ++pass) {
    Extended<MaxwellSlip<T>> model(MaxwellSlip<T>(base), p);
    std::size_t visited = 0, wrong = 0;
    friction::for_each_extended_step(
        model, std::span<const double>(time), std::span<const T>(x),
        std::span<const double>(), &w,
        [&](std::size_t k, const friction::ExtendedMotion<T>& c, const T&) {
          ++visited;
          const T dx = k > 0 ? T(xs[k] - xs[k - 1]) : T(0);
          const T turn = friction::turn_increment(std::span<const T>(xs), k);
          if (!same(c.x, xs[k]) || !same(c.dx, dx) || !same(c.turn, turn) ||
              !same(c.piece_velocity, v[k]) || !same(c.acceleration, a[k])) {
            if (wrong++ == 0)
              ADD_FAILURE() << what << ", pass " << pass << ": the first motion differing is "
                            << k << " of " << n;
          }
        },
        std::span<const double>(measured));
    EXPECT_EQ(visited, n) << what;
    EXPECT_EQ(wrong, 0u) << what << ", pass " << pass;
  }
}

TEST(Extensions, StreamedSteppingHandsOverTheWholeRecordsMotions) {
  std::vector<double> time, x;
  friction::testing::test_excitation(3000, 1e-3, 20e-6, time, x);
  // Irregular stamps (a jitter of 1e-4 Ts on every seventh sample: those windows are solved on
  // their own) and a measured displacement that is not the model's (an encoder of 5 nm).
  for (std::size_t k = 0; k < time.size(); k += 7) time[k] += 1e-7;
  std::vector<double> measured(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) measured[k] = 5e-9 * std::round(x[k] / 5e-9);
  const friction::DerivativeWindows chosen = friction::record_derivative_windows(time, measured);
  friction::DerivativeWindows wide = chosen;
  wide.velocity_half_width = 40, wide.velocity_degree = 4;
  wide.acceleration_half_width = 75, wide.acceleration_degree = 2;
  for (const auto& [w, name] : {std::pair{chosen, "the record's windows"},
                                std::pair{wide, "windows of 81 and 151 samples"}}) {
    const std::string what(name);
    expect_streamed_motions<double>(time, x, {}, w, 0.0, what + ", no delay");
    expect_streamed_motions<double>(time, x, measured, w, 0.0, what + ", measured, no delay");
    expect_streamed_motions<double>(time, x, measured, w, 2.3e-3,
                                    what + ", measured, delay 2.3 samples");
    expect_streamed_motions<double>(time, x, {}, w, -1.6e-3, what + ", delay -1.6 samples");
    using J = ceres::Jet<double, 2>;
    std::vector<J> xj(x.size());
    for (std::size_t k = 0; k < x.size(); ++k) xj[k] = J(x[k]);
    expect_streamed_motions<J>(time, xj, measured, w, J(2.3e-3, 0),
                               what + ", Jets, measured, a delay with a derivative");
    expect_streamed_motions<J>(time, xj, {}, w, J(0.0, 1),
                               what + ", Jets, a delay of 0 with a derivative");
    expect_streamed_motions<J>(time, xj, {}, w, J(0.0), what + ", Jets, no delay");
  }
  // A record shorter than the windows: they span it whole.
  std::vector<double> short_time(time.begin(), time.begin() + 40),
      short_x(x.begin(), x.begin() + 40);
  expect_streamed_motions<double>(short_time, short_x, {}, wide, 1.2e-3, "40 samples, wide");
}

// A one-off run under UncachedSteps (the diagnosis's stepping check on a grid four times finer)
// neither fills the thread's filter cache, whose buffers would keep that grid's length, nor reads
// it, and leaves it as it found it for the fit that filled it: the same force as without the cache.
TEST(Extensions, UncachedStepsLeaveTheFilterCacheAlone) {
  std::vector<double> time, x;
  friction::testing::test_excitation(2000, 1e-3, 20e-6, time, x);
  ExtensionParameters<double> p;
  p.viscous = {{10.0}};
  MaxwellSlipParameters<double> base;
  base.stiffness = {4e4, 1e4};
  base.threshold = {2e-6, 3e-5};
  auto run = [&](const std::vector<double>& t, const std::vector<double>& xx) {
    Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(base), p);
    return friction::simulate_extended(model, std::span<const double>(t),
                                       std::span<const double>(xx));
  };
  const std::vector<double> first = run(time, x);  // fills the cache with this record's filter
  auto& cache = friction::detail::filtered_displacement();
  ASSERT_TRUE(cache.valid);
  ASSERT_EQ(cache.samples, time.size());
  const std::size_t capacity = cache.velocity.capacity();
  std::vector<double> fine_time, fine_x;  // twice as fine: another length, another filter
  for (std::size_t k = 0; k + 1 < time.size(); ++k) {
    fine_time.insert(fine_time.end(), {time[k], 0.5 * (time[k] + time[k + 1])});
    fine_x.insert(fine_x.end(), {x[k], 0.5 * (x[k] + x[k + 1])});
  }
  std::vector<double> fine;
  {
    const friction::detail::UncachedSteps uncached;
    fine = run(fine_time, fine_x);
    EXPECT_TRUE(cache.busy);
  }
  EXPECT_FALSE(cache.busy);
  EXPECT_TRUE(cache.valid);
  EXPECT_EQ(cache.samples, time.size()) << "the fine grid went into the cache";
  EXPECT_EQ(cache.velocity.capacity(), capacity);
  EXPECT_EQ(run(fine_time, fine_x), fine) << "the uncached run differs from a cached one";
  // The cache now holds the fine grid's filter: the first record again, the first force.
  EXPECT_EQ(run(time, x), first);
}

TEST(Extensions, TheFilterCacheSeesAChangeOfOneSample) {
  // The thread's filter cache is reused when a record's fingerprint matches the last one's: a
  // record of the same length that differs in one time stamp or one displacement sample, changed
  // in place in the same buffers, must be filtered anew, and so simulate as a run that never
  // reads the cache does.  With the windows given, as a fit gives them (chosen anew, they might
  // differ for the changed record and hide a stale cache).
  std::vector<double> time, x;
  friction::testing::test_excitation(3000, 1e-3, 20e-6, time, x);
  ExtensionParameters<double> p;
  p.viscous = {{10.0}};
  p.inertia = {{0.5}};
  MaxwellSlipParameters<double> base;
  base.stiffness = {4e4, 1e4};
  base.threshold = {2e-6, 3e-5};
  const friction::DerivativeWindows windows = friction::record_derivative_windows(time, x);
  auto run = [&] {
    Extended<MaxwellSlip<double>> model(MaxwellSlip<double>(base), p);
    return friction::simulate_extended(model, std::span<const double>(time),
                                       std::span<const double>(x), {}, &windows);
  };
  auto uncached = [&] {
    const friction::detail::UncachedSteps keep_out;
    return run();
  };
  const std::vector<double> first = run();  // fills the cache
  ASSERT_TRUE(friction::detail::filtered_displacement().valid);
  ASSERT_EQ(run(), first);  // and reads it
  const std::size_t k = 1234;
  const double x_k = x[k], time_k = time[k];
  x[k] += 1e-9;  // a nanometre at one sample
  const std::vector<double> moved = run();
  EXPECT_EQ(moved, uncached()) << "a changed displacement sample read the old filter";
  EXPECT_NE(moved, first);
  x[k] = x_k;
  time[k] += 1e-7;  // a tenth of a microsecond at one stamp
  const std::vector<double> shifted = run();
  EXPECT_EQ(shifted, uncached()) << "a changed time stamp read the old filter";
  EXPECT_NE(shifted, first);
  time[k] = time_k;
  EXPECT_EQ(run(), first);
}

}  // namespace
}  // namespace test_extensions
