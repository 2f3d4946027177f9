// NLR: identification of the basic Maxwell Slip model (methods.md section 3, reconstructed).
//
// Model (paper eqs. 4-5): F(t) = sum_i k_i delta_i(t), operators with thresholds Delta_i.
//
// Estimator: separable nonlinear least squares.  For fixed thresholds the model is linear in the
// stiffnesses, so the cost is concentrated on the thresholds (variable projection, Golub &
// Pereyra 1973):
//
//     r(Delta, rho) = F - Phi(Delta, rho) k*(Delta, rho),   k* = argmin_{k >= 0} ||F - Phi k||
//
// where Phi(t, i) = delta_i(t) is the deflection of a unit-stiffness operator (MaxwellSlip<T>
// with k = 1) and rho_i = delta_i(0) / Delta_i in [-1, 1] is the relative initial deflection.
//
//  * Stiffnesses k > 0: k* is the non-negative least-squares solution (an active-set method,
//    Lawson-Hanson, exact in a finite number of steps; its free subproblems use column-pivoted QR
//    of unit-norm columns).  Unconstrained LS gives 1-4 negative stiffnesses of 6-10 on real
//    records (methods.md 8); a stiffness that the data want negative is driven to the bound 0,
//    which means the operator is not needed: it is removed from the model with a warning and the
//    criterion sees the smaller model.
//  * Thresholds ordered and inside [q, L] (displacement resolution, largest travel; see
//    identification.hpp) through a stick-breaking map in log space from the unit box:
//    beta_i = 1 - prod_{l<=i}(1 - s_l), log Delta_i = log q + (log L - log q) beta_i, s in [0,1]^M.
//    Box bounds then give q <= Delta_1 <= ... <= Delta_M <= L:
//    positive, ordered, log-scaled, and never a relay below the resolution nor a linear spring
//    beyond the travel.
//  * Initial state: rho is optimised with the thresholds (box [-1, 1]); the reported errors use
//    estimate_initial_deflections (initial_state.hpp) with the final parameters, the same routine
//    validation uses (with refine_initial_state off, the fit's own rho instead).
//  * Jacobian: exact Golub-Pereyra derivative of the projected residual (both terms, not Kaufman's
//    approximation), built from d delta_i / d Delta_i and d delta_i / d delta_i(0): the numbers
//    one run of MaxwellSlip<ceres::Jet<double, 2>> gives (autodiff through the slip recursion),
//    computed by that recursion written out per operator (a test checks them bit for bit against
//    the Jet run).  The derivative is exact on the piece of the piecewise-smooth cost the point
//    lies on; tests compare it with finite differences.
//  * Local search: Levenberg-Marquardt in the box (src/bounded_levenberg_marquardt.hpp: the step
//    solved on the parameters not held at a bound by the gradient, clamped into the box, accepted
//    by the decrease its own linear model predicts, one evaluation per trial; Ceres' projected
//    line search wasted a third of the evaluations on steps pushing a parameter at its bound
//    outward, and this search reaches the same minima in 1.2-2.5x less time on the bench
//    records, README "NLR's own bounded Levenberg-Marquardt").  A search that cannot reach the
//    best minimum already known at this M, nor the (M-1)-operator minimum (which an M-operator
//    model contains), within its remaining iterations at the pace of its last 10 is stopped
//    (logged as such); the warm start runs first so that this target exists early.  Without the
//    stop one start on data/estimation.csv spent all 100 iterations (40 % of the Jacobians of the
//    whole identification) crawling along a valley to a minimum 75 % above the one the warm start
//    had reached; the results (table, selected M, parameters) are unchanged by it.  A search
//    also ends, as converged, when at that pace its whole budget would lower the RSS by less than
//    one noise variance.  The search is given the compressed problem (src/compressed_cost.hpp):
//    2M + 1 residuals F with F^T F = [J r]^T [J r], built from row blocks of J without storing
//    it, on which Levenberg-Marquardt takes the same steps as on the N projected residuals.
//  * Cost of an evaluation: NNLS on the compressed P x P problem (the Cholesky factor of the
//    Gram matrix, formed at matrix-product speed, or a Householder QR when the regressors are
//    ill-conditioned; then O(M^3) active-set steps), the last point's trajectories, NNLS and
//    projection kept so that repeated requests at one point (its cost, then its Jacobian) cost
//    once, and storage reused between evaluations.
//  * Starts (automatic, from the data): (a) "dictionary": one NNLS over a dense grid of thresholds
//    (16 per decade over [q, L]; each threshold the record does not wipe out at once from three
//    initial states: virgin and either bound), accumulated as a Gram matrix in blocks of rows; the
//    grid points it keeps gather around the thresholds the data hold and are merged into M
//    operators (nlr.cpp, dictionary_start).  Only when it keeps none, (a') "force-quantiles":
//    Delta_j = u_j / 2 where u_j is the travel after the largest reversal at which the force has
//    covered (j - 1/2)/M of its swing, and "geometric": thresholds spread geometrically between
//    the smallest of those and half the presliding travel.  (b) "warm": the M-1 solution with one
//    threshold inserted in its largest log-gap (in the order selection, where it replaces (a) once
//    M exceeds the dictionary's operators).
//  * Global stage: the cost is only piecewise smooth, and one start can end in a worse local
//    minimum (methods.md 8).  Whenever the best start is above the noise floor (at a fixed M and
//    in the order selection), the best fit's operators are moved one at a time: each threshold is
//    profiled over a log grid of [q, L] (8 points per decade) and over +-20 % of its value (1 %
//    steps) with the others held and the stiffnesses re-solved (Gram products only), and the best
//    move is polished by the local search when its gain is significant (above the 0.999 quantile
//    of a chi-square of 2 degrees of freedom, in noise variances); sweeps repeat while they
//    improve; then a restart from the initial-state estimate, in up to three rounds while moves
//    are taken.
//    Deterministic, no random numbers.  Against the controlled random search it replaced (NLopt
//    GN_CRS2_LM, 500 M evaluations per round): the strokes bench record's minimum 49 % lower, the
//    NLR round-trip study as good (pooled coverage 299/320 against 298/320) in a third of the time.
//    Every start, its cost before and after, and whether it found a new distinct minimum are
//    logged.
//  * Order: M = 1..max_operators, chosen by BIC = N ln(RSS/N) + 2M ln N on the estimation record
//    (the initial states are nuisance parameters that only act until each operator first
//    saturates, so they are not counted).  BIC rather than AIC: with N in the thousands AIC's
//    penalty of 2 per parameter accepts operators that fit noise; an inner split would halve the
//    data that determine the large thresholds, which are seen at only a few reversals.
//    The stage is skipped when the best start is already at the noise floor (RSS below
//    N sigma^2 + 3 sqrt(2N) sigma^2, sigma = estimate_white_noise_sigma).
//  * Uncertainty: marginal covariance of (log k, log Delta) at the optimum with the relative
//    initial deflections rho as nuisance parameters, scaled by sigma^2 = RSS / (N - 3M); 95 %
//    intervals are log-normal, value * exp(+-1.96 se_log).  A rank-deficient covariance is a
//    warning, never a NaN.  The SVD is taken of the triangular factor of the Jacobian's row
//    blocks (the same singular values and vectors), so no N x 3M matrix is kept.
//
// Variable projection versus joint optimisation of (log k, s, rho), both with the same exact
// Jacobian machinery (bench_identification, one run each, CPU time on a shared 2-core machine):
//   M = 10, N = 10,000 (global stage on):  VP 0.64 s, RSS/SSS 0.0098 %  |  joint 3.1 s, 0.0221 %
//                                          (noise floor 0.0102 %)
//   M = 4,  N = 3,000 (2 starts, no global): VP 38 ms, joint 25 ms, both 0.00451 % (floor 0.0050)
// Joint is faster when M is small, but VP reaches the lower minimum at the M the method is used
// for, so VP is the default (`NlrSolver::Joint` stays available for comparison).  Before the
// evaluation was made cheaper (QR-compressed NNLS, per-point reuse, the crawl stop) VP took 2.4 s
// on the first case (the two starts then ended 0.0098 % and in a distinct minimum, so the global
// stage also ran) and 83 ms on the second; `friction-identify compare` on data/estimation.csv
// (M = 1..8, global stages) went from 3.7 to 1.4 s CPU with the same table and model.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <span>

