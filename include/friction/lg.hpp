// LG: identification of the seven LuGre parameters from one displacement-force record (Rizos &
// Fassois 2005; methods.md sections 1, 2, 6 and 8).
//
// Model: LuGre (lugre.hpp, paper eqs. 1-3) driven by the piecewise-constant backward-difference
// velocity of the record (motion.hpp), from an initial bristle deflection z0 estimated with the
// parameters.  Parameters theta = (sigma0, sigma1, sigma2, Fc, Fs, vs, mu) are optimised as
// log(theta): all are positive, their scales span ten decades (sigma0 ~ 1e5 N/m, vs ~ 1e-3 m/s),
// and a relative step is what the data resolve.  The initial state is z0 = u * z_ref, u bounded
// to [-1.5, 1.5] and z_ref = max(Fc, Fs) / sigma0, the largest deflection reachable from rest.
//
// 1. Data-driven start (`lugre_start`).  The record is cut at its reversals (turning points of x
//    with a hysteresis of max(3 q, 1e-4 range), q the displacement resolution).  On each segment
//    between reversals, with dir = sgn of its travel, g(t) = dir (F(t) - F(reversal)) rises by the
//    swing S.  A segment *slides* when the force over the second half of its travel stays within
//    25 % of S (a plateau; a presliding-only loop keeps rising, covering ~50 % there); its
//    *sliding samples* are those past 1.5 times the travel at which g first reached 95 % of the
//    breakaway B, the largest g over the first half of the travel (not of S: slowing into the
//    next reversal, friction climbs the Stribeck curve again, and with S the transient of a fast
//    stroke seemed to last to its end).  Sliding speeds are summarised by percentiles weighted
//    by travel (each sample by its |dx|), so that a fast stroke counts as much as a slow one of
//    the same length although it has fewer samples: `slowest` / `fastest_sliding_speed` are the
//    5th / 95th.  The median of dir F over sliding samples must be positive (else the force
//    pushes the motion: the record is in the other sign convention, and the message says so).
//      * Fc, sigma2: a straight line dir F = Fc + sigma2 |v| fitted by least squares to the sliding
//        samples in the upper third (by travel) of the sliding speeds (where the Stribeck dip has
//        died out).  The line is used only when (a) the speeds of the fit vary by more than their
//        noise (standard deviation > 2 q / Ts, q the displacement resolution, Ts the median
//        sampling period; else the record slides at one speed, `one_speed`), (b) the slope
//        exceeds twice its standard error and (c) the line meets v = 0 at a positive level.
//        Otherwise (one speed, the Stribeck dip not yet over, viscous friction lost in the
//        noise) Fc is the median level of those samples and sigma2 starts at 1 % of Fc / vmax (a
//        positive start for a log parameter).  At one speed sigma2, Fs, vs and mu cannot be
//        separated from Fc (a real single-speed tribometer record made sxx ~ 0 and the line's
//        intercept -1.2e9 N): a warning says so, as it does whenever vmax < 3 vmin.
//      * Fs observed: the larger of the level dir F - sigma2 |v| of the slowest 10 % of sliding
//        samples and the median over sliding segments of their force peak (breakaway), at least
//        1.01 Fc.  Both fall short of Fs when the record leaves presliding at speeds above vs.
//      * Fs, vs: the static curve Fc + (Fs - Fc) w(v; vs, mu = 2) fitted by least squares to the
//        sliding levels dir F - sigma2 |v|: vs on a log grid (61 points from a tenth of the
//        slowest to 3 times the fastest sliding speed), Fs - Fc by linear least squares for each,
//        with Fs kept between the observed Fs and twice it.
//      * sigma0, sigma1: on segments that start from sliding (the previous one slid), a pooled
//        least-squares regression (each segment with its own intercept) of dir F on the travel
//        from the reversal u and the speed |v|, over the travel until g covers f = 30 % of S.
//        Leaving steady sliding the bristles go from -s to +s with dz/dx = 1 + |z|/s, so the
//        coefficients are about -2 f / ln(1 - f) = 1.68 times sigma0 and sigma1 (LuGre's
//        stiffness right after a reversal from sliding is 2 sigma0, not sigma0), and are divided
//        by it.  The speed term matters: near a reversal sigma1 dz/dt grows like sqrt(u) and
//        would otherwise inflate the slope.  Without such segments (or with a singular or
//        non-positive fit) sigma0 is the median chord slope dF/dx of all segments (presliding
//        loops, dz/dx ~ 1).
//      * sigma1 when the regression gives none: a damping argument, sigma1 dz/dt taken as 10 % of
//        Fs at the typical presliding speed v_p (median |v| over the samples before g reaches
//        95 % of S), sigma1 = 0.1 Fs / v_p.  The global stage searches 4.5 decades around it.
//      * mu = 2 (both shapes); z0 for these parameters by `estimate_lugre_initial_state`.
// 2. Global stage: a controlled random search with local mutation (CRS2-LM, the algorithm of
//    NLopt's GN_CRS2_LM with the search's own generator, seeded by LgOptions::seed) over
//    the box of (log theta, u); the box is derived from the start (sigma0 x/÷ 10, sigma1 1e-3..30x,
//    sigma2 from 1e-4 Fc / vmax to max(3 sigma2, Fc / vmax), Fc and Fs x/÷ 3, vs from a tenth of
//    the slowest to ten times the fastest sliding speed, mu in [0.3, 6]).  Its objective is the
//    free-run RSS/SSS % with the exact step (`LuGre<double>`), its transitions shared between
//    samples whose motions repeat or, when few do, interpolated over the speed
//    (`LgOptions::memoise_steps`): 20-70 microseconds per evaluation for 10,000 samples, a few
//    hundred stepping every sample.  The data-driven
//    start and the CRS2 optimum are each polished by NLopt's BOBYQA (derivative-free,
//    deterministic, same objective, 1500 evaluations); both are logged in `report.starts`, with
//    `distinct` set when a minimum differs by more than one percent from every earlier one.  The
//    polish is cheap where the local stage is not: one CVODES Jacobian costs as much as ~2000
//    exact-step evaluations, and with 400 BOBYQA evaluations Ceres still needed 6-11 Jacobians on
//    sigma0 = 1e6 records, with 1500 it needs 1-2 (measured, 6000 samples).
// 3. Local stage: Ceres Levenberg-Marquardt from the best polished point, on the N residuals
//    (F - Fhat) / rms(F), with one parameter block of the 7 log-parameters and one for u, both
//    bounded by the same box.  Residuals come from the exact step (exact for the piecewise-
//    constant velocity); the iterations' Jacobian from autodiff through the exact step
//    (ceres::Jet, `LgJacobian::ExactStep`, the default) or from CVODES forward sensitivities
//    (`simulate_lugre_cvodes` with log_parameters, whose right-hand-side partials are autodiff).
//    A CVODES sensitivity run costs as much as ~150 exact-step Jacobians (`bench_lg`, 10,000
//    samples: 265 ms against 1.8 ms), and on the bench records the one or two it took per fit
//    were half of LG's time; so CVODES now checks the optimum (`LgOptions::cvodes_check`): one
//    sensitivity run there, its relative difference from the exact step's Jacobian in the
//    convergence message (1.5e-4 to 5e-4 on data/, the tribometer and the bench records; a
//    warning above 1e-2), and it is the Jacobian of the covariance.  After the local stage z0
//    is re-estimated by `estimate_lugre_initial_state`, the routine validation uses.
// 4. Report: parameters with units; standard errors from ceres::Covariance of log theta at the
//    optimum (z0 held at its estimate), scaled by RSS / (N - 8); 95 % intervals log-normal,
//    value * exp(+-1.96 se_log).  DENSE_SVD with a null-space tolerance: when J^T J is singular to
//    within 1e-14 the covariance is the pseudo-inverse, the parameters that carry the weakest
//    direction get standard error 0 (interval = the value) and a warning names them -- never a
//    NaN.  Warnings: near-singular problem (reciprocal condition number < 1e-10), a 95 % interval
//    spanning more than a factor 10, any pair correlated above 0.95, and the known trade-offs
//    named explicitly: Fs/vs and mu/sigma2 above 0.9 (methods.md 8: at the speeds of a presliding
//    record they are not identifiable); a parameter at its search bound; a record with little
//    sliding or a narrow range of sliding speeds; and an error far (> 3x) above the noise floor,
//    with the share of it in presliding: a single-state LuGre cannot reproduce multi-element
//    presliding hysteresis (nonlocal memory), so its error stays well above that of Maxwell Slip
//    models on such records however it is fitted.
//
// `report.starts` for LG: `operators` = 1 (one state); `start_thresholds` / `final_thresholds`
// (field names made for Maxwell Slip) hold the 7 parameters in to_array order followed by z0 [m].
// `report.initial_deflections` = {z0}.  `report.selection` has one row (7 parameters, the fitted
// model, its BIC).  `report.convergence.final_cost` is the free-run RSS/SSS % with the
// re-estimated z0.
#pragma once

