// Identification with requested extension pieces: `identify --model TYPE --extension NAME ...`.
//
// A user who knows (or suspects) that a record holds effects of methods.md section 7 asks for them
// by name; the base model is identified by its own method (methods.hpp) and the pieces of
// extensions.hpp are then estimated on the same record.  Nothing here decides WHETHER an effect is
// present (that is `diagnose`): every requested piece is fitted and kept, and the report says how
// strongly the record supports it.
//
// 1. Maxwell Slip base (NLR).  The base and all requested pieces are refitted jointly with
//    fit_extended_slip (extension_fit.hpp): theta = [log k_i, log Delta_i, piece parameters], the
//    relative initial deflections rho_i estimated with them.  Each piece starts from the residual
//    evidence of the current model (analyse_residual / extension_start of diagnose.hpp, the
//    effect table's start_from_evidence: the regression coefficient of the effect's signature,
//    the best point of its grid, the lag of the cross-correlation).  During the fit the level
//    pieces refer to the fixed F0 of the NLR model (a common scale of the thresholds stays
//    identifiable); `static`, `amplitude` and `friction_coefficient` are converted to the fitted
//    model's own F0 at the end, which is what a saved model uses.
//
//    Restart.  The NLR base was identified on a force that holds the effects, and a local refit
//    from it can keep its distortion: with a Stribeck level and an offset together the joint fit
//    stalled at 0.098 % (sequential) / 0.16 % (joint) against a noise floor of 0.0031 %.  So, after
//    the first fit, NLR is run again (order selection and global stage as the user asked for the
//    base) on the force with the fitted pieces taken out -- added terms subtracted, divided by the
//    level along the fitted model's run -- and the joint fit repeated from that base; it is kept
//    when its BIC is lower (M may differ).  That took the case above to 0.0029 %.  The price is a
//    second NLR identification (on a 6741-sample `generate` record with viscous 40 N s/m and an
//    offset of 0.05 N the pieces, restart included, took 4.3 s of the 12.7 s that identify took).
//    A restart that was kept is repeated from its own pieces, while BIC falls (twice at most):
//    the first one's force still carries the sequential pieces' errors, and a piece off by about
//    one noise sigma was enough for NLR to merge two operators of close thresholds.  A joint fit
//    of the restart serves only if it ends at a lower BIC than the fit it restarts, so it is
//    stopped when, at the pace of its last ten iterations, its remaining budget would not take it
//    there (the rule that stops NLR's hopeless starts): on data/ the restart after the diagnosis's
//    second finding made two fits of 57 iterations that ended at 2.2 times the RSS to beat.
//
//    Order growth.  The restart's order selection runs on a corrected force, and dividing by the
//    level is exact only for operators at their slip limits: an operator that sticks while the
//    level changes (a normal force that varies in presliding) keeps its force.  So BIC on that
//    force can stop short: on a discovery-study record with a varying normal force (11 elements,
//    envelope excitation) it chose 4 operators, and the joint fit validated at 5.6 times the
//    floor, where the joint fit at 6 operators reaches it.  Unless the user fixed M, the restart
//    is therefore followed by growth: NLR at M + 1 on the force without the current pieces, the
//    joint fit from that base, kept while its own BIC (the joint model's, the criterion that
//    counts) falls, up to max_operators when the user gave one, else `operator_limit`: the
//    pieces are in the criterion here, and a record of more elements than NLR's first range
//    (1..8) left them paying for the missing ones (a delay 3 % short, 3.7 standard errors, on a
//    discovery-study record of 12 elements; README, "Growth past NLR's first range").  NLR's own
//    selection keeps its range: without the pieces its criterion kept falling where operators
//    soaked up an effect (10 operators for a system of 8 with a lag and a Stribeck curve, which
//    the diagnosis then named as a position term).  A delay is taken out as well: the operators
//    see the displacement at t - D.  `diagnose` grows only in its final polish (its restarts run
//    once per accepted finding, and growth costs an NLR fit per step).
//
//    Order.  `sequential` (the default) adds the pieces one at a time, the one whose signature
//    explains most of the current residual first, refitting everything at each step and
//    recomputing the evidence after it; `joint` starts every piece from one evidence of the NLR
//    model and fits them all at once.  Measured on pairs of effects written into 4000-sample
//    records (tests/test_extension_identification.cpp, DISABLED_MeasureSequentialAgainstJoint;
//    4 operators, noise 2 mN, estimation RSS/SSS %, noise floor 0.003-0.004 %):
//                           with the restart          without it
//                           sequential   joint        sequential   joint
//      viscous + offset     0.00363      0.00363      0.00363      0.00363
//      stribeck + inertia   0.00302      0.00303      0.00302      0.00303
//      asymmetry + viscous  0.00554      0.00554      0.00548      0.00548
//      drift + offset       0.00326      0.00326      0.00326      0.00326
//      position + inertia   0.00380      0.00380      0.00380      0.00380
//      stribeck + offset    0.00291      0.00291      0.098        0.162
//    and 0.2-1.2 s per identification either way.  With the restart the two orders end alike;
//    without it sequential was never worse and much better once, so it stays the default (the
//    restart starts from the first fit's pieces).
//
// 2. LuGre (LG) and DNLRX bases.  First the pieces and the initial state (z0 for LuGre, the
//    deflections for DNLRX) are fitted with the base parameters HELD at their estimate, by Ceres
//    (Levenberg-Marquardt, automatic derivatives through Extended<LuGre<Jet>> /
//    Extended<Dnlrx<Jet>> and simulate_extended; the LuGre exact step is a template), the pieces
//    started from regressions of the base's residual on each effect's signature
//    (start_from_regression of effect_table.hpp, with the one Stribeck start grid).  Then
//    (refit_base, the default) everything is refitted together from there: DNLRX filters in N/m and
//    log thresholds in [q, L], coefficients its identification dropped for rank deficiency kept at
//    0; the seven LuGre parameters in SI, boxed to their domain, a sigma1 or sigma2 left at 0 kept
//    at 0.  The joint result is kept when it lowers the RSS, and `base` in the report says which
//    ("refitted jointly" or "held").  Holding alone is not enough: a base identified on a force
//    that holds the effect has absorbed part of it.  Measured on a 4-operator record with an offset
//    of 0.02 N (4000 samples, noise 2 mN): DNLRX (n = nx = 0) alone 0.275 %; held 0.0669 %, offset
//    0.0153 N; joint 0.00363 %, offset 0.0200 N.  A LuGre system with an offset of 0.1 N: LG alone
//    0.434 %, joint 0.00116 %, offset 0.10006 N.  (A LuGre base on a Maxwell Slip record cannot
//    separate an offset from its structural misfit: 0.040 N for a true 0.02 N -- methods.md 8 on
//    what LuGre cannot represent.)
//
//    Combinations that duplicate what the base already has are refused (InvalidParameter):
//      lugre: viscous (sigma2), stribeck (Fs, vs, mu) and frictional-lag (the bristle dynamics,
//             and the lag acts through the viscous/Stribeck pieces the base already holds);
//      dnlrx: viscous (its input filter is sum_j g_j dx(t-j) = (sum_j g_j) Ts v at constant
//             speed), and frictional-lag without stribeck (the lag needs a velocity piece).
//    On a Maxwell Slip base, frictional-lag without viscous or stribeck brings a viscous companion
//    (it would have no effect alone) and says so.
//
// 3. Report.  Every piece's parameters in SI with the names of methods.md 7, and standard errors
//    (through covariance_report.hpp, in the parametrisation each parameter is fitted in: log-normal
//    intervals for log k, log Delta and DNLRX's log Delta, symmetric for the pieces, the DNLRX
//    filters and the LuGre parameters, which are refitted in SI) from the covariance at the
//    optimum of the final fit: the sandwich s^2 (J^T J)^-1 (J^T R J) (J^T J)^-1 of an AR(1)
//    residual, s^2 = RSS / (N - p) (the Gauss-Newton s^2 (J^T J)^-1 when the residual is white),
//    each variance raised to that of the block scores where larger (noise_colour.hpp),
//    over the free parameters (the base's when it was refitted, and the initial state), J the
//    Jacobian of the free-run residuals (automatic derivatives).
//    Parameters sitting at a bound of the fit are left out (their standard error is 0: not
//    available).  When J^T J is rank deficient (eigenvalues of the column-scaled matrix below
//    1e-12 of the largest) the parameters with a part in those null directions (sum of their
//    squared components over the null eigenvectors >= 1e-6) get no standard error, the others
//    theirs from the pseudo-inverse (exact for estimable parameters), and a warning names the
//    pieces' parameters left without one; never NaN.  The residual of a free run holds the
//    model's misfit where it is imperfect; the block scores see the part of it that varies along
//    the record, not a bias the whole record shares, so the errors can still be too small there.
//    A piece is "not supported by the record" (warning "the record gives no evidence of <effect>")
//    when its main parameter (viscous, static - F0, lag_time, asymmetry, offset, mass, amplitude,
//    relative_rate, delay) is within 2 standard errors of its null value or ends at the bound that
//    is its null value (viscous = 0, mass = 0).  normal-load has no null value (mu only rescales
//    the level) and is not tested.  A normal-load request on a record without a normal-force column
//    is a DataError (exit 1 in the CLI).
//
// 4. Initial state and the error figures.  The estimation error reported is that of a free run of
//    the final model from an initial state estimated on the record with every parameter fixed
//    (free_run_extended): the base's plain estimator (estimate_initial_deflections for Maxwell
//    Slip, free_run_dnlrx's for DNLRX, estimate_lugre_initial_state for LuGre) gives a start, and
//    that start, the relaxed state 0 and half the start are each refined through the extended
//    model by Ceres; the best is kept.  Several starts because an operator that the plain estimate
//    puts at its threshold and that saturates at once has no gradient to leave it by: with the
//    plain start alone, the Stribeck test record scored 0.0225 % where the joint fit's own state
//    gave 0.0029 %; with the three starts 0.0029 %.  `validate --model-file` scores a saved
//    extended model by exactly this procedure, so it reproduces the identify figure on the
//    estimation record.  (`simulate --model-file` starts from rest, as for every model.)
//
// Files: the model families, their fit and covariance in src/extension_families.hpp; the Maxwell
// Slip path (1) in src/extension_identify_slip.cpp; the held LuGre / DNLRX path (2) in
// src/extension_identify_held.cpp; the report (3) and the free run (4) in
// src/extension_identification.cpp.
#pragma once

