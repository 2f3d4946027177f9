// Internal machinery shared by the initial-state estimation, NLR and DNLRX (not installed).
//
// Operator trajectories.  With unit stiffness the Maxwell Slip operators' deflections delta_i(t)
// are the regressors of both NLR (F = sum k_i delta_i) and DNLRX (lagged delta_i).  Operator i
// depends only on its own threshold Delta_i and initial deflection delta_i(0).  So one
// MaxwellSlip<ceres::Jet<double, 2>> run would give every partial derivative needed: seed every
// threshold with derivative (1, 0) and every initial deflection with (0, 1); since no operator
// mixes with another, the Jet part of delta_i(t) is exactly
// (d delta_i(t) / d Delta_i, d delta_i(t) / d delta_i(0)).  operator_trajectories computes that
// recursion directly (identical numbers, a test checks it against the Jet run).  The second is the
// indicator "not yet saturated" (1 until the operator first reaches a bound, 0 after), which is
// what the initial-state estimation exploits.
#pragma once

#include <ceres/jet.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "friction/error.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/nlr.hpp"

namespace friction::detail {

struct OperatorTrajectories {
  Eigen::MatrixXd delta;        ///< N x M: delta_i(t), unit stiffness
  Eigen::MatrixXd d_threshold;  ///< d delta_i(t) / d Delta_i with delta_i(0) held fixed
  Eigen::MatrixXd d_initial;    ///< d delta_i(t) / d delta_i(0)
  /// The same two sensitivities in compact form (operator_trajectories_compact; d_threshold and
  /// d_initial are then left empty), N x M column-major: in the nominal box they take only three
  /// pairs of values, (0, 1) until the operator first meets a bound, then (1, 0) or (-1, 0) as the
  /// bound it met last is the upper or the lower, so one byte holds both where the dense form
  /// takes sixteen.  A fit that keeps its workspace between evaluations keeps M bytes per sample
  /// instead of 16 M.
  std::vector<std::uint8_t> codes;
  static constexpr std::uint8_t kFree = 0, kUpper = 1, kLower = 2;

