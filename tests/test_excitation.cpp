// The excitations do what an identification experiment needs of them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "friction/error.hpp"
#include "friction/excitation.hpp"

namespace test_excitation {
namespace {

using friction::ExcitationKind;
using friction::ExcitationOptions;

std::vector<double> velocity(const friction::Signal& s) {
  std::vector<double> v;
  for (std::size_t k = 1; k < s.time.size(); ++k)
    v.push_back((s.displacement[k] - s.displacement[k - 1]) / (s.time[k] - s.time[k - 1]));
  return v;
}

// Displacements at which the velocity changes sign.
std::vector<double> reversal_points(const friction::Signal& s) {
  std::vector<double> points;
  const auto v = velocity(s);
  double last_sign = 0;
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (std::abs(v[k]) < 1e-12) continue;
    const double sign = v[k] > 0 ? 1 : -1;
    if (last_sign != 0 && sign != last_sign) points.push_back(s.displacement[k]);
    last_sign = sign;
  }
  return points;
}

TEST(Excitation, SampledAtTheRequestedRate) {
  ExcitationOptions o;
  o.rate = 2500;
  for (auto kind : {ExcitationKind::Presliding, ExcitationKind::Strokes, ExcitationKind::Multisine,
                    ExcitationKind::Combined}) {
    o.kind = kind;
    const auto s = friction::make_excitation(o);
    ASSERT_GT(s.time.size(), 100u) << friction::to_string(kind);
    for (std::size_t k = 1; k < s.time.size(); ++k)
      ASSERT_NEAR(s.time[k] - s.time[k - 1], 1.0 / o.rate, 1e-12);
    EXPECT_EQ(s.displacement.front(), 0.0);
  }
}

TEST(Excitation, PreslidingReversalsNestAndShrink) {
  ExcitationOptions o;
  o.kind = ExcitationKind::Presliding;
  const auto s = friction::make_excitation(o);
  const auto r = reversal_points(s);
  // One reversal ends the initial slide, then 2 per cycle of the loops.
  ASSERT_GE(r.size(), static_cast<std::size_t>(2 * o.presliding_cycles));
  const double centre = 0.5 * o.stroke;
  for (std::size_t i = 2; i < r.size(); ++i) {
    EXPECT_LT(std::abs(r[i] - centre), std::abs(r[i - 1] - centre)) << "reversal " << i;
    EXPECT_LT(std::abs(r[i] - centre), std::abs(r[i - 2] - centre)) << "reversal " << i;
  }
  EXPECT_LE(std::abs(r[1] - centre), o.presliding_amplitude * (1 + 1e-9));
}

TEST(Excitation, StrokesCruiseAtEverySpeedInBothDirections) {
  ExcitationOptions o;
  o.kind = ExcitationKind::Strokes;
  const auto s = friction::make_excitation(o);
  const auto v = velocity(s);
  for (double speed : o.speeds) {
    const auto count = [&](double sign) {
      return std::count_if(v.begin(), v.end(),
                           [&](double u) { return std::abs(u - sign * speed) < 1e-6 * speed; });
    };
    EXPECT_GT(count(+1), 5) << "speed " << speed;
    EXPECT_GT(count(-1), 5) << "speed " << speed;
  }
  const auto [lo, hi] = std::minmax_element(s.displacement.begin(), s.displacement.end());
  EXPECT_NEAR(*hi - *lo, o.stroke, 1e-3 * o.stroke);
}

TEST(Excitation, MultisineHasTheRequestedPeakAndDependsOnTheSeed) {
  ExcitationOptions o;
  o.kind = ExcitationKind::Multisine;
  const auto a = friction::make_excitation(o);
  const auto b = friction::make_excitation(o);
  EXPECT_EQ(a.displacement, b.displacement);
  o.seed = 2;
  const auto c = friction::make_excitation(o);
  EXPECT_NE(a.displacement, c.displacement);
  double peak = 0;
  for (double x : a.displacement) peak = std::max(peak, std::abs(x));
  EXPECT_LE(peak, o.multisine_amplitude * 1.001);
  EXPECT_GT(peak, o.multisine_amplitude * 0.5);
  EXPECT_NEAR(a.time.back(), o.multisine_duration, 2.0 / o.rate);
}

TEST(Excitation, WhiteNoiseHasTheRequestedDeviationAndIsReproducible) {
  std::vector<double> a(20000, 1.0), b(20000, 1.0);
  friction::NormalSource s1(7), s2(7);
  friction::add_white_noise(a, 0.01, s1);
  friction::add_white_noise(b, 0.01, s2);
  EXPECT_EQ(a, b);
  const double mean = std::accumulate(a.begin(), a.end(), 0.0) / a.size();
  double var = 0;
  for (double x : a) var += (x - mean) * (x - mean);
  const double sd = std::sqrt(var / (a.size() - 1));
  // The sample s.d. of n normal deviates has relative s.e. 1/sqrt(2n) = 0.5 %; allow 4 of them.
  EXPECT_NEAR(sd, 0.01, 0.01 * 4 / std::sqrt(2.0 * a.size()));
  EXPECT_NEAR(mean, 1.0, 4 * 0.01 / std::sqrt(a.size()));
}

TEST(Excitation, QuantiseRoundsToTheResolution) {
  std::vector<double> x{0.0, 0.4e-6, 0.6e-6, -1.4e-6, 2.5001e-6};
  friction::quantise(x, 1e-6);
  const std::vector<double> expected{0.0, 0.0, 1e-6, -1e-6, 3e-6};
  for (std::size_t i = 0; i < x.size(); ++i) EXPECT_DOUBLE_EQ(x[i], expected[i]);
  EXPECT_THROW(friction::quantise(x, -1.0), friction::InvalidParameter);
}

TEST(Excitation, RejectsBadOptions) {
  ExcitationOptions o;
  o.rate = 0;
  EXPECT_THROW(friction::make_excitation(o), friction::InvalidParameter);
  o = {};
  o.speeds = {};
  EXPECT_THROW(friction::make_excitation(o), friction::InvalidParameter);
  o = {};
  o.presliding_decay = 1.0;
  EXPECT_THROW(friction::make_excitation(o), friction::InvalidParameter);
  EXPECT_THROW(friction::parse_excitation_kind("chirp"), friction::InvalidParameter);
}

}  // namespace
}  // namespace test_excitation
