// The sandwich covariance for AR(1) residuals and the block scores (noise_colour.hpp) against
// Monte Carlo: a linear least-squares problem with a slowly varying and a fast regressor, noise
// white or AR(1) with phi up to 0.95, or noise whose size follows the regressors, 2000 repetitions;
// the predicted standard errors must match the spread of the estimates and the 95 % intervals must
// cover 95 % of the time, where the white formula (or the AR(1) one) covers less.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <cstdio>
#include <limits>
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

// The regressors of the Monte-Carlo tests: a slow sinusoid (3 cycles over the record) and a fast
// one (`fast_cycles`).
Eigen::MatrixXd slow_and_fast_regressors(std::size_t n, double fast_cycles) {
  Eigen::MatrixXd j(n, 2);
  for (std::size_t t = 0; t < n; ++t) {
    const double s = static_cast<double>(t) / static_cast<double>(n);
    j(static_cast<Eigen::Index>(t), 0) = std::sin(2 * M_PI * 3 * s);
    j(static_cast<Eigen::Index>(t), 1) = std::sin(2 * M_PI * fast_cycles * s);
  }
  return j;
}

TEST(NoiseColour, SandwichMatchesTheSpreadOfEstimates) {
  const std::size_t n = 2000, reps = 2000;
  const Eigen::MatrixXd j = slow_and_fast_regressors(n, 400);  // fast: a period of 5 samples
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

// A residual the AR(1) model does not describe: noise whose size follows the regressors (as a
// friction model's misfit grows where the motion reverses), coloured.  The model-based sandwich
// then misjudges the spread of the estimates; the block scores do not, and the larger of the two
// (what covariance_at reports) covers 95 % of the time.  On white noise of constant size the
// larger of the two covers about as the AR(1) sandwich alone does.
TEST(NoiseColour, BlockScoresCoverWhenTheResidualFollowsTheRegressors) {
  const std::size_t n = 2000, reps = 2000;
  const Eigen::MatrixXd j = slow_and_fast_regressors(n, 170);  // fast: a period of 12 samples
  const Eigen::MatrixXd jtj_inv = (j.transpose() * j).inverse();
  for (const bool follows : {true, false}) {
    std::mt19937_64 gen(follows ? 90210 : 90211);
    std::normal_distribution<double> w(0, 1);
    const double phi = 0.5;
    std::vector<Eigen::Vector2d> estimates;
    Eigen::Vector2d mean_se = Eigen::Vector2d::Zero();
    int covered[2] = {0, 0}, covered_model[2] = {0, 0};
    for (std::size_t r = 0; r < reps; ++r) {
      Eigen::VectorXd e(n);
      double x = w(gen) / std::sqrt(1 - phi * phi);
      for (std::size_t t = 0; t < n; ++t) {
        x = phi * x + w(gen);
        const auto k = static_cast<Eigen::Index>(t);
        // Size (|j0| + |j1|)^2: large where either regressor is, as misfit is at reversals.
        const double size = std::abs(j(k, 0)) + std::abs(j(k, 1));
        e[k] = follows ? x * size * size : x;
      }
      const Eigen::Vector2d beta = jtj_inv * j.transpose() * e;  // true beta = 0
      const Eigen::VectorXd res = e - j * beta;
      std::vector<double> rv(res.data(), res.data() + n);
      const ResidualColour c = residual_colour(rv);
      ColouredGram g(2, c.phi);
      BlockScores scores(2, score_block_length(n, c));
      for (std::size_t t = 0; t < n; ++t) {
        const auto k = static_cast<Eigen::Index>(t);
        const std::vector<double> row{j(k, 0), j(k, 1)};
        g.add(row);
        scores.add(row, res[k]);
      }
      ASSERT_GE(scores.blocks(), kMinimumScoreBlocks);
      const double s2 = res.squaredNorm() / static_cast<double>(n - 2);
      const Eigen::MatrixXd model = sandwich_covariance(jtj_inv, g.coloured(), s2);
      const Eigen::MatrixXd cov =
          larger_variances(model, block_sandwich_covariance(jtj_inv, scores, n, 2));
      for (int i = 0; i < 2; ++i) {
        const double se = std::sqrt(cov(i, i));
        mean_se[i] += se / reps;
        covered[i] += std::abs(beta[i]) <= 1.96 * se;
        covered_model[i] += std::abs(beta[i]) <= 1.96 * std::sqrt(model(i, i));
      }
      estimates.push_back(beta);
    }
    for (int i = 0; i < 2; ++i) {
      double var = 0;
      for (const auto& b : estimates) var += b[i] * b[i] / reps;
      SCOPED_TRACE(std::string(follows ? "noise following the regressors" : "white noise") +
                   ", parameter " + std::to_string(i));
      const double coverage = covered[i] / double(reps);
      const double model_coverage = covered_model[i] / double(reps);
      std::printf(
          "%s, parameter %d: coverage %.3f (AR(1) sandwich alone %.3f), mean s.e. / spread "
          "%.3f\n",
          follows ? "noise following the regressors" : "white noise", i, coverage, model_coverage,
          mean_se[i] / std::sqrt(var));
      EXPECT_GE(mean_se[i] / std::sqrt(var), 0.95);
      EXPECT_LE(mean_se[i] / std::sqrt(var), 1.15);
      // About 45 blocks: the block variance is itself uncertain by about sqrt(2/45), which costs
      // a point of coverage against the spread-matched 95 %.
      EXPECT_GE(coverage, 0.925);
      EXPECT_LE(coverage, 0.975);
      if (follows) {
        EXPECT_LT(model_coverage, 0.91);
      }
    }
  }
}

// Misfit correlated over far more samples than a base block: a random error per "stroke" of 200
// samples (an encoder's reversal, a presliding curve of another shape, seen for a whole stroke),
// against base blocks of max(sqrt(N), 5 tau) = 120 samples (the strokes make the residual's lag-one
// correlation about 0.92).  Blocks of one length split each stroke into two "independent" pieces
// and the variance comes out too small: 95 % intervals covered 76 % of the time.  The doubled
// blocks (240 samples, 17 of them) outlast the correlation and covered 88 % (an estimate from 17
// blocks scatters by about a third, and blocks only somewhat longer than the strokes still share
// some of them): not the nominal 95 %, and the 85 % is what is asserted.
TEST(NoiseColour, DoubledBlocksCoverMisfitCorrelatedOverAStroke) {
  const std::size_t n = 4000, reps = 2000, stroke = 200;
  const Eigen::MatrixXd j = slow_and_fast_regressors(n, 170);
  const Eigen::MatrixXd jtj_inv = (j.transpose() * j).inverse();
  std::mt19937_64 gen(4717);
  std::normal_distribution<double> w(0, 1);
  std::vector<Eigen::Vector2d> estimates;
  int covered[2] = {0, 0}, covered_one_length[2] = {0, 0};
  for (std::size_t r = 0; r < reps; ++r) {
    Eigen::VectorXd e(n);
    double u = 0;
    for (std::size_t t = 0; t < n; ++t) {
      if (t % stroke == 0) u = w(gen);
      e[static_cast<Eigen::Index>(t)] = u + 0.3 * w(gen);
    }
    const Eigen::Vector2d beta = jtj_inv * j.transpose() * e;  // true beta = 0
    const Eigen::VectorXd res = e - j * beta;
    std::vector<double> rv(res.data(), res.data() + n);
    const ResidualColour c = residual_colour(rv);
    BlockScores scores(2, score_block_length(n, c));
    for (std::size_t t = 0; t < n; ++t) {
      const auto k = static_cast<Eigen::Index>(t);
      scores.add(std::vector<double>{j(k, 0), j(k, 1)}, res[k]);
    }
    ASSERT_GE(scores.blocks(2), kMinimumScoreBlocks);
    const Eigen::MatrixXd cov = block_sandwich_covariance(jtj_inv, scores, n, 2);
    const double b = static_cast<double>(scores.blocks());
    const Eigen::MatrixXd one_length =
        b / (b - 1) * (n - 1.0) / (n - 2.0) * jtj_inv * scores.meat() * jtj_inv;
    for (int i = 0; i < 2; ++i) {
      covered[i] += std::abs(beta[i]) <= 1.96 * std::sqrt(cov(i, i));
      covered_one_length[i] += std::abs(beta[i]) <= 1.96 * std::sqrt(one_length(i, i));
    }
    estimates.push_back(beta);
  }
  // The slow regressor (three cycles) keeps the strokes' errors; the fast one averages them out
  // within each stroke and is covered either way.
  const double coverage = covered[0] / double(reps);
  const double one_length_coverage = covered_one_length[0] / double(reps);
  std::printf(
      "misfit over strokes, slow parameter: coverage %.3f (blocks of one length %.3f), "
      "fast parameter %.3f\n",
      coverage, one_length_coverage, covered[1] / double(reps));
  EXPECT_LT(one_length_coverage, 0.8);
  EXPECT_GE(coverage, 0.85);
  EXPECT_LE(coverage, 0.99);
  EXPECT_GE(covered[1] / double(reps), 0.9);
}

TEST(NoiseColour, LargerVariancesKeepTheModelsCorrelations) {
  Eigen::Matrix2d model, robust;
  model << 4, 1.2, 1.2, 1;  // correlation 0.6
  robust << 1, -0.5, -0.5, 9;
  const Eigen::MatrixXd c = larger_variances(model, robust);
  EXPECT_DOUBLE_EQ(c(0, 0), 4);
  EXPECT_DOUBLE_EQ(c(1, 1), 9);
  EXPECT_NEAR(c(0, 1) / std::sqrt(c(0, 0) * c(1, 1)), 0.6, 1e-12);
  EXPECT_DOUBLE_EQ(c(0, 1), c(1, 0));
}

// covariance_at gathers the block scores and the coloured Gram matrix on every column of the
// Jacobian, unscaled, and takes them to the chosen columns, scaled, afterwards: the result must be
// that of those rows added directly, to rounding, including the partial last block, and a column
// left out must not be read (it may hold non-finite derivatives).
TEST(NoiseColour, ScoresAndColouredGramOfChosenScaledColumnsAsIfAddedSo) {
  std::mt19937_64 gen(29);
  std::normal_distribution<double> w(0, 1);
  const std::size_t n = 1037, p = 5;
  const std::vector<Eigen::Index> columns{4, 0, 2};
  Eigen::VectorXd scale(3);
  scale << 1.0 / 3.0, 7.5, 1e-3;
  BlockScores all(p, 40), direct(3, 40);
  ColouredGram all_gram(p, 0.6), direct_gram(3, 0.6);
  for (std::size_t k = 0; k < n; ++k) {
    Eigen::VectorXd row(p);
    for (Eigen::Index j = 0; j < row.size(); ++j) row(j) = w(gen) * std::pow(10.0, double(j) - 2);
    if (k % 97 == 5) row(3) = std::numeric_limits<double>::quiet_NaN();  // a column left out
    const double e = w(gen);
    Eigen::VectorXd chosen(3);
    for (Eigen::Index q = 0; q < 3; ++q) chosen(q) = scale(q) * row(columns[std::size_t(q)]);
    all.add(std::span<const double>(row.data(), p), e);
    all_gram.add(std::span<const double>(row.data(), p));
    direct.add(std::span<const double>(chosen.data(), 3), e);
    direct_gram.add(std::span<const double>(chosen.data(), 3));
  }
  const BlockScores moved = all.selected(columns, scale);
  ASSERT_EQ(moved.blocks(), direct.blocks());
  EXPECT_EQ(moved.blocks(), (n + 39) / 40);
  for (std::size_t merge : {1u, 2u, 4u}) {
    const Eigen::MatrixXd a = moved.meat(merge), b = direct.meat(merge);
    ASSERT_TRUE(a.allFinite()) << "merge " << merge << ": a column left out was read";
    EXPECT_LE((a - b).norm(), 1e-12 * b.norm()) << "merge " << merge;
  }
  // The Gram matrices taken to the chosen columns the way covariance_at takes them.
  const auto chosen = [&](const Eigen::MatrixXd& m) {
    Eigen::MatrixXd out(3, 3);
    for (Eigen::Index q = 0; q < 3; ++q)
      for (Eigen::Index u = 0; u < 3; ++u)
        out(q, u) = scale(q) * m(columns[std::size_t(q)], columns[std::size_t(u)]) * scale(u);
    return out;
  };
  for (const auto& [a, b] : {std::pair{chosen(all_gram.coloured()), direct_gram.coloured()},
                             std::pair{chosen(all_gram.gram()), direct_gram.gram()}}) {
    ASSERT_TRUE(a.allFinite());
    EXPECT_LE((a - b).norm(), 1e-12 * b.norm());
  }
}

}  // namespace
}  // namespace test_noise_colour
}  // namespace friction::testing
