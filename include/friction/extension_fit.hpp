// Fitting a Maxwell Slip model together with extension pieces of methods.md section 7
// (extensions.hpp) to one record: the machinery that `diagnose` uses for every candidate and that
// `identify --extensions` uses for the pieces a user asks for.
//
// Parameters.  theta = [log k_i (M), log Delta_i (M), the pieces' parameters in
// ExtensionParameters::for_each_parameter order], and the relative initial deflections
// rho_i = delta_i(0) / Delta_i in [-1, 1], estimated from the same record (methods.md 2: the
// initial state is unknown on every record and is estimated the same way for every method), and
// with a frictional-lag piece the lag's initial offset after them (extended_state_size).
// Stiffness and threshold are log-parametrised, which keeps them positive without bounds; the
// thresholds are boxed inside [q, L] (displacement resolution, largest travel) as NLR keeps them,
// because an operator beyond the travel with a large initial deflection acts as a free offset.
//
// Solver.  Ceres Levenberg-Marquardt with forward-mode derivatives through
// Extended<MaxwellSlip<Jet>> and simulate_extended (the discrete recursion is piecewise linear in
// the states, so they are exact wherever they exist), taken from the model's structure: the pieces
// once with Jets of their own parameters, then each operator alone (extension_fit.cpp,
// StructuredSlipCost; the same Jacobian as through the whole model, to rounding:
// extended_slip_jacobian below).  Extension parameters are boxed (extension_parameter_bounds) to
// their physical domain, e.g. a stribeck_velocity between 1e-6 and 10 times the largest speed in
// the record.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "friction/extensions.hpp"
#include "friction/identification.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/record.hpp"

namespace friction {

/// Entries of the initial state of an extended Maxwell Slip model on M operators: the relative
/// deflections rho_i, then, with a frictional-lag piece, the lag's offset u = v_l(t_0) - v(t_0)
/// [m/s] (extensions.hpp).  The lag's memory of the motion before the record is as unknown as the
/// operators' deflections: started in step with the motion (u = 0), a record cut from longer
/// motion shows the transient sigma2 u exp(-t/tau), which a fit otherwise absorbs by bending
/// sigma2 and tau (on the discovery study's told records, 2.6 to 77 times the noise RSS).
inline std::size_t extended_state_size(std::size_t operators,
                                       const ExtensionParameters<double>& ext) {
  return operators + (ext.frictional_lag ? 1 : 0);
}

/// The record's duration t_N - t_1 [s], at least 1e-12: the time scale of the pieces' boxes (drift,
/// delay), the same in every fit and report.
double record_duration(const Record& r);

/// The record's largest interval speed |x_k - x_{k-1}| / (t_k - t_{k-1}) [m/s], at least 1e-12: the
/// speed scale of the pieces' boxes.
double largest_interval_speed(const Record& r);

/// The box |u| <= 2 v_max of the lag's offset on a record (v_max its largest interval speed):
/// v_l and v both lie within the speeds of the motion.
double lag_offset_bound(const Record& r);

/// One fitted parameter of a piece, in the model's own F0 (covariance_report.hpp).
struct ExtensionEstimate {
  Effect effect{};
  std::string name;  ///< methods.md 7 name ("viscous", "static", "mass", ...)
  std::string unit;  ///< SI
  double value = 0;
  double standard_error = 0;  ///< 0 when not available (at a bound, rank-deficient covariance)
  bool at_bound = false;
  bool available = false;           ///< has a standard error
  double lower95 = 0, upper95 = 0;  ///< 95 % interval (pieces are fitted linearly: symmetric)

