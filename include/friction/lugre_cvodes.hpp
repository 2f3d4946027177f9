// LuGre over a whole record with SUNDIALS CVODES, with optional forward sensitivities.
//
// The velocity is the SAME piecewise-constant velocity the exact step uses (motion.hpp): v_k over
// (t_{k-1}, t_k].  Where v jumps, eq. 1's right-hand side is discontinuous, so the integrator is
// re-initialised there (CVodeReInit, and CVodeSensReInit) and stopped exactly at the end of the
// stretch of samples that share the velocity (CVodeSetStopTime); no multistep history is carried
// across a jump.  Within a stretch (a stroke at constant speed, an encoder count repeated) CVODES
// steps freely and interpolates each sample's state; velocities that agree to a hundredth of the
// relative tolerance count as one, since a displacement written in decimal gives a stroke's
// velocities that differ in their last bits.  Across a stretch the sensitivities enter the error
// test (the steps are no longer bounded by the sample interval).  On the strokes bench record
// (8,573 moving intervals in 936 stretches) this cut LG's CVODES check from 0.089 to 0.036 s
// and the Jacobian's relative difference from the exact step's from 2.2e-4 to 2.6e-5.
// Intervals with v = 0 are skipped: z and its sensitivities are constant there (eq. 1 is 0).
// The force of sample k is eq. 2 at t_k with the interval's velocity v_k, as in `LuGre::step`, and
// the force of sample 0 is sigma0 z0.
//
// Sensitivities.  z depends on sigma0, Fc, Fs, vs, mu and the initial state z0 (not on sigma1,
// sigma2), so CVODES integrates those six sensitivities s_p = dz/dp with
//     ds_p/dt = (df/dz) s_p + df/dp,
// where f is `lugre_rhs` (lugre.hpp) evaluated on ceres::Jet: one Jet evaluation gives the whole
// right-hand side of all six at once (CVSensRhsFn), with no hand-written derivative.  The force
// derivative dF/dtheta follows from eq. 2 evaluated on Jets whose z part carries s_p, so sigma1 and
// sigma2 get their explicit terms (dz/dt and v).  The Jacobian is returned row-major, N x 7, in
// `LuGreParameters::to_array()` order -- the layout Ceres expects for a residual block of N against
// one 7-parameter block -- optionally with respect to log(theta) (= theta dF/dtheta).  dF/dz0 comes
// separately, for identifying the initial state.  Sensitivities enter the error test
// only on request (`sensitivity_error_control`); their tolerances are scaled by the parameter
// magnitudes (CVodeSetSensParams' pbar, CVodeSensEEtolerances).
//
// Tolerances.  `absolute_tolerance` is in newtons on sigma0 z (the state tolerance is that over
// sigma0), so it means the same thing whatever the stiffness; `relative_tolerance` is on z.
//
// Method and tolerances, measured (Release, 2 shared cores; bench/bench_lugre.cpp's record: 10,000
// samples at 1 kHz, 3 s of presliding sinusoids of 2-5 um, then 7 s of sliding sweeps to +-20 mm/s;
// sigma1 = sqrt(sigma0), sigma2 = 0.5 N s/m, Fc = 1 N, Fs = 1.5 N, vs = 1e-3 m/s, mu = 2; dense
// direct 1x1 linear solver with the Jet df/dz, Newton iteration; error = max |F_cvodes - F_exact|
// over the record; defaults rtol = 1e-6, atol = 1e-8 N; CPU time per record):
//
//   sigma0 [N/m]  method  sensitivities  time [ms]  steps/sample  max error [N]
//   1e5           Adams   no               61          5.5          6.3e-6
//   1e5           BDF     no               63          6.3          2.6e-5
//   1e5           Adams   yes             277          5.5          6.3e-6
//   1e5           BDF     yes             320          6.3          2.6e-5
//   1e6           Adams   no               97         10.4          1.7e-5
//   1e6           BDF     no              113         12.8          7.0e-5
//   1e6           Adams   yes             528         10.4          1.7e-5
//   1e6           BDF     yes             612         12.8          7.0e-5
//   (exact step, for comparison: 0.36 ms per record; with Jet<7> derivatives 0.90 ms)
//
// Tolerance sweep (sigma0 = 1e5, atol = 1e-2 rtol [N]; max error Adams / BDF, steps per sample):
//   rtol 1e-4: 3.1e-4 / 7.9e-4 N, 2.8 / 2.9     rtol 1e-7: 1.1e-6 / 4.1e-6 N, 7.3 / 9.6
//   rtol 1e-5: 5.3e-5 / 1.3e-4 N, 3.9 / 4.3     rtol 1e-8: 1.6e-7 / 4.6e-7 N, 9.5 / 14.4
//   rtol 1e-6: 6.3e-6 / 2.6e-5 N, 5.5 / 6.3
// A faster sweep (+-0.1 m/s: relaxation rate |v|/s(v) up to 1e4 1/s at sigma0 = 1e5 and 1e5 1/s at
// 1e6) ranked them the same (Adams vs BDF: 1.3e-5 vs 2.6e-5 N at sigma0 = 1e5; 1.7e-5 vs 7.0e-5 N
// and 80 vs 134 ms at 1e6).
//
// Choice: Adams, rtol 1e-6, atol 1e-8 N.  Adams was faster and 2-4x more accurate at equal
// tolerances in every case.  The reason is the restart at every sample (that record's velocity
// changes at every sample): CVODES spends most of each 1 ms interval at orders 1-2, where
// Adams-Moulton (backward Euler, trapezoidal rule) is A-stable and, with Newton on the 1x1
// system, handles the stiff sliding relaxation as BDF does, with a smaller error constant.
// rtol 1e-6 keeps the force error near 1e-5 of the force level, below any force sensor's
// resolution, for 1.3-1.5x the time of rtol 1e-5.  Rejected after measuring: not
// restarting (stop time only, history carried across the velocity jump) took up to 35 % fewer steps
// but erred by 3.9e-3 N; an initial-step hint from the previous interval gained nothing;
// CV_SIMULTANEOUS changed the time by < 10 %.  Fused vector operations, measured then as well
// at < 10 %, are on since the stretches of one velocity: on the strokes bench record they take
// 2-3 ms off LG's 25 ms check with the same Jacobian to the bit.  Sensitivities
// cost 4.5-5.5x the plain run (the time goes into CVODES' per-vector operations, not the Jet
// right-hand side), 10-12x with their error control on.  For identification, Jets through the exact
// step (`LuGre<ceres::Jet>`) give the same Jacobian some 300x cheaper; these sensitivities are the
// integrator-side cross-check.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "friction/lugre.hpp"

