// The sandwich covariance for AR(1) residuals (noise_colour.hpp) against Monte Carlo: a linear
// least-squares problem with a slowly varying and a fast regressor, noise white or AR(1) with phi
// up to 0.95, 2000 repetitions; the predicted standard errors must match the spread of the
// estimates and the 95 % intervals must cover 95 % of the time, where the white formula covers far
// less.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <random>
#include <vector>

#include "friction/noise_colour.hpp"

namespace friction::testing {
namespace test_noise_colour {
namespace {

TEST(NoiseColour, LagCorrelationsOfAnAr1Series) {
  std::mt19937_64 gen(11);
  std::normal_distribution<double> w(0, 1);
  std::vector<double> e(50000);
  double x = 0;
  for (double& v : e) v = x = 0.7 * x + w(gen);
  const ResidualColour c = residual_colour(e);
  EXPECT_NEAR(c.lag_one, 0.7, 0.02);
  EXPECT_NEAR(c.lag_two, 0.49, 0.03);
  EXPECT_TRUE(c.ar1_adequate);
  // An AR(2) with the same lag-one correlation is recognised as not AR(1).
  double x1 = 0, x2 = 0;
  for (double& v : e) {
    v = 1.2 * x1 - 0.7 * x2 + w(gen);
    x2 = x1;
    x1 = v;
  }
  EXPECT_FALSE(residual_colour(e).ar1_adequate);
}

TEST(NoiseColour, SandwichMatchesTheSpreadOfEstimates) {
  const std::size_t n = 2000, reps = 2000;
  Eigen::MatrixXd j(n, 2);
  for (std::size_t t = 0; t < n; ++t) {
    const double s = static_cast<double>(t) / static_cast<double>(n);
    j(static_cast<Eigen::Index>(t), 0) = std::sin(2 * M_PI * 3 * s);    // slow
    j(static_cast<Eigen::Index>(t), 1) = std::sin(2 * M_PI * 400 * s);  // fast (5 samples)
  }
  const Eigen::MatrixXd jtj_inv = (j.transpose() * j).inverse();
  for (double phi : {0.0, 0.5, 0.9, 0.95}) {
    std::mt19937_64 gen(1234 + static_cast<unsigned>(phi * 100));
    std::normal_distribution<double> w(0, 1);
    std::vector<Eigen::Vector2d> estimates;
    Eigen::Vector2d mean_se = Eigen::Vector2d::Zero(), mean_white = Eigen::Vector2d::Zero();
    int covered[2] = {0, 0}, covered_white[2] = {0, 0};
    for (std::size_t r = 0; r < reps; ++r) {
      Eigen::VectorXd e(n);
      double x = w(gen) / std::sqrt(1 - phi * phi);
      for (std::size_t t = 0; t < n; ++t) e[static_cast<Eigen::Index>(t)] = x = phi * x + w(gen);
      const Eigen::Vector2d beta = jtj_inv * j.transpose() * e;  // true beta = 0
      const Eigen::VectorXd res = e - j * beta;
      std::vector<double> rv(res.data(), res.data() + n);
      const ResidualColour c = residual_colour(rv);
      ColouredGram g(2, c.phi);
      for (std::size_t t = 0; t < n; ++t)
        g.add(std::span<const double>(std::vector<double>{j(static_cast<Eigen::Index>(t), 0),
                                                          j(static_cast<Eigen::Index>(t), 1)}));
      const double s2 = res.squaredNorm() / static_cast<double>(n - 2);
      const Eigen::MatrixXd cov = sandwich_covariance(jtj_inv, g.coloured(), s2);
      for (int i = 0; i < 2; ++i) {
        const double se = std::sqrt(cov(i, i)), white = std::sqrt(s2 * jtj_inv(i, i));
        mean_se[i] += se / reps;
        mean_white[i] += white / reps;
        covered[i] += std::abs(beta[i]) <= 1.96 * se;
        covered_white[i] += std::abs(beta[i]) <= 1.96 * white;
      }
      estimates.push_back(beta);
    }
    for (int i = 0; i < 2; ++i) {
      double var = 0;
      for (const auto& b : estimates) var += b[i] * b[i] / reps;
      SCOPED_TRACE("phi " + std::to_string(phi) + " parameter " + std::to_string(i));
      EXPECT_NEAR(mean_se[i] / std::sqrt(var), 1.0, 0.08);
      EXPECT_NEAR(covered[i] / double(reps), 0.95, 0.02);
      if (phi >= 0.9 && i == 0) {
        EXPECT_LT(covered_white[i] / double(reps), 0.6);
      }
    }
  }
}

}  // namespace
}  // namespace test_noise_colour
}  // namespace friction::testing
