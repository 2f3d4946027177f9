// From a parameter covariance to standard errors, 95 % intervals, correlations and
// identifiability warnings: the one step every method (NLR, DNLRX, LG, the extension pieces and
// diagnose's findings) takes after its fit.
//
// Input.  The covariance of the fitted coordinates at the optimum (each method computes it its
// own way: the Gauss-Newton cov = s^2 (J^T J)^-1 with s^2 = RSS / (N - p), marginal over nuisance
// initial states where they are estimated too, or Ceres' pseudo-inverse for LG), and for every
// reported parameter its value in its own units, how it was fitted (parametrisation.hpp) and the
// covariance column it has (none: held, at a bound, not identifiable -- no standard error).
//
// Output, per parameter, in the parametrisation it was fitted in:
//   log:     s = standard error of ln v;  standard error v s;  interval [v e^(-1.96 s), v e^(1.96
//   s)] linear:  s = standard error of the fitted coordinate, times the parameter's `scale` (a
//            reported value that is `scale` times the fitted one, e.g. a piece converted to the
//            model's own F0);  interval v -+ 1.96 s.
// A parameter without a standard error has standard_error 0 and the interval [v, v] (never NaN).
// Intervals may be clipped to the parameter's search box (LG: where e^(1.96 s) overflows or leaves
// the box, the linearisation says nothing the box does not).  Correlations r_ab = c_ab /
// sqrt(c_aa c_bb) between parameters that have a standard error (identity elsewhere).
//
// Identifiability warnings are typed (IdentifiabilityWarning); each method words them in its
// report.  A log interval wider than a factor `span_limit` (10: more than an order of magnitude), a
// linear parameter within 1.96 standard errors of 0 (`zero_test`), a pair correlated above
// `correlation_limit` (near-singular), a parameter at a bound of its fit, a parameter without a
// standard error, and a covariance that could not be computed at all.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "friction/identification.hpp"
#include "friction/parametrisation.hpp"

namespace friction {

/// One reported parameter.
struct CovarianceParameter {
  std::string name;
  std::string unit;
  double value = 0;  ///< in its own units, as reported
  Parametrisation fitted = Parametrisation::linear;
  double scale = 1;            ///< linear: the reported value is `scale` times the fitted one
  std::ptrdiff_t column = -1;  ///< its row/column of the covariance; -1: no standard error
  bool at_bound = false;       ///< ended at a bound of the fit (then column is -1)
  /// The interval is clipped to [lower_limit, upper_limit] when the options ask for it.
  double lower_limit = -std::numeric_limits<double>::infinity();
  double upper_limit = std::numeric_limits<double>::infinity();
};

struct CovarianceOptions {
  double span_limit = 10.0;  ///< log parameters: warn when upper95 > span_limit lower95
  double correlation_limit = std::numeric_limits<double>::infinity();  ///< warn above |r|
  bool zero_test = false;       ///< linear parameters: warn when |value| < 1.96 standard errors
  bool clip_to_limits = false;  ///< clip intervals to the parameters' limits
};

struct ParameterUncertainty {
  bool available = false;            ///< has a standard error
  double fitted_standard_error = 0;  ///< of the fitted coordinate (ln v for log parameters)
  double standard_error = 0;         ///< in the parameter's units; 0 when not available
  double lower95 = 0, upper95 = 0;   ///< 95 % interval in the fitted parametrisation
  bool clipped = false;              ///< the interval was clipped to the limits
};

enum class IdentifiabilityIssue {
  wide_interval,           ///< log interval spans more than span_limit
  not_significant,         ///< |value| < 1.96 standard errors (zero_test)
  correlated,              ///< |r| above correlation_limit (parameter, other)
  at_bound,                ///< ended at a bound of the fit: no standard error
  no_standard_error,       ///< no covariance column (held, not identifiable)
  covariance_unavailable,  ///< the covariance could not be computed: no standard errors at all
};

struct IdentifiabilityWarning {
  IdentifiabilityIssue issue{};
  std::size_t parameter = 0;
  std::size_t other = 0;  ///< `correlated`: the second parameter
  double value = 0;       ///< `correlated`: r
};

struct CovarianceReport {
  bool computed = false;  ///< a covariance was given
  std::vector<ParameterUncertainty> parameters;
  Eigen::MatrixXd correlation;                   ///< of the parameters (identity where unknown)
  std::vector<IdentifiabilityWarning> warnings;  ///< per parameter in order, then the pairs

  /// Writes standard errors and intervals into estimates of the same parameters (same order).
  void apply(std::vector<ParameterEstimate>& estimates) const;
};

/// The report of `parameters` from `covariance` (of the fitted coordinates; null when it could not
/// be computed).  See the header comment.
CovarianceReport covariance_report(const Eigen::MatrixXd* covariance,
                                   const std::vector<CovarianceParameter>& parameters,
                                   const CovarianceOptions& options = {});

}  // namespace friction