#include <ceres/cost_function.h>

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "friction/identification.hpp"
#include "friction/lugre.hpp"
#include "friction/lugre_cvodes.hpp"
#include "friction/metrics.hpp"
#include "friction/motion.hpp"

namespace friction {

/// Where the local stage's Jacobian comes from.
enum class LgJacobian {
  Cvodes,     ///< CVODES forward sensitivities (default)
  ExactStep,  ///< autodiff (ceres::Jet) through the exact exponential step
};

/// CVODES settings of the LG Jacobian: sensitivities w.r.t. log(theta), 1e-5 relative (the
/// Jacobian only steers Gauss-Newton and the covariance), the library's other defaults.
inline CvodesOptions lg_default_cvodes() {
  CvodesOptions c;
  c.relative_tolerance = 1e-5;
  c.sensitivities = true;
  c.log_parameters = true;
  return c;
}

struct LgOptions {
  StribeckShape shape = StribeckShape::Rational;
  bool global_stage = true;       ///< CRS2-LM + BOBYQA polish before the local stage
  int global_evaluations = 0;     ///< CRS2 budget; 0 means 1500
  int polish_evaluations = 1500;  ///< BOBYQA budget per polished point
  unsigned seed = 1;              ///< seed of the global stage's own generator (reproducible)
  /// q [m] when > 0: the resolution of the displacement as measured (NlrOptions says why); 0:
  /// from the displacement given.
  double displacement_resolution = 0;
  int max_iterations = 50;  ///< Ceres iterations of the local stage
  /// Jacobian of the local stage's iterations.  ExactStep: autodiff through the exact step, the
  /// derivative of the very residuals minimised, at ~1/150 of the time of a CVODES sensitivity
  /// run (`bench_lg` BM_LgJacobian, 10,000 samples: 1.8 ms against 265 ms).  Cvodes: a CVODES
  /// run at every iteration.
  LgJacobian jacobian = LgJacobian::ExactStep;
  /// At the optimum one CVODES sensitivity run is compared with the exact step's Jacobian (the
  /// relative difference is in the convergence message; a warning above 1e-2) and is the
  /// Jacobian of the covariance.
  bool cvodes_check = true;
  /// CVODES settings for the Jacobian (sensitivities and log_parameters are forced on).
  CvodesOptions cvodes = lg_default_cvodes();
  bool covariance = true;  ///< standard errors and correlations
  /// The global stage computes each distinct motion's exact-step transition (velocity and
  /// interval equal to a relative 1e-9) once per run instead of once per sample (LuGre::Transition,
  /// carried as the decay of the state's excess over its steady deflection: the same numbers to
  /// rounding), or, when few motions repeat on a record sampled at one interval, interpolates them
  /// from a table over the speed (lugre_transition_table.hpp; the local stage and every reported
  /// figure use the exact step).  false steps every sample exactly, for checking.
  bool memoise_steps = true;
};

/// The data-driven start and the scales behind it (see the header comment, step 1).
struct LgStart {
  LuGreParameters<double> parameters;
  std::size_t segments = 0;          ///< segments between reversals
  std::size_t sliding_segments = 0;  ///< of which slide
  std::size_t sliding_samples = 0;
  double slowest_sliding_speed = 0;  ///< 5th percentile of |v| by sliding travel [m/s]
  double fastest_sliding_speed = 0;  ///< 95th percentile by sliding travel [m/s]
  double presliding_speed = 0;       ///< v_p [m/s]
  double velocity_noise = 0;         ///< q / Ts, one velocity quantum [m/s]
  /// The fastest third of the sliding speeds varies by no more than its noise (a single speed):
  /// no slope of force on speed can be fitted.
  bool one_speed = false;
  /// sigma2 and Fc from the line of force on speed (else Fc the median level, sigma2 small).
  bool viscous_from_slope = false;
  bool sigma0_from_sliding_reversals = false;
  std::vector<bool> presliding;       ///< per sample: before g reached 95 % of its breakaway
  std::vector<std::string> warnings;  ///< what the record cannot tell (copied into the report)
};

/// Where the time went (wall-clock seconds) and how often the Jacobian was computed.
struct LgTimings {
  double start = 0;              ///< data-driven start and its initial state
  double global = 0;             ///< CRS2 and the BOBYQA polishes
  double local = 0;              ///< Ceres
  double report = 0;             ///< free run, covariance, warnings
  int jacobian_evaluations = 0;  ///< of the local stage and of its CVODES check
  /// How the global stage computed its transitions (LgOptions::memoise_steps): "shared" (once
  /// per distinct motion, exact), "tabulated" (interpolated over the speed) or "exact".
  std::string global_transitions = "exact";
};

struct LgResult {
  LuGreParameters<double> parameters;  ///< the estimate
  double initial_state = 0;            ///< estimated z0 [m]
  LgStart start;                       ///< the data-driven start
  LgTimings timings;
  IdentificationReport report;
};

/// The data-driven start (step 1 of the header comment).  Throws InvalidParameter when the record
/// is unusable (lengths differ, fewer than 20 samples, no motion, zero force) or never slides
/// (presliding alone cannot determine Fc, Fs, vs, mu, sigma2).  `resolution`: q [m] of the
/// displacement as measured (LgOptions::displacement_resolution); 0: from x.
LgStart lugre_start(std::span<const double> time, std::span<const double> x,
                    std::span<const double> force, StribeckShape shape = StribeckShape::Rational,
                    double resolution = 0);

/// Identify the LuGre model from displacement `x` [m] and force [N] (model's sign convention)
/// sampled at `time` [s], strictly increasing.  Throws as `lugre_start`.
LgResult identify_lugre(std::span<const double> time, std::span<const double> x,
                        std::span<const double> force, const LgOptions& options = {});

/// z0 [m] minimising the free-run RSS of the model (exact step) against `force` over
/// [-1.5, 1.5] max(Fc, Fs) / sigma0.  The simulated force is affine in z0, so this is a linear
/// least-squares problem, solved in closed form from one run that carries d Fhat / d z0.  For
/// validation records: nothing but the initial state is estimated.
double estimate_lugre_initial_state(const LuGreParameters<double>& parameters,
                                    std::span<const double> time, std::span<const double> x,
                                    std::span<const double> force);

/// A free run of a LuGre model from an estimated initial state, and its errors.
struct LuGreFreeRun {
  double initial_state = 0;       ///< estimated z0 [m]
  std::vector<double> simulated;  ///< Fhat [N]
  ErrorMetrics errors;            ///< against `force`, every sample counted
};

/// Validation of a LuGre model with fixed parameters on a record (z0 estimated, then free run).
LuGreFreeRun free_run_lugre(const LuGreParameters<double>& parameters, std::span<const double> time,
                            std::span<const double> x, std::span<const double> force);

/// The local stage's cost function, exposed for tests: residuals r_k = (F_k - Fhat_k) / scale
/// (exact step), blocks {log theta (7, to_array order), u (1)} with z0 = u * z_ref; Jacobian as
/// chosen by `jacobian`.  The spans must outlive the object.  Returns false from Evaluate (a
/// rejected step for Ceres) when the simulation fails.
class LgCostFunction final : public ceres::CostFunction {
 public:
  LgCostFunction(std::span<const double> time, std::span<const double> x,
                 std::span<const double> force, double scale, double z_ref, StribeckShape shape,
                 LgJacobian jacobian, const CvodesOptions& cvodes);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  /// Evaluations with a Jacobian so far.
  int jacobian_evaluations() const noexcept { return jacobian_evaluations_; }

  /// The last evaluation with a Jacobian: its parameters and outputs.  Ceres' last Jacobian is
  /// that of its final point (it evaluates one at every accepted step only), which is where the
  /// covariance needs one: handed to the covariance's cost function (`reuse`), that evaluation
  /// answers it instead of a second CVODES run with sensitivities (half of LG's time on a record
  /// whose global stage already ended at the minimum).  Answers only the same parameters, bit for
  /// bit.
  struct Memo {
    std::vector<double> parameters, residuals, jacobian_theta, jacobian_state;
  };
  Memo take_memo() { return std::move(memo_); }
  void reuse(Memo memo) { memo_ = std::move(memo); }

 private:
  std::span<const double> time_, x_, force_;
  std::vector<Motion<double>> motions_;
  double scale_, z_ref_;
  StribeckShape shape_;
  LgJacobian jacobian_;
  CvodesOptions cvodes_;
  mutable int jacobian_evaluations_ = 0;
  mutable Memo memo_;
};

}  // namespace friction
