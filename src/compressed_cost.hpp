// A least-squares problem of N residuals handed to Ceres as P + 1 (not installed).
//
// Levenberg-Marquardt sees the residuals r (N) and their Jacobian J (N x P) only through
// J^T J, J^T r and r^T r: the step solves (J^T J + mu D) h = -J^T r, the model's predicted
// decrease is -h^T J^T r - h^T J^T J h / 2, the Jacobi scaling uses sqrt(diag J^T J), the gradient
// and the projected gradient of the bounds are J^T r, and the cost is r^T r / 2.  Any F
// ((P+1) x (P+1)) with F^T F = [J r]^T [J r] therefore stands for them: its first P columns for J,
// its last column for r, and Ceres takes the same steps on it as on the N-row problem.  What it no
// longer does per iteration is the O(N P^2) QR of J, the O(N P) copies, products and finiteness
// checks of N-vectors, and the N x P matrices it keeps.  F comes from the Gram matrix of [J r]
// (one blocked product, N P^2 / 2 multiply-adds, about a quarter of the QR's) through a pivoted
// LDL^T: a zero column or a direction lost to rounding gets a pivot of 0, never a failed
// factorisation.  The Gram matrix squares J's condition number; the unit-diagonal scaling it is
// factored in removes the column scales, which is what Ceres' Jacobi scaling did to the QR, and
// directions that the squaring loses (singular values below 1e-8 of the largest after scaling)
// are the ones Levenberg-Marquardt's damping already dominates.
//
// Values without a Jacobian (the line search's trial points, a candidate's cost) are returned as
// (0, ..., 0, ||r||): the same cost.  Ceres asks for the Jacobian again, with the residuals, at
// every point it accepts, so the two forms are never mixed within one step.
#pragma once

#include <ceres/cost_function.h>

#include <Eigen/Core>

#include <functional>
#include <memory>
#include <vector>

namespace friction::detail {

/// F with F^T F = G for a positive semi-definite G given by its lower triangle (overwritten: it is
/// scaled in place).  F = D^1/2 L^T P S, from the pivoted LDL^T of the unit-diagonal scaling
/// S^-1 G S^-1 = P^T L D L^T P (negative pivots from rounding clipped to 0).
void normal_factor(Eigen::MatrixXd& gram, Eigen::MatrixXd& factor);

/// Adds rows of [J r], one at a time, to the lower triangle of a Gram matrix ((P+1) x (P+1)):
/// they are gathered 256 at a time (in cache) and added by one rank update per 256, over the
/// columns not zero on all of them.  What keeps the memory of a compressed evaluation
/// independent of N: no N x P Jacobian is stored when its rows come one by one
/// (RowStreamingCost).
class GramAccumulator {
 public:
  explicit GramAccumulator(Eigen::MatrixXd& gram);
  GramAccumulator(const GramAccumulator&) = delete;
  GramAccumulator& operator=(const GramAccumulator&) = delete;
  ~GramAccumulator() = default;
  /// One row: block b's sizes[b] entries at blocks[b] (null: not requested, no columns), then r.
  void add(const double* const* blocks, const std::vector<int>& sizes, double r);
  /// Adds what is gathered; call once after the last row.
  void flush();

 private:
  static constexpr Eigen::Index kRows = 256;
  Eigen::MatrixXd& gram_;
  Eigen::MatrixXd rows_;
  Eigen::Index used_ = 0;
  std::vector<Eigen::Index> live_;          // the columns not zero on every gathered row
  Eigen::MatrixXd live_rows_, live_gram_;  // those columns, and their products
};

/// Adds the rows of [J r] to the lower triangle of `gram` ((P+1) x (P+1)), J given as row-major
/// blocks of columns (null: a block whose Jacobian was not requested, skipped).
void accumulate_gram(const std::vector<const double*>& blocks, const std::vector<int>& sizes,
                     const double* residuals, Eigen::Index n, Eigen::MatrixXd& gram);

/// A cost that can hand its Jacobian over row by row instead of as N x P blocks: CompressedCost
/// then needs memory of order P^2, not N P.  `requested[b]` says whether block b's columns are
/// wanted; `visit(k, rows)` is called for k = 0, ..., N - 1 in order with rows[b] pointing at row
/// k of block b (valid during the call; null when not requested), after all N residuals are
/// written.
class RowStreamingCost {
 public:
  using RowVisitor = std::function<void(std::size_t k, const double* const* rows)>;
  virtual ~RowStreamingCost() = default;
  /// Whether EvaluateRows can be used at all (false: Evaluate with N x P blocks).
  virtual bool streams() const = 0;
  virtual bool EvaluateRows(double const* const* parameters, double* residuals,
                            const bool* requested, const RowVisitor& visit) const = 0;
};

/// The triangular factor R (P x P) of a tall matrix A (N x P) given by blocks of rows, A = Q R:
/// each block is stacked under the R so far and the stack re-factored (Householder), so R carries
/// A's singular values and right singular vectors to rounding, with N x P never stored.  What
/// takes a covariance or a rank decision from an SVD of A can take it from R.
class RowCompressor {
 public:
  explicit RowCompressor(Eigen::Index cols);
  /// Adds rows (any count, P columns).
  void add(const Eigen::Ref<const Eigen::MatrixXd>& rows);
  /// R (upper triangular; rows beyond the number added are zero).
  Eigen::MatrixXd factor() const;

 private:
  Eigen::Index cols_;
  Eigen::MatrixXd stack_;  // R so far (at most P rows)
};

/// `inner` (N residuals) compressed to P + 1 residuals, P the total size of its parameter blocks.
/// Evaluate is not re-entrant (it keeps its buffers): one solver thread per problem, as every
/// fit here runs.
class CompressedCost final : public ceres::CostFunction {
 public:
  explicit CompressedCost(ceres::CostFunction* inner);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  const ceres::CostFunction& inner() const { return *inner_; }

 private:
  // Both add the rows of [J r] (the requested columns) to gram_'s lower triangle.
  bool add_rows_streamed(double const* const* parameters, double** jacobians) const;
  bool add_rows_whole(double const* const* parameters, double** jacobians) const;

  // Whether `parameters` are, bit for bit, those of the last evaluation of values alone.
  bool same_as_last_value_point(double const* const* parameters) const;

  std::unique_ptr<ceres::CostFunction> inner_;
  const RowStreamingCost* streaming_ = nullptr;  // inner_ itself when it streams its rows
  // The last evaluation of values alone (point, RSS root, success).  Ceres' bounded trust region
  // evaluates each step twice at the same point: its projected line search tries step 1 first,
  // and the minimiser then evaluates the candidate it accepted, x + 1 x delta, again.
  mutable std::vector<double> last_value_point_;
  mutable double last_value_norm_ = 0.0;
  mutable bool last_value_ok_ = false;
  mutable std::vector<double> residuals_;
  mutable std::vector<std::vector<double>> jacobians_;
  mutable Eigen::MatrixXd gram_, factor_;
};

}  // namespace friction::detail