  /// Rows [t0, t0 + rows) of d_threshold and d_initial into the top rows of `dt` and `di` (at
  /// least `rows` x M), from whichever form was computed.
  void sensitivity_rows(Eigen::Index t0, Eigen::Index rows, Eigen::Ref<Eigen::MatrixXd> dt,
                        Eigen::Ref<Eigen::MatrixXd> di) const;
};

/// Slip limits that change from sample to sample: operator i is clamped to
/// [-lower[t] Delta_i, upper[t] Delta_i] at sample t, and its initial deflection, given at level 1,
/// is multiplied by `first`.  This is the box an Extended<MaxwellSlip> hands its base
/// (extensions.hpp): upper = (1 + a) L(t), lower = (1 - a) L(t), first = L(0), with L the product
/// of the level pieces along the record and a the asymmetry.  A base fitted under them is fitted
/// under the pieces' level instead of on the force divided by it, which in presliding (where the
/// operators do not feel the level) is not the force of any Maxwell Slip model.
struct SlipLimits {
  std::vector<double> upper, lower;
  /// The factors at the turn inside a sample's interval, for the step to the extremum (motion.hpp,
  /// The level at the turn); empty: upper and lower.
  std::vector<double> turn_upper, turn_lower;
  double first = 1;
};

/// Throws InvalidParameter unless `limits` has `samples` factors of each kind, all finite and > 0,
/// and a finite first level > 0.  operator_trajectories checks only the sizes (it runs at every
/// evaluation of a fit); identify_maxwell_slip_under_limits checks the rest once.
void check_slip_limits(const SlipLimits& limits, std::size_t samples);

/// Deflections of unit-stiffness operators from the given initial deflections (clamped to the
/// thresholds), sample 0 being the initial state and sample k > 0 the state after x[k]-x[k-1].
/// With `limits` the thresholds are scaled per sample (SlipLimits) and so are the derivatives:
/// at a limit d delta_i / d Delta_i is that sample's factor (upper[t] or -lower[t]) rather than
/// +-1, and d delta_i / d delta_i(0) starts at `first`.
///
/// This is the recursion of MaxwellSlip<ceres::Jet<double, 2>> (eq. 4 with the clamp of
/// scalar.hpp, which keeps the derivative of the branch taken) written out per operator: at the
/// upper bound the derivatives are (1, 0), at the lower bound (-1, 0), and in between they are
/// carried over unchanged.  The same numbers, bit for bit (test_nlr compares the two), without
/// the Jet arithmetic: the identification evaluates this thousands of times.
///
/// `turns`, when not empty, is turns_of(x) computed once by a caller that evaluates the same
/// displacement many times (a fit): the turns depend on x alone.
void operator_trajectories(std::span<const double> thresholds,
                           std::span<const double> initial, std::span<const double> x,
                           bool sensitivities, OperatorTrajectories& out,
                           const SlipLimits* limits = nullptr,
                           std::span<const double> turns = {});

/// operator_trajectories with sensitivities, in the nominal box, the sensitivities written as
/// OperatorTrajectories::codes: the same recursion, the same numbers once decoded.
void operator_trajectories_compact(std::span<const double> thresholds,
                                   std::span<const double> initial, std::span<const double> x,
                                   OperatorTrajectories& out, std::span<const double> turns = {});

OperatorTrajectories operator_trajectories(std::span<const double> thresholds,
                                           std::span<const double> initial,
                                           std::span<const double> x, bool sensitivities,
                                           const SlipLimits* limits = nullptr);

/// Motion::turn of every interval of x (motion.hpp, Turns between samples); entry 0 is 0.
std::vector<double> turns_of(std::span<const double> x);

/// NLR (identify_maxwell_slip) with its operators under `limits`: the force is sum k_i delta_i
/// with delta_i clamped to the moving box of SlipLimits.  The starts' initial states come from
/// the nominal box (initial_state.hpp knows no other); the local searches fit them under the
/// limits.  The report's initial deflections are given at level 1 (what SlipLimits::first scales)
/// and its estimation errors are those of the run under the limits.
NlrResult identify_maxwell_slip_under_limits(std::span<const double> time,
                                             std::span<const double> x,
                                             std::span<const double> force,
                                             const NlrOptions& options,
                                             const SlipLimits& limits);

/// The coefficients of signals a_j(t_k) fitted beside the operators of NLR's dictionary (nlr.cpp,
/// dictionary_operators: NNLS over a dense grid of thresholds and initial states, the a_j's
/// coefficients bounded below by `lower`, free where it is short), in the force's units per unit
/// of a_j; empty when the record gives no dictionary.  `residual_variance`: the fit's residual
/// variance per sample [force^2].  A viscous term fitted this way is that of the force whatever
/// thresholds the operators take: the restart of an extended fit (extension_identify_slip.cpp,
/// without_dictionary_viscous) takes it out before NLR, where the joint fit's coefficient may
/// carry a base that absorbed part of it.
std::vector<double> dictionary_added_coefficients(std::span<const double> x,
                                                  std::span<const double> force,
                                                  std::span<const std::vector<double>> added,
                                                  std::span<const double> lower,
                                                  double displacement_resolution_hint,
                                                  const SlipLimits* limits = nullptr,
                                                  double* residual_variance = nullptr);

/// Column `c` delayed by `lag` samples, the record being extended backwards with its first value
/// (the system at rest before the record: delta(t < 0) = delta(0), dx(t <= 0) = 0).
inline Eigen::VectorXd lagged(const Eigen::Ref<const Eigen::VectorXd>& c, Eigen::Index lag) {
  const Eigen::Index n = c.size();
  Eigen::VectorXd out(n);
  for (Eigen::Index t = 0; t < n; ++t) out(t) = c(t >= lag ? t - lag : 0);
  return out;
}

/// The active-set solve of box_least_squares on its compressed form: min ||as z - bs|| with as
/// (P x P, or N x P uncompressed) the column-scaled regressors, `scale` their column norms and
/// `b_norm` = ||b|| (for the optimality tolerance).  Returns the unscaled solution.
Eigen::VectorXd box_least_squares_reduced(const Eigen::MatrixXd& as,
                                          const Eigen::VectorXd& bs,
                                          const Eigen::VectorXd& scale, double b_norm,
                                          const Eigen::VectorXd& lo,
                                          const Eigen::VectorXd& hi,
                                          std::vector<int>* at_bound);

/// The compression of box_least_squares from the normal equations: `gram` holds A^T A in its
/// lower triangle and is scaled in place to unit diagonal; `scale` receives the column norms (1
/// for a zero column).  With L L^T its Cholesky factorisation, R = L^T and Q^T b = L^-1 A^T b are
/// the QR's compression up to the signs of R's rows, as long as the normal equations lose few
/// digits: false (as, bs untouched) unless the reciprocal condition of the scaled Gram matrix
/// exceeds 1e-10, i.e. cond(A) below 1e5, at most 5 of 16 digits lost (a zero column fails).
bool compress_by_gram(Eigen::MatrixXd& gram, const Eigen::VectorXd& atb,
                      Eigen::LLT<Eigen::MatrixXd>& llt, Eigen::VectorXd& scale,
                      Eigen::MatrixXd& as, Eigen::VectorXd& bs);

/// min ||A z - b|| subject to lo <= z <= hi (entries may be +-infinity) by an active-set method
/// (Lawson-Hanson generalised to two-sided bounds).  Columns are scaled to unit norm internally;
/// the free subproblems are solved by column-pivoted QR, so a rank-deficient free set gives a
/// basic solution, never a NaN.  Converges in a finite number of steps for this convex problem.
/// `at_bound` (optional) receives 1 for every variable left on a bound.
///
/// Compression: with A = Q R (N > P), ||A z - b||^2 = ||R z - Q^T b||^2 + const, so one O(N P^2)
/// factorisation turns the problem into a P x P one and every active-set step (each a fresh QR of
/// the free columns) costs O(P^3) instead of O(N P^2).  Q is orthogonal, so the column norms, the
/// conditioning and hence the rank decisions are those of A itself.
/// Storage box_least_squares may keep from call to call (N x P; see Workspace in nlr.cpp).
struct BoxLeastSquaresStorage {
  Eigen::MatrixXd scaled;
  Eigen::VectorXd rhs;
  Eigen::MatrixXd gram;
  Eigen::LLT<Eigen::MatrixXd> llt;
};

Eigen::VectorXd box_least_squares(const Eigen::MatrixXd& a, const Eigen::VectorXd& b,
                                  const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                  std::vector<int>* at_bound = nullptr,
                                  BoxLeastSquaresStorage* storage = nullptr);

/// box_least_squares from the normal equations alone: `gram` = A^T A (lower triangle read),
/// `atb` = A^T b, `btb` = b^T b.  Moving one operator of a fitted set needs no N x P matrix this
/// way (see threshold_moves in nlr.cpp).  False, with z untouched, when the column-scaled Gram
/// matrix has a reciprocal condition of 1e-10 or less (or a zero column): the normal equations
/// would then lose more than 5 digits.  `rss` receives ||A z - b||^2, from the reduced problem
/// (relative accuracy about 1e-16 / (RSS/SSS), ample for comparing fits).
bool box_least_squares_gram(const Eigen::MatrixXd& gram, const Eigen::VectorXd& atb,
                            double btb, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                            Eigen::VectorXd& z, double& rss,
                            std::vector<int>* at_bound = nullptr);

/// Projection machinery of variable projection for a regressor matrix Phi (N x P): column-scaled,
/// column-pivoted QR, rank-revealing.  For a parameter p with dPhi/dp, the exact (Golub-Pereyra)
/// derivative of the projected residual r = (I - Phi Phi^+) y is
///     dr/dp = -P_perp (dPhi/dp) c - (Phi^+)^T (dPhi/dp)^T r,
/// and `derivative(a, w)` returns it from a = (dPhi/dp) c and w = (dPhi/dp)^T r.  Columns beyond
/// the numerical rank are left out of the pseudo-inverse (minimum-information, never NaN).
struct Projector {
  Eigen::VectorXd scale;  ///< column norms used for scaling
  Eigen::Index rank = 0;

