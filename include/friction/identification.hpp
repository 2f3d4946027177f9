// Result types shared by the identification methods, and the scales they derive from the data.
//
// Every method reports the same things: the parameters with standard errors and 95 % intervals,
// their correlations, the free-run errors on the estimation record (initial state estimated from
// the record, every sample counted), the table of the order selection, warnings, a convergence
// summary, the seconds taken and the log of the global stage.
//
// Scales from the data (used for bounds and automatic starts; all in metres):
//  * displacement resolution q: the quantum of |dx|.  For a quantised record (an encoder) the
//    smallest nonzero |dx|; a record that is not quantised has arbitrarily small increments near
//    every reversal, so its resolution is taken as the 1st percentile of the nonzero |dx|, and
//    never below 1e-9 of the displacement range (double-precision round-off of the positions).
//    Thresholds below q cannot be told apart from a relay.
//  * largest travel L = (max x - min x) / 2: an operator whose threshold exceeds L may never
//    saturate whatever its initial deflection, so it is a linear spring and its threshold is not
//    identifiable.  Thresholds are kept in [q, L].
//  * presliding travel: after each reversal of x (detected with a hysteresis of a few q, so that
//    noise does not make reversals) the force changes until the elements slide.  The travel from
//    the reversal at which the force has covered a fraction of its swing over that segment is
//    measured on the segment with the largest force swing.  The largest of these travels (95 %
//    of the swing) is the presliding travel; it bounds the automatic starts, not the estimates.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "friction/metrics.hpp"

namespace friction {

struct Record;

/// One estimated parameter with its standard error and 95 % interval.
struct ParameterEstimate {
  std::string name;  ///< e.g. "stiffness[1]", "threshold[3]", "input_filter[0]"
  std::string unit;  ///< SI unit
  double value = 0;
  double standard_error = 0;  ///< 0 when not available (see the warnings)
  double lower95 = 0;         ///< 95 % interval (log-normal for positive parameters)
  double upper95 = 0;
};

/// One row of an order selection: an information criterion computed on the estimation record.
struct SelectionRow {
  std::size_t operators = 0;     ///< M
  std::size_t spring_order = 0;  ///< n (DNLRX), 0 for Maxwell Slip
  std::size_t input_order = 0;   ///< nx (DNLRX), 0 for Maxwell Slip
  std::size_t parameters = 0;    ///< number of parameters counted by the criterion
  double rss = 0;                ///< estimation residual sum of squares [N^2]
  double rss_sss_percent = 0;    ///< estimation RSS/SSS [%]
  double criterion = 0;          ///< BIC = N ln(RSS/N) + p ln N
  bool selected = false;
  bool failed = false;  ///< the fit failed (message in the warnings)
};

/// What the local optimiser reported for the selected model.
struct ConvergenceSummary {
  bool converged = false;
  int iterations = 0;       ///< of the final local search
  int local_searches = 0;   ///< over the whole selection
  double initial_cost = 0;  ///< RSS/SSS % at the start of the final local search
  double final_cost = 0;    ///< RSS/SSS % at its end
  std::string message;
};

/// One start of the multi-start / global stage and where it ended.
struct StartLog {
  std::size_t operators = 0;  ///< M of the fit
  std::string kind;           ///< "dictionary", "warm", "moved", "restart", "crs2-lm+bobyqa", ...
  std::vector<double> start_thresholds;  ///< [m]
  double start_percent = 0;              ///< RSS/SSS % at the start (concentrated cost)
  double final_percent = 0;              ///< RSS/SSS % at the local minimum
  std::vector<double> final_thresholds;  ///< [m]
  bool distinct = false;                 ///< a minimum not met by an earlier start of this M
  int iterations = 0;                    ///< of the local search
  double seconds = 0;                    ///< wall time of the local search
};

/// Everything an identification returns besides the model itself.
struct IdentificationReport {
  ErrorMetrics estimation;                    ///< free run on the estimation record
  std::vector<double> estimation_simulated;   ///< that free run [N]
  double noise_sigma = 0;                     ///< estimate_white_noise_sigma of the force [N]
  double noise_floor_percent = 0;             ///< RSS/SSS % of that noise alone
  std::vector<ParameterEstimate> parameters;  ///< in the model's order
  Eigen::MatrixXd correlation;                ///< of `parameters` (identity where unknown)
  std::vector<double> initial_deflections;    ///< estimated delta_i(0) [m]
  std::string initial_state = "estimated";
  std::string criterion = "BIC";
  std::vector<SelectionRow> selection;  ///< the order-selection table
  std::vector<StartLog> starts;         ///< log of the starts and the global stage
  std::vector<std::string> warnings;
  ConvergenceSummary convergence;
  double seconds = 0;
  double displacement_resolution = 0;  ///< q [m]
  double largest_travel = 0;           ///< L [m]
  double presliding_travel = 0;        ///< [m]
};

/// Displacement resolution q of a record (see the header comment) [m].
double displacement_resolution(std::span<const double> x);

/// q of the displacement as measured when the models see its local-polynomial estimate (the
/// `displacement_resolution` option of NLR, LG and DNLRX); 0 when the record holds the displacement
/// as measured (the identification then takes q from it) or it never moves.
double record_resolution(const Record& r);

/// Indices of the turning points of x, detected with hysteresis h [m] (a reversal counts once x
/// has come back by more than h from its extreme, so noise does not make reversals): the first
/// sample, every extreme, and the last sample.
std::vector<std::size_t> turning_points(std::span<const double> x, double h);

/// Largest travel L = (max x - min x) / 2 [m].
double largest_travel(std::span<const double> x);

/// Travel after a reversal at which the force has covered `fraction` of its swing, on the
/// segment between reversals with the largest force swing [m] (see the header comment).
double travel_at_force_fraction(std::span<const double> x, std::span<const double> force,
                                double fraction);

/// BIC = N ln(RSS / N) + p ln N, the criterion of every order selection here.
double bayesian_information_criterion(double rss, std::size_t samples, std::size_t parameters);

}  // namespace friction