#include "friction/identification.hpp"
#include "friction/maxwell_slip.hpp"

namespace friction {

/// How the thresholds and stiffnesses are optimised.
enum class NlrSolver {
  VariableProjection,  ///< stiffnesses eliminated by NNLS at every evaluation (default)
  Joint,               ///< stiffnesses (log k) optimised with the thresholds
};

struct NlrOptions {
  std::size_t max_operators = 8;  ///< M = 1..max_operators are fitted and compared by BIC
  std::size_t operators = 0;      ///< > 0: fit this M only (no selection)
  NlrSolver solver = NlrSolver::VariableProjection;
  bool global_stage = true;       ///< threshold moves (nlr.cpp) above the noise floor
  double stall_tolerance = 0.01;  ///< relative difference of two minima that makes them distinct
  int max_iterations = 100;       ///< trial steps per local search
  /// Stop when a step changes the cost by less than this fraction of it; 0: 0.01 / N (a step that
  /// lowers the RSS by less than 1 % of one residual variance)
  double function_tolerance = 0.0;
  bool covariance = true;  ///< standard errors and correlations
  /// The thorough initial-state refinement of the returned fit (nlr.cpp).  DNLRX turns it off in
  /// its order selection: it takes only NLR's minima per M and refines its own model.  Off, the
  /// report's estimation errors are those of the fit's own initial state (no global search).
  bool refine_initial_state = true;
  /// The starts of one M (the warm and the dictionary start in the order selection) run on this
  /// many threads (0: one per core); the result does not depend on it.
  unsigned threads = 1;
  /// q [m] when > 0: the resolution of the displacement as measured, for a record whose models
  /// see its local-polynomial estimate (record.hpp, measured_displacement; record_resolution);
  /// 0: from the displacement given.
  double displacement_resolution = 0;
};

struct NlrResult {
  MaxwellSlipParameters<double> parameters;  ///< ordered thresholds, positive stiffnesses
  IdentificationReport report;
};

/// Identify a basic Maxwell Slip model from displacement `x` [m] and force [N] sampled at `time`
/// [s] (the force in the model's sign convention).  Throws DataError-free InvalidParameter for
/// unusable input (mismatched lengths, fewer than 20 samples, no motion, zero force).
NlrResult identify_maxwell_slip(std::span<const double> time, std::span<const double> x,
                                std::span<const double> force, const NlrOptions& options = {});

/// The projected (concentrated) residual r = (F - Phi k*) / rms(F) and, when `jacobian` is not
/// null, its exact derivative J with respect to (s, rho) (N x 2M, s first).  `lower`/`upper` are
/// the threshold bounds q and L.  Exposed for tests; `stiffness` receives k*; `compressed`
/// receives what the local search is given instead of J and r: F ((2M+1) x (2M+1)) with
/// F^T F = [J r]^T [J r], built without storing J.
void nlr_projected_residual(std::span<const double> x, std::span<const double> force, double lower,
                            double upper, std::span<const double> s, std::span<const double> rho,
                            Eigen::VectorXd& residual, Eigen::MatrixXd* jacobian,
                            Eigen::VectorXd* stiffness = nullptr,
                            Eigen::MatrixXd* compressed = nullptr);

/// Thresholds [m] for stick-breaking coordinates s in [0,1]^M between `lower` and `upper`.
std::vector<double> nlr_thresholds_from_coordinates(std::span<const double> s, double lower,
                                                    double upper);

/// Inverse of nlr_thresholds_from_coordinates (thresholds sorted and clamped into the bounds).
std::vector<double> nlr_coordinates_from_thresholds(std::span<const double> thresholds,
                                                    double lower, double upper);

}  // namespace friction
