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
#include <vector>

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
// pieces approximate, an encoder's staircase seen through the stiffnesses), which repeats with the
// motion and leaks into the parameters: on the discovery study's records the AR(1) intervals of the
// pieces' parameters covered their truth 61-65 % of the time (|z| of 3-16 for delays, wavelengths,
// viscous terms).  The batch-means (cluster) sandwich makes no model of the residual: the record is
// cut into B consecutive blocks and
//     C_block = (J^T J)^-1 (sum_b s_b s_b^T) (J^T J)^-1 * B/(B-1) * (N-1)/(N-r),   s_b = J_b^T e_b,
// the score of block b (r the rank of the fit; the factors are the usual small-sample ones).
// What the residual shares with a parameter's sensitivity, noise or misfit, shows in how the block
// scores scatter, provided that the blocks are long against the correlation of the scores: shorter
// blocks split one correlated stretch into several "independent" ones and the variance comes out
// too small.  That correlation is not the noise's: an encoder's error near one reversal is one
// misfit for the whole stroke (hundreds of samples), while the residual's lag-one correlation sees
// the noise.  So the blocks are doubled in turn, the blocking method of Flyvbjerg and Petersen:
// base blocks of max(floor(sqrt N), 5 tau) samples (tau = (1+phi)/(1-phi), the AR(1) integrated
// time; sqrt N the usual batch-means rate), then 2, 4, ... of them merged, as long as at least 10
// blocks remain (the estimate's relative error is about sqrt(2/B)).  The variance grows with the
// block length until the blocks outlast the correlation and then levels off; each parameter's is
// the largest over the lengths (a plateau read from above, so somewhat conservative: on white noise
// test_noise_colour measures mean standard errors 1.08-1.11 times the spread of the estimates).
// Where a misfit lasts a stroke of 200 samples the 95 % intervals covered 76 % of the time with
// blocks of one length and 88 % with the doubling (same test); on the discovery study at seed
// 3012241078514469427 the pieces' coverage went from 71 % to 76 %.  Each parameter's standard
// error is then the larger of that and the AR(1) sandwich's; the correlations are the AR(1)
// sandwich's (larger_variances).

/// Base block length of the block scores for a residual of N samples and colour c (above).
std::size_t score_block_length(std::size_t n, const ResidualColour& c);

/// Accumulates the score s_b = J_b^T e_b of each base block of `block_length` consecutive rows
/// (time order): sqrt(N) p-vectors, so memory stays O(sqrt(N) p).
class BlockScores {
 public:
  BlockScores(std::size_t parameters, std::size_t block_length);
  /// Adds the Jacobian row and residual of the next sample.
  void add(std::span<const double> row, double residual);
  /// sum_b s_b s_b^T over blocks of `merge` consecutive base blocks, the last (partial) one
  /// included.
  Eigen::MatrixXd meat(std::size_t merge = 1) const;
  /// B, the blocks of `merge` base blocks, the partial one included.
  std::size_t blocks(std::size_t merge = 1) const;
  /// The block scores of rows that hold only `columns` of these, each times its `scale`, as if
  /// those rows had been added (a score is linear in its rows); the other columns are not read.
  BlockScores selected(const std::vector<Eigen::Index>& columns,
                       const Eigen::VectorXd& scale) const;

 private:
  std::size_t length_, in_block_ = 0;
  Eigen::VectorXd score_;
  std::vector<Eigen::VectorXd> done_;  // the scores of the complete base blocks
};

/// The fewest blocks the block scores are used with.
inline constexpr std::size_t kMinimumScoreBlocks = 10;

/// C_block at every block length of the doubling (above) with at least kMinimumScoreBlocks
/// blocks, each variance the largest of them; `rank` is the fit's rank.
Eigen::MatrixXd block_sandwich_covariance(const Eigen::MatrixXd& gram_inverse,
                                          const BlockScores& scores, std::size_t n,
                                          std::size_t rank);

/// The covariance with each variance the larger of `model`'s and `robust`'s and the correlations
/// of `model` (S R S: positive semi-definite as R is).
Eigen::MatrixXd larger_variances(const Eigen::MatrixXd& model, const Eigen::MatrixXd& robust);

}  // namespace friction