#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "friction/extension_fit.hpp"
#include "friction/extensions.hpp"
#include "friction/identification.hpp"
#include "friction/metrics.hpp"
#include "friction/model_io.hpp"
#include "friction/record.hpp"

namespace friction {

/// How the pieces are added to a Maxwell Slip base (see the header comment).
enum class ExtensionOrder { sequential, joint };

struct ExtensionFitOptions {
  ExtensionOrder order = ExtensionOrder::sequential;
  int max_iterations = 60;        ///< Ceres iterations per fit
  double evidence_sigmas = 2.0;   ///< |main - null| below this many standard errors: no evidence
  bool refit_base = true;         ///< LuGre / DNLRX: refit the base with the pieces (comment, 2)
  bool restart_base = true;       ///< Maxwell Slip: restart from NLR on the corrected force (1)
  std::size_t operators = 0;      ///< the restart's M (0: selected by BIC up to max_operators)
  std::size_t max_operators = 0;  ///< 0: NLR's default
  bool global_stage = false;      ///< the restart's NLR global stage
  /// After the restart, M grows one operator at a time while the joint fit's BIC falls (1).
  bool grow_operators = true;
  /// The largest M the growth reaches when max_operators is 0 (1).
  std::size_t operator_limit = 32;
  /// With a level piece that changes along the record (stribeck, position-dependence, drift,
  /// normal-load), the restart also runs NLR with the operators under the pieces' level (their
  /// slip limits scaled per sample), beside NLR on the force divided by the level, and keeps the
  /// joint fit with the lower BIC.  On the told-the-effect records of the discovery study at four
  /// seeds (21, 22, 17, 22 eligible records) it passes 70 of 82 against 69 with the division
  /// alone and 68 under the level alone: each fixes Stribeck records the other misses.
  bool base_under_level = true;
  /// The restart's NLR fits on different forces (divided by the level, under it, each with and
  /// without the dictionary's viscous take-out) are independent: they run on this many threads
  /// (0: one per core), each into its own slot, compared in a fixed order afterwards, so the
  /// result does not depend on it.
  unsigned threads = 1;
};

/// What identify_extensions returns.
struct ExtensionIdentification {
  explicit ExtensionIdentification(AnyModel m) : model(std::move(m)) {}
  AnyModel model;                                  ///< the extended model (own F0)
  std::vector<ExtensionEstimate> estimates;        ///< every piece's parameters
  std::vector<ParameterEstimate> base_parameters;  ///< refitted base (Maxwell Slip only)
  /// Correlation of [base_parameters, estimates] (identity where unknown).
  Eigen::MatrixXd correlation_matrix;
  std::vector<Effect> order;             ///< order in which the pieces were added
  std::vector<Effect> without_evidence;  ///< pieces the record does not support
  ErrorMetrics estimation;               ///< free run, initial state estimated
  std::vector<double> simulated;         ///< that free run [N]
  Json initial_state;                    ///< {"kind": "estimated", "values", "unit"}
  std::vector<double> initial_values;    ///< the estimated initial state
  double base_estimation_percent = 0;    ///< the base alone, RSS/SSS %
  double fit_rss_sss_percent = 0;        ///< the final fit's own figure (joint state)
  bool base_held = false;                ///< LuGre / DNLRX: base parameters held
  bool restarted = false;  ///< Maxwell Slip: the restart from the corrected force was better
  std::vector<std::string> warnings;
  double seconds = 0;
  /// {"base": "refitted jointly" | "held", "order": [...], "pieces": {effect: {param: {value,
  /// unit, standard_error, at_bound}}}, "no_evidence": [...], "estimation_before", ...}
  Json to_json() const;
};

/// The pieces' estimates as the documents show them: {effect: {param: {value, unit,
/// standard_error, at_bound}}}: standard_error null when its uncertainty is unknown
/// (ExtensionEstimate::uncertainty_unknown), 0 beside at_bound true at a bound.
Json pieces_to_json(const std::vector<ExtensionEstimate>& estimates);

/// The section 7 names, comma-separated, for messages.
std::string extension_names();

/// Parses NAME or NAME,NAME,... into effects (duplicates dropped, order kept).  Throws
/// InvalidParameter naming the accepted names for an unknown one.
std::vector<Effect> parse_extension_list(const std::vector<std::string>& names);

/// Throws InvalidParameter for a combination the base type cannot carry (header comment, 2) and
/// DataError for normal-load on a record without a normal force.  Called before the base is
/// identified, so that a bad request fails at once.
void check_extension_request(const std::string& type, const std::vector<Effect>& effects,
                             const Record& record);

/// Fits the requested pieces on top of an identified base model (plain, no pieces) on the record
/// it was identified on.  `base_simulated` is the base's free run on the record (its estimation
/// run) and `base_initial` its estimated initial state (deflections, or z0 for LuGre).
ExtensionIdentification identify_extensions(const AnyModel& base, const Record& record,
                                            const std::vector<double>& base_simulated,
                                            const std::vector<double>& base_initial,
                                            const std::vector<Effect>& effects,
                                            const ExtensionFitOptions& options = {});

/// Free run of a model carrying pieces (Maxwell Slip, DNLRX or LuGre base) from an initial state
/// estimated on the record with every parameter fixed (header comment, 4).
struct ExtendedFreeRun {
  std::vector<double> simulated;
  std::vector<double> initial;  ///< deflections [m] or z0 [m]
  /// With a frictional-lag piece: its estimated offset u = v_l(t_0) - v(t_0) [m/s]
  /// (extension_fit.hpp, extended_state_size).
  std::optional<double> lag_offset;
  /// {"kind": "estimated", "values": initial, "unit": "m"}, and "lag_offset" [m/s] with a lag.
  Json to_json() const;
};
ExtendedFreeRun free_run_extended(const AnyModel& model, const Record& record);

/// SI unit of a piece parameter of methods.md 7 ("N s/m", "N", "m/s", "s", "kg", ...).
std::string extension_parameter_unit(std::string_view name);

}  // namespace friction
