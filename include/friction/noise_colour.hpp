// Standard errors when the residual is not white: the sandwich covariance for AR(1) residuals.
//
// The Gauss-Newton covariance s^2 (J^T J)^-1 assumes independent residuals.  Measured forces carry
// coloured noise (a filtered load cell, a drive's current loop, electrical pickup), and a fit's
// residual also holds slow misfit.  With residual autocorrelation rho(l) the least-squares
// estimate's covariance is the sandwich
//     C = (J^T J)^-1 (J^T Omega J) (J^T J)^-1,   Omega_ts = s^2 rho(t - s),
// which for a parameter whose sensitivity varies slowly is s^2 (J^T J)^-1 times
// 1 + 2 sum_l rho(l) (= (1 + phi)/(1 - phi) for AR(1): 39 at phi = 0.95, i.e. standard errors 6.2
// times the white ones): the "effective N" N (1 - phi)/(1 + phi).  For a sensitivity that changes
// faster than the noise (an acceleration's, a reversal's) the inflation is smaller, which is why
// the sandwich is used rather than one factor for every parameter.
//
// The residual is modelled as AR(1), e_t = phi e_{t-1} + w_t, with phi its lag-one
// autocorrelation; then rho(l) = phi^|l| and
//     J^T Omega J / s^2 = sum_t (J_t G_t^T + G_t J_t^T - J_t J_t^T),   G_t = J_t + phi G_{t-1},
// one forward pass with one p-vector of state: no N x p matrix is kept, so the cost and memory
// stay linear in N (a record of 10^6 samples needs the same p^2 accumulators as one of 10^3).
// AR(1) is the lowest-order model of colour; `residual_colour` also reports the lag-two
// correlation, and where it departs from phi^2 by more than its sampling error the caller warns
// that the intervals rest on that approximation.  phi is clamped to [0, 0.99]: a negative lag-one
// correlation (noise differentiated somewhere upstream) would shrink the intervals below the white
// ones, which the data do not justify, and phi -> 1 is a trend, not noise.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <span>

namespace friction {

/// Lag-one and lag-two autocorrelation of a residual, and the AR(1) coefficient used.
struct ResidualColour {
  double lag_one = 0;  ///< rho(1)
  double lag_two = 0;  ///< rho(2)
  double phi = 0;      ///< clamp(rho(1), 0, 0.99)
  /// rho(2) departs from phi^2 by more than 3 standard errors (sqrt(1/N) scale): AR(1) is only an
  /// approximation of this residual's colour.
  bool ar1_adequate = true;
  /// (1 + phi)/(1 - phi): the variance inflation of a slowly varying sensitivity.
  double slow_inflation() const { return (1 + phi) / (1 - phi); }
};

ResidualColour residual_colour(std::span<const double> residual);

/// Accumulates J^T J and J^T R J (R the AR(1) correlation matrix) row by row.
class ColouredGram {
 public:
  ColouredGram(std::size_t parameters, double phi);
  /// Adds the Jacobian row of the next sample (rows in time order).
  void add(std::span<const double> row);
  const Eigen::MatrixXd& gram() const { return gram_; }  ///< J^T J
  Eigen::MatrixXd coloured() const;                      ///< J^T R J (symmetric)

 private:
  double phi_;
  Eigen::VectorXd g_;
  Eigen::MatrixXd gram_, cross_;  // sum J J^T, sum J G^T
};

/// The sandwich covariance s^2 (J^T J)^-1 (J^T R J) (J^T J)^-1 from the accumulators, where
/// (J^T J)^-1 is the caller's (pseudo-)inverse of gram().
Eigen::MatrixXd sandwich_covariance(const Eigen::MatrixXd& gram_inverse,
                                    const Eigen::MatrixXd& coloured, double residual_variance);

// Misfit as well as noise: block scores.
//
// The AR(1) sandwich models the residual as stationary noise.  A fitted friction model's residual
// also holds what its structure misses (a presliding curve of another shape, a level that the
// pieces approximate), which repeats with the motion and leaks into the parameters: on the
// discovery study's records the AR(1) intervals of the pieces' parameters covered their truth
// 61-65 % of the time (|z| of 3-16 for delays, wavelengths, viscous terms).  The batch-means (cluster)
// sandwich makes no model of the residual: the record is cut into B consecutive blocks and
//     C_block = (J^T J)^-1 (sum_b s_b s_b^T) (J^T J)^-1 * B/(B-1) * (N-1)/(N-r),   s_b = J_b^T e_b,
// the score of block b (r the rank of the fit; the factors are the usual small-sample ones).
// What the residual shares with a parameter's sensitivity, noise or misfit, shows in how the block
// scores scatter.  Blocks must be long against the residual's correlation (the AR(1) integrated
// time tau = (1+phi)/(1-phi): with blocks of 5 tau the variance is biased low by about a tenth)
// and many (the estimate's relative error is about sqrt(2/B)): length max(floor(sqrt N), 5 tau),
// the usual batch-means rate, and not used below 10 blocks.  Each parameter's standard error is the
// larger of the two; the correlations are the AR(1) sandwich's (larger_variances).

/// Block length of the block scores for a residual of N samples and colour c (above).
std::size_t score_block_length(std::size_t n, const ResidualColour& c);

/// Accumulates sum_b s_b s_b^T over consecutive blocks of `block_length` rows (time order).
class BlockScores {
 public:
  BlockScores(std::size_t parameters, std::size_t block_length);
  /// Adds the Jacobian row and residual of the next sample.
  void add(std::span<const double> row, double residual);
  Eigen::MatrixXd meat() const;  ///< sum_b s_b s_b^T, the last (partial) block included
  std::size_t blocks() const;    ///< B, the partial block included

 private:
  std::size_t length_, in_block_ = 0, blocks_ = 0;
  Eigen::VectorXd score_;
  Eigen::MatrixXd meat_;
};

/// The fewest blocks the block scores are used with.
inline constexpr std::size_t kMinimumScoreBlocks = 10;

/// C_block from the accumulated scores (above); `rank` is the fit's rank.
Eigen::MatrixXd block_sandwich_covariance(const Eigen::MatrixXd& gram_inverse,
                                          const BlockScores& scores, std::size_t n,
                                          std::size_t rank);

/// The covariance with each variance the larger of `model`'s and `robust`'s and the correlations
/// of `model` (S R S: positive semi-definite as R is).
Eigen::MatrixXd larger_variances(const Eigen::MatrixXd& model, const Eigen::MatrixXd& robust);

}  // namespace friction