  Projector() = default;
  explicit Projector(const Eigen::MatrixXd& phi, double threshold = 1e-12) {
    compute(phi, threshold);
  }

  /// (Re)factorise for `phi`, reusing storage when the sizes repeat.
  void compute(const Eigen::MatrixXd& phi, double threshold = 1e-12);

  /// Basic least-squares solution: columns beyond the numerical rank get coefficient 0 (dropped).
  Eigen::VectorXd solve(const Eigen::VectorXd& y) const;

  /// True for a column left out (beyond the numerical rank).
  bool dropped(Eigen::Index j) const { return position_(j) >= rank; }

  /// Column-wise `derivative` for many parameters at once: A is N x k, W is P x k.
  Eigen::MatrixXd derivatives(const Eigen::MatrixXd& a, const Eigen::MatrixXd& w) const;

  /// The same into `out` (N x k), through storage kept from call to call: the variable-projection
  /// Jacobians call this at every accepted step, and fresh N x k temporaries there cost more in
  /// page faults than the arithmetic.
  void derivatives_into(const Eigen::MatrixXd& a, const Eigen::MatrixXd& w, Eigen::MatrixXd& out);

  Eigen::VectorXd derivative(const Eigen::VectorXd& a, const Eigen::VectorXd& w) const;

 private:
  Eigen::MatrixXd phis_;  // unit-norm columns
  Eigen::MatrixXd gram_matrix_;
  Eigen::MatrixXd small_;  // P x k scratch of derivatives_into
  Eigen::LLT<Eigen::MatrixXd> gram_;
  bool use_gram_ = false;
  Eigen::MatrixXd q_;         // N x rank, orthonormal basis of the range (QR path)
  Eigen::MatrixXd r11_;       // rank x rank upper triangular (QR path)
  Eigen::VectorXi position_;  // position_[j]: where column j sits after pivoting
};

/// Ordered thresholds in [lo, hi] from a point of the unit box by stick-breaking in log space:
/// beta_i = 1 - prod_{l <= i} (1 - s_l), log Delta_i = log lo + (log hi - log lo) beta_i.  Every
/// s in [0, 1]^M gives lo <= Delta_1 <= ... <= Delta_M <= hi, so box bounds on s (which Ceres and
/// NLopt both handle) keep the thresholds ordered and inside their physical range.
struct StickBreaking {
  double lo, hi;