namespace friction {

/// Linear multistep family of CVODES.
enum class CvodesMethod {
  Adams,  ///< Adams-Moulton, orders 1-12 (non-stiff)
  BDF,    ///< backward differentiation, orders 1-5 (stiff)
};

/// Integration options for `simulate_lugre_cvodes`.
struct CvodesOptions {
  CvodesMethod method = CvodesMethod::Adams;  // chosen by measurement (header comment)
  double relative_tolerance = 1e-6;           ///< on z
  double absolute_tolerance = 1e-8;           ///< [N] on sigma0 z
  bool sensitivities = false;                 ///< compute dF/dtheta (N x 7) and dF/dz0
  bool log_parameters = false;  ///< Jacobian with respect to log(theta) instead of theta
  /// Include the sensitivities in the local error test (CVodeSetSensErrCon).  Off by default: the
  /// steps chosen for z already resolve the sensitivities (same linear dynamics per interval);
  /// measured, the Jacobian's relative error was 4e-6 without and 1.5e-6 with it, at +40 % time.
  bool sensitivity_error_control = false;
  long max_steps_per_sample = 20000;  ///< CVodeSetMaxNumSteps for each sample interval
};

/// CVODES counters summed over the record.
struct CvodesStatistics {
  long steps = 0;
  long rhs_evaluations = 0;
  long sensitivity_rhs_evaluations = 0;
  long error_test_failures = 0;
  long nonlinear_iterations = 0;
  long intervals_integrated = 0;  ///< sample intervals with v != 0
  long restarts = 0;              ///< re-initialisations: where the velocity or the level jumps
};

/// Output of `simulate_lugre_cvodes`.
struct LuGreCvodesResult {
  std::vector<double> force;  ///< F_k [N], k = 0..N-1
  std::vector<double> state;  ///< z_k [m]
  /// Row-major N x 7: jacobian[7k + j] = dF_k / dtheta_j (or dF_k / dlog theta_j), theta in
  /// `LuGreParameters::to_array()` order.  Empty unless `CvodesOptions::sensitivities`.
  std::vector<double> jacobian;
  /// dF_k / dz0 [N/m].  Empty unless `CvodesOptions::sensitivities`.
  std::vector<double> initial_state_derivative;
  CvodesStatistics statistics;
};

/// Simulates the LuGre model over the record (`time` [s] strictly increasing, displacement `x` [m])
/// from the initial state z0 [m].  `level`, when not empty, is the slip-force scale factor of each
/// sample's interval (as in `simulate`).  `velocity`, when not empty, replaces the backward
/// difference of x as the interval velocity v_k (e.g. from `smoothed_interval_velocity`).
/// Throws InvalidParameter for bad parameters/inputs and NumericalError (with the CVODES flag and
/// the time) when CVODES fails.
LuGreCvodesResult simulate_lugre_cvodes(const LuGreParameters<double>& parameters,
                                        std::span<const double> time, std::span<const double> x,
                                        const CvodesOptions& options = {}, double z0 = 0.0,
                                        std::span<const double> level = {},
                                        std::span<const double> velocity = {});

}  // namespace friction