  /// Neither a standard error nor a bound to explain its absence: the parameter trades off with
  /// others on the record (a rank-deficient covariance).  The documents write null for it and the
  /// tool warns; at a bound the 0 beside at_bound says why.
  bool uncertainty_unknown() const { return !available && !at_bound; }
};

/// "effect.name, effect.name, ..." of the estimates whose uncertainty_unknown(), in their order;
/// empty when there is none.
std::string pieces_of_unknown_uncertainty(const std::vector<ExtensionEstimate>& estimates);

/// Residuals (F - Fhat) * scale of `model`'s free run on the record, from the state the model
/// holds, handed to visit(k, residual_k) in sample order: the loop of every extension cost
/// functor (Maxwell Slip in extension_fit.cpp, the other bases in extension_families.hpp), whose
/// Jacobian rows are then handed over a sample at a time (src/streamed_autodiff_cost.hpp).  The
/// record is streamed (for_each_extended_step): nothing of its length is allocated per evaluation
/// (the filter's cache, one per thread, aside).
template <class Model, class Visit>
void visit_extended_residuals(Model& model, const Record& r, double scale,
                              const DerivativeWindows& windows, Visit&& visit) {
  using T = typename Model::Scalar;
  for_each_extended_step(
      model, std::span<const double>(r.time), std::span<const double>(r.displacement),
      std::span<const double>(r.normal), &windows,
      [&](std::size_t k, const auto&, const T& force) {
        visit(k, T((T(r.force[k]) - force) * scale));
      },
      std::span<const double>(r.measured_displacement));
}

/// Free run of an extended Maxwell Slip model in double, with the regime of every sample (the
/// context is built exactly as simulate_extended builds it; tests compare the two).
struct ExtendedSlipRun {
  std::vector<double> force;
  std::vector<char> sliding;
  std::vector<double> velocity, acceleration;  // of the (shifted) record
};

/// Sets an extended Maxwell Slip model's initial state from deflections_from_relative's vector:
/// the M deflections (at level 1), then the lag's offset when there is one.
template <typename T>
void set_extended_slip_state(Extended<MaxwellSlip<T>>& model, std::span<const T> initial) {
  const std::size_t m = model.base().parameters().size();
  model.base().reset(initial.first(std::min(initial.size(), m)), model.asymmetry());
  if (initial.size() > m) model.set_initial_lag_offset(initial[m]);
}

/// `initial`: deflections_from_relative's M deflections, then the lag's offset when there is one.
ExtendedSlipRun run_extended_slip(const MaxwellSlipParameters<double>& base,
                                  const ExtensionParameters<double>& ext,
                                  std::span<const double> initial, const Record& r);

/// The record's scales that the profiles' ranges follow from (effect_table.hpp), from the record
/// and a free run of the current model on it (its sliding regime and its velocities at t_k).
ProfileScales profile_scales(const Record& r, const ExtendedSlipRun& run, double reference_force);

/// Where a fit starts (effect_table.hpp, Profiles): the best point of the grid of `profiled`'s
/// nonlinear parameters, with the stiffnesses and every added term of `ext` (viscous, offset,
/// mass) solved by bounded least squares at each point (k, viscous, mass >= 0), the thresholds and
/// the initial deflections held: `rho`, relative to the slip limits at `rho_level` (the first level
/// of the model it comes from; extensions.hpp, Initial state), so that every grid point starts from
/// that model's operators.  A normal-load piece is set to its derived mu.  Without axes (an added
/// term) it is the projection alone.  `told`: the piece was asked for (identify --extension), and
/// a position-dependence piece is also started from a fine linearised scan of its wavelength
/// (extension_profile.cpp: position_scan), which the diagnosis does not run.
struct ProfiledStart {
  MaxwellSlipParameters<double> base;  ///< stiffnesses solved, thresholds as given
  ExtensionParameters<double> ext;     ///< the best point, added terms solved
  double rss = 0;                      ///< at the best point [N^2]
  std::size_t points = 0;              ///< grid points evaluated
};
ProfiledStart profile_start(const Record& r, const MaxwellSlipParameters<double>& base,
                            const std::vector<double>& rho, double rho_level,
                            const ExtensionParameters<double>& ext, Effect profiled,
                            const DerivativeWindows& windows, const ProfileScales& scales,
                            bool told = false);

/// Box of one extension parameter during a fit (f0 the reference force, duration of the record,
/// vmax its largest speed).
struct ExtensionBounds {
  double lower, upper;
};

ExtensionBounds extension_parameter_bounds(Effect e, std::string_view name, double f0,
                                           double duration, double vmax);

/// Result of fit_extended_slip: parameters, relative initial deflections and the RSS [N^2].
struct ExtendedSlipFit {
  MaxwellSlipParameters<double> base;
  std::vector<double> rho;  ///< extended_state_size entries: M deflections, then the lag's offset
  ExtensionParameters<double> ext;
  double rss = 0;
  bool ok = false;
  /// Piece parameters the fit left on a finite edge of their box (effect, methods.md 7 name).
  std::vector<std::pair<Effect, std::string>> at_bound;
};

/// Fits theta and rho from the given start (see the header comment); `fix_theta` estimates the
/// initial state only.  `ok` is false when Ceres found no usable solution (rss is then infinite).
ExtendedSlipFit fit_extended_slip(const Record& r, const MaxwellSlipParameters<double>& base0,
                                  const std::vector<double>& rho0,
                                  const ExtensionParameters<double>& ext0, bool fix_theta,
                                  int max_iterations);

/// The residuals (F - Fhat) / rms(F) of fit_extended_slip's cost at (base, rho, ext) on `r` and its
/// Jacobian with respect to theta = [log k, log Delta, pieces] and to rho, by the evaluation the
/// fit uses (the structured one of extension_fit.cpp when it applies: `structured`) or, with
/// `whole_model`, by forward-mode derivatives through the whole model.  For tests and diagnostics;
/// ok is false outside the parameters' domain.
struct ExtendedSlipJacobian {
  Eigen::VectorXd residual;
  Eigen::MatrixXd theta, rho;
  bool structured = false;
  bool ok = false;
};
ExtendedSlipJacobian extended_slip_jacobian(const Record& r,
                                            const MaxwellSlipParameters<double>& base,
                                            const std::vector<double>& rho,
                                            const ExtensionParameters<double>& ext,
                                            bool whole_model);

/// The pieces with the parameters that refer to F0 (effect table: `static`, `amplitude`,
/// `friction_coefficient`) converted from the fit's fixed reference force (ext.reference_force) to
/// `own_f0`, the sliding force of the fitted base, with reference_force 0: what a saved model uses.
ExtensionParameters<double> to_own_reference(const ExtensionParameters<double>& ext, double own_f0);

/// The factor to_own_reference multiplies those parameters by (1 without a reference force).
double own_reference_ratio(const ExtensionParameters<double>& ext, double own_f0);

/// Standard errors and 95 % intervals of a joint fit at its optimum on the record `r` it was
/// fitted on: the covariance (extension_identification.hpp, 3) of theta = [log k, log Delta,
/// pieces] with the relative initial deflections as nuisance parameters (those at +-1 held),
/// through covariance_report.hpp.
/// Parameters at a bound of their box have no standard error; a rank-deficient J^T J gives none.
struct ExtendedSlipReport {
  std::vector<ExtensionEstimate> pieces;  ///< in the model's own F0, symmetric intervals
  std::vector<ParameterEstimate> base;    ///< stiffness[i], threshold[i]: log-normal intervals
  Eigen::MatrixXd correlation;            ///< of [base, pieces]
  bool rank_deficient = false;
};
ExtendedSlipReport report_extended_slip(const Record& r, const ExtendedSlipFit& fit);

/// delta_i(0) = (rho_i + a) Delta_i: rho_i in [-1, 1] relative to the centre a Delta_i of operator
/// i's box, a the asymmetry of `ext` (0 without one; extensions.hpp); with a frictional-lag piece
/// the lag's offset u follows as entry M (run_extended_slip's `initial` takes it there).  These are deflections at
/// level 1: the model's first step scales them by its level (extensions.hpp, Initial state), so
/// the deflections at the record's first sample are first_level times these.
std::vector<double> deflections_from_relative(const MaxwellSlipParameters<double>& base,
                                              const std::vector<double>& rho,
                                              const ExtensionParameters<double>& ext);

/// The level an extended Maxwell Slip model hands its base at the record's first sample (1 without
/// a level piece): the factor its initial state is scaled by (extensions.hpp, Initial state).
/// `windows`: the record's derivative windows when the caller has them (record_derivative_windows
/// otherwise chooses them again, most of this function's cost).
double first_level(const MaxwellSlipParameters<double>& base,
                   const ExtensionParameters<double>& ext, const Record& r,
                   const DerivativeWindows* windows = nullptr);

/// The state `rho` of a model (from_base, from_ext) as the relative state of another model on the
/// same operators (to_base, to_ext): the same deflections at the record's first sample, clamped to
/// the new model's limits there.  A fit that adds or changes a level piece starts from the
/// operators of the model it comes from, not from ones stretched by the new first level.
std::vector<double> carried_state(const Record& r, const MaxwellSlipParameters<double>& from_base,
                                  const ExtensionParameters<double>& from_ext,
                                  const std::vector<double>& rho,
                                  const MaxwellSlipParameters<double>& to_base,
                                  const ExtensionParameters<double>& to_ext,
                                  const DerivativeWindows* windows = nullptr);

/// The plain Maxwell Slip estimate of the relative initial state (initial_state.hpp) on the force
/// without the pieces' added terms and the asymmetry's shift: the start of every refinement.
std::vector<double> plain_relative_state(const MaxwellSlipParameters<double>& base,
                                         const ExtensionParameters<double>& ext, const Record& r);

/// The initial state of a record for fixed parameters: the plain Maxwell Slip estimate
/// (initial_state.hpp) as a start, refined through the extended model; never worse than its
/// start.  `rss` receives the resulting RSS when not null.
std::vector<double> estimate_relative_deflections(const MaxwellSlipParameters<double>& base,
                                                  const ExtensionParameters<double>& ext,
                                                  const Record& r, double* rss);

}  // namespace friction
