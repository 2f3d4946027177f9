// Identification of the DNLRX model (methods.md section 4, reconstructed; model in dnlrx.hpp).
//
//     F(t) = sum_i sum_{j=0..n} theta_{i,j} delta_i(t-j) + sum_{j=0..nx} g_j dx(t-j)
//
// For fixed thresholds (and initial deflections) the model is linear in theta and g, so it is
// solved as a linear least-squares problem:
//  * Columns are scaled to unit norm and solved by the normal equations when well conditioned,
//    else by column-pivoted (rank-revealing) QR.  A column whose pivot falls below the rank
//    tolerance (below) is dropped (coefficient 0) and named in a warning, so a rank-deficient
//    regressor gives a well-defined model, never a NaN.
//  * Rank deficiency has a known cause (methods.md 8): an operator that never saturates has
//    delta_i(t) = delta_i(0) + x(t) - x(0), so its lagged columns satisfy
//    delta_i(t) - delta_i(t-1) = dx(t) and duplicate the input filter.  Such operators are
//    detected from d delta_i / d delta_i(0) (1 at every sample) and their lags j >= 1 dropped
//    before the solve, with a warning; the QR then handles what remains near-collinear.  A
//    dropped column rather than a ridge: the model is then exactly the smaller one, its
//    parameters have ordinary standard errors, and no lambda has to be chosen.
//  * Initial deflections: estimated from the record (initial_state.hpp, spring-filter form), and
//    the linear solve and the estimate alternate (3 rounds; the estimate changes the regressors
//    only until each operator first saturates).  The record is extended backwards at rest
//    (delta(t < 0) = delta(0), dx(t <= 0) = 0), as Dnlrx::reset does.
//  * Thresholds: for each M, NLR's best minimum with M operators, then re-optimised with the
//    smallest filters of the grid by variable projection (Ceres, exact Golub-Pereyra Jacobian,
//    stick-breaking bounds as in NLR) before the orders are compared, and re-optimised again for
//    the selected orders (`DnlrxThresholds`).  Measured (bench_identification, N = 10,000,
//    Maxwell Slip M = 4 plus a viscous term, CPU s / selected orders / validation RSS/SSS %):
//      thresholds from NLR only:              2.1 s, M=6 n=2 nx=0, 0.0288 %
//      re-optimised for the selected orders:  2.6 s, M=6 n=2 nx=0, 0.0041 %
//      re-optimised per M and selected:       2.3 s, M=4 n=0 nx=0, 0.0041 %  (default)
//    (3.4, 4.1 and 3.7 s, same orders and errors, before NLR's evaluations were made cheaper and
//    the re-optimisation kept the last point's trajectories and projection for Ceres' repeated
//    requests.)  `friction-identify compare` on data/estimation.csv: 3.6 s -> 1.6 s CPU, same
//    selected orders, estimation 0.2000 % and validation 0.1964 %.
//    NLR's thresholds absorb the viscous term; with them the criterion buys extra operators and
//    filter taps instead.  Re-optimising per M finds the true structure at no extra cost.
//  * Rank tolerance: a unit-norm column whose pivot in the column-pivoted QR is below
//    eta / sqrt(N) (eta = noise sigma / rms F, estimated from the force) is dropped: it could not
//    be estimated to better than 100 % even with a coefficient as large as the whole force.
//  * Orders (M, n, nx): chosen on the estimation record only by BIC = N ln(RSS/N) + p ln N with
//    p = M (n+1) + (nx+1) + M (filters and thresholds, minus dropped columns), over
//    M = 1..max_operators, n = 0..max_spring_order, nx = 0..max_input_order; table in the report.
//  * Uncertainty: sigma^2 (J^T J)^{-1} with J = [Phi, d Fhat / d log Delta] at the optimum (the
//    linear part's (X^T X)^{-1} sigma^2 extended by the thresholds), by SVD of the scaled J; a
//    rank-deficient J is a warning and the standard errors are left at 0.  Filter coefficients
//    get symmetric intervals (value +- 1.96 se), thresholds log-normal ones.
#pragma once

#include <cstddef>
#include <span>

#include "friction/dnlrx.hpp"
#include "friction/identification.hpp"
#include "friction/nlr.hpp"

namespace friction {

/// Where the thresholds of DNLRX come from (see the header comment for the measurements).
enum class DnlrxThresholds {
  Nlr,                 ///< NLR's thresholds for each M, never changed
  ReoptimiseSelected,  ///< NLR's, re-optimised with the filters for the selected orders only
  ReoptimisePerOperatorCount,  ///< re-optimised for every M (smallest filters) before the orders
                               ///< are compared, and again for the selected orders (default)
};

struct DnlrxOptions {
  std::size_t max_operators = 6;     ///< M = 1..max_operators
  std::size_t max_spring_order = 2;  ///< n = 0..max_spring_order
  std::size_t max_input_order = 2;   ///< nx = 0..max_input_order
  std::size_t operators = 0;         ///< > 0: this M only
  long spring_order = -1;            ///< >= 0: this n only
  long input_order = -1;             ///< >= 0: this nx only
  DnlrxThresholds thresholds = DnlrxThresholds::ReoptimisePerOperatorCount;
  double rank_tolerance = 1e-10;  ///< floor of the data-derived rank tolerance (header comment)
  bool covariance = true;
  /// Threads for the operator counts of the order selection (0: one per core); the result is the
  /// same for any count.
  unsigned threads = 0;
  NlrOptions nlr;  ///< for the thresholds (its operator counts are overridden)
  /// The report of identify_maxwell_slip on the same record with the same `nlr` options (its
  /// refine_initial_state, covariance and max_operators aside; max_operators at least this one's):
  /// DNLRX then takes its thresholds from that run's starts instead of running NLR's order
  /// selection again.  The fits of M = 1..max_operators do not depend on the largest M tried or
  /// on what NLR does after its selection, and the starts of its final initial-state refinement
  /// are left out where DNLRX's own run would not make them, so the result is the same, bit for
  /// bit (test_dnlrx_identification).  Ignored (DNLRX runs NLR itself) unless the report holds a
  /// start for every M tried.  `compare` passes the NLR it identifies anyway.
  const IdentificationReport* nlr_report = nullptr;
};

struct DnlrxResult {
  DnlrxParameters<double> parameters;
  IdentificationReport report;  ///< parameters: spring_filter[i,j], input_filter[j], threshold[i]
};

/// Identify a DNLRX model from displacement `x` [m] and force [N] sampled at `time` [s].
DnlrxResult identify_dnlrx(std::span<const double> time, std::span<const double> x,
                           std::span<const double> force, const DnlrxOptions& options = {});

/// The linear part alone: filters (and initial deflections) for given thresholds and orders, with
/// the same report contents (a one-row selection table; thresholds get standard errors from the
/// same J, though they were not estimated here).
DnlrxResult fit_dnlrx_filters(std::span<const double> time, std::span<const double> x,
                              std::span<const double> force, std::span<const double> thresholds,
                              std::size_t spring_order, std::size_t input_order,
                              double rank_tolerance = 1e-10);

/// Free run of a DNLRX model with fixed parameters on a record, initial deflections estimated from
/// that record (nothing else is): validation.
struct DnlrxFreeRun {
  std::vector<double> initial_deflections;
  std::vector<double> simulated;
  ErrorMetrics errors;
};
DnlrxFreeRun free_run_dnlrx(const DnlrxParameters<double>& parameters, std::span<const double> time,
                            std::span<const double> x, std::span<const double> force);

}  // namespace friction