  std::vector<double> thresholds(std::span<const double> s) const {
    std::vector<double> d(s.size());
    const double a = std::log(lo), w = std::log(hi) - std::log(lo);
    double rest = 1.0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      rest *= 1.0 - s[i];
      d[i] = std::exp(a + w * (1.0 - rest));
    }
    return d;
  }

  /// J(i, l) = d Delta_i / d s_l (lower triangular).
  Eigen::MatrixXd jacobian(std::span<const double> s) const {
    const Eigen::Index m = static_cast<Eigen::Index>(s.size());
    const std::vector<double> d = thresholds(s);
    const double w = std::log(hi) - std::log(lo);
    Eigen::MatrixXd j = Eigen::MatrixXd::Zero(m, m);
    for (Eigen::Index i = 0; i < m; ++i)
      for (Eigen::Index l = 0; l <= i; ++l) {
        double prod = 1.0;
        for (Eigen::Index q = 0; q <= i; ++q)
          if (q != l) prod *= 1.0 - s[static_cast<std::size_t>(q)];
        j(i, l) = d[static_cast<std::size_t>(i)] * w * prod;
      }
    return j;
  }

  /// Inverse map for thresholds (sorted and clamped into [lo, hi] first).
  std::vector<double> coordinates(std::vector<double> d) const {
    std::sort(d.begin(), d.end());
    const double a = std::log(lo), w = std::log(hi) - std::log(lo);
    std::vector<double> s(d.size());
    double prev = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i) {
      const double beta = std::clamp((std::log(std::clamp(d[i], lo, hi)) - a) / w, 0.0, 1.0);
      s[i] = prev < 1.0 ? std::clamp((beta - prev) / (1.0 - prev), 0.0, 1.0) : 0.0;
      prev = std::max(prev, beta);
    }
    return s;
  }
};

/// Marginal (unscaled) covariance of the first `interest` parameters, (J^T J)^-1 restricted to
/// them, where the remaining columns of J are nuisance parameters (initial states) estimated with
/// them.  Columns are scaled to unit norm before the SVD; nuisance columns that are identically
/// zero (an operator saturated from the first sample: its initial state has no effect) are left
/// out.  When J is rank-deficient (reciprocal condition below `rcond`) the nuisance columns are
/// held fixed instead (the conditional covariance); false when even that is rank-deficient.
bool marginal_covariance(const Eigen::MatrixXd& jac, Eigen::Index interest,
                         Eigen::MatrixXd& out, double rcond = 1e-10);

}  // namespace friction::detail
