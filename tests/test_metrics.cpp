// Error metrics and the white-noise estimate, on hand-computed cases.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "friction/metrics.hpp"

namespace test_metrics {
namespace {

using friction::compute_errors;
using friction::estimate_white_noise_sigma;
using friction::noise_floor_rss_sss_percent;

TEST(Metrics, HandComputedCase) {
  const std::vector<double> measured{1.0, -2.0, 3.0};
  const std::vector<double> simulated{1.5, -2.0, 2.0};
  const auto m = compute_errors(measured, simulated);
  // e = (-0.5, 0, 1): RSS 1.25, SSS 14, mean F 2/3, sum (F - mean)^2 = 114/9.
  EXPECT_DOUBLE_EQ(m.rss, 1.25);
  EXPECT_NEAR(m.rss_sss_percent, 100.0 * 1.25 / 14.0, 1e-12);
  EXPECT_NEAR(m.rms, std::sqrt(1.25 / 3.0), 1e-15);
  EXPECT_DOUBLE_EQ(m.max_abs, 1.0);
  EXPECT_NEAR(m.r_squared, 1.0 - 1.25 * 9.0 / 114.0, 1e-15);
  EXPECT_EQ(m.samples, 3u);
}

TEST(Metrics, PerfectFitAndSignOfTheError) {
  const std::vector<double> f{0.2, -0.1, 0.4, 0.0};
  const auto perfect = compute_errors(f, f);
  EXPECT_EQ(perfect.rss_sss_percent, 0.0);
  EXPECT_EQ(perfect.r_squared, 1.0);
  // A model that predicts zero has RSS/SSS of exactly 100 %, whatever the force.
  const auto zero = compute_errors(f, std::vector<double>(4, 0.0));
  EXPECT_NEAR(zero.rss_sss_percent, 100.0, 1e-12);
  // Swapping measured and simulated changes RSS/SSS (it is normalised by the measured force).
  const std::vector<double> g{0.1, -0.1, 0.3, 0.1};
  EXPECT_NE(compute_errors(f, g).rss_sss_percent, compute_errors(g, f).rss_sss_percent);
}

TEST(Metrics, RejectsUnusableInput) {
  const std::vector<double> a{1.0, 2.0}, b{1.0};
  EXPECT_THROW(compute_errors(a, b), friction::InvalidParameter);
  EXPECT_THROW(compute_errors(std::vector<double>(3, 0.0), std::vector<double>(3, 1.0)),
               friction::InvalidParameter);
  EXPECT_THROW(compute_errors(std::vector<double>{}, std::vector<double>{}),
               friction::InvalidParameter);
}

TEST(Metrics, NoiseFloorFormula) {
  const std::vector<double> f{1.0, -1.0, 2.0, 0.0};  // sum F^2 = 6
  EXPECT_NEAR(noise_floor_rss_sss_percent(f, 0.1), 100.0 * 4 * 0.01 / 6.0, 1e-12);
}

TEST(Metrics, WhiteNoiseSigmaOnSmoothAndKinkedSignals) {
  std::mt19937 gen(3);
  const double sigma = 0.01;
  std::normal_distribution<double> noise(0.0, sigma);
  const std::size_t n = 20000;
  std::vector<double> smooth(n), kinked(n), clean(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / static_cast<double>(n);
    smooth[k] = std::sin(2 * M_PI * 5 * t) + noise(gen);
    // Hysteresis-like: a clipped ramp with reversals (kinks every few hundred samples).
    const double tri = std::abs(std::fmod(40 * t, 2.0) - 1.0);
    clean[k] = std::clamp(3.0 * tri - 1.5, -1.0, 1.0);
    kinked[k] = clean[k] + noise(gen);
  }
  EXPECT_NEAR(estimate_white_noise_sigma(smooth), sigma, 0.05 * sigma);
  EXPECT_NEAR(estimate_white_noise_sigma(kinked), sigma, 0.05 * sigma);
  EXPECT_LT(estimate_white_noise_sigma(clean), 1e-3 * sigma);  // no noise, no estimate
  EXPECT_EQ(estimate_white_noise_sigma(std::vector<double>{1.0, 2.0}), 0.0);
}

}  // namespace
}  // namespace test_metrics
