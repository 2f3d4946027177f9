// Initial states of the Maxwell Slip operators, estimated from the record itself (methods.md 2).
//
// The state at the start of any record, estimation or validation, is unknown.  Every method here
// estimates it the same way, from the same record whose error is then reported, and every sample
// counts in that error (as MATLAB's `compare` does by default); outputs say
// `initial_state: "estimated"`.
//
// Structure exploited.  Operator i's deflection from the initial value d_i = delta_i(0) is
//
//     delta_i(t; d_i) = d_i + x(t) - x(0)      until it first reaches +-Delta_i,
//
// and after that first saturation it no longer depends on d_i at all (an operator at its bound
// forgets how it got there).  So d delta_i(t) / d d_i is the indicator "not yet saturated": 1 up
// to the first saturation, 0 after, and the force is piecewise linear in d with a Jacobian that
// is cheap and exact.  Every evaluation is made from these pieces, never by stepping the
// recursion: the first saturation is a binary search in the running maximum and minimum of
// x(t) - x(0), after it the operator follows the trajectory started at that bound (computed once),
// so a trajectory is two vectorised copies instead of a chain of N dependent clamps.  The
// estimate minimises sum_t (F(t) - Fhat(t; d))^2 over the box -Delta_i <= d_i <= Delta_i by
//   1. a scan over physically plausible states: the virgin state d = 0, and the states left by
//      sliding in either direction and then reversing by a travel u (d_i = s max(Delta_i - u,
//      -Delta_i), s = +-1, u on a geometric grid spanning the thresholds), plus a caller's
//      guess; the best of these starts
//   2. coordinate descent in which each operator's step is its exact global 1-D minimum (the cost
//      in one d_i is piecewise quadratic between the breakpoints where its first saturation
//      time changes; all pieces are minimised from prefix sums in O(N n^2));
//   3. projected Gauss-Newton on all operators together: each step a box-constrained linear
//      least-squares problem (active set), accepted only if the cost decreases.  It follows the
//      valleys in which early samples see only a weighted sum of deflections, which coordinate
//      steps cannot; 2 and 3 alternate while either improves.
// 2-3 are run from the best few scan candidates, the guess and a few seeded uniform starts in the
// box; the winner is then perturbed on three scales (3, 10, 30 % of each threshold: basin
// hopping) and refined again, keeping what improves, and last every pair of operators is moved
// along the valley in which the early samples see only Theta_i d_i + Theta_j d_j (a scan of the
// line across the box, its best point refined; `InitialStateOptions`).  On the four-operator
// test records single starts ended in minima with up to 10x the true state's cost, and local
// minima a few percent of a threshold apart were only left by the perturbations; with 3 + 8
// starts and 24 perturbations the true state (noise-free) or a lower cost (noisy) was reached.
// The result is deterministic (seeded).
//
// Only a prefix of the record depends on d: once the displacement has covered a range of
// 2 max(Delta_i) every operator has saturated whatever its initial deflection, and (n samples of
// filter lag later) the force no longer depends on d.  The estimate uses that prefix only, and
// each operator its own (the range 2 Delta_i is covered sooner): an evaluation costs the sum of
// the operators' prefixes, not M times the longest.
//
// The same routine serves DNLRX: its operators enter through a spring filter,
// Fhat(t) = sum_i sum_j filter(i, j) delta_i(t - j) + (terms that do not depend on d), with the
// record extended backwards at rest (delta_i(t < 0) = delta_i(0)).
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <span>
#include <vector>

#include "friction/maxwell_slip.hpp"
#include "friction/metrics.hpp"

namespace friction {

/// How hard the estimate searches (see the header comment).
struct InitialStateOptions {
  std::size_t refined_candidates = 3;  ///< best scan candidates refined by steps 2-3
  std::size_t random_starts = 8;       ///< extra seeded uniform starts in the box
  std::size_t perturbations = 24;      ///< basin-hopping perturbations of the winner
  unsigned seed = 1;
  std::size_t valley_points = 32;  ///< grid points of each pair's valley scan (0: none)

  /// One refined start and no global moves: for the many estimates inside an identification,
  /// whose result is refined again by the optimiser or by a final thorough estimate.
  static InitialStateOptions quick() { return {1, 0, 0, 1, 0}; }
};

/// Initial deflections d (|d_i| <= Delta_i) minimising the free-run error of
/// Fhat(t) = sum_i sum_j filter(i, j) delta_i(t - j) against `target` (the measured force minus
/// every term that does not depend on the operators).  `filter` is M x (n + 1); `guess`, when not
/// empty, is one more candidate start.
std::vector<double> estimate_initial_deflections(std::span<const double> x,
                                                 std::span<const double> target,
                                                 std::span<const double> thresholds,
                                                 const Eigen::MatrixXd& filter,
                                                 std::span<const double> guess = {},
                                                 const InitialStateOptions& options = {});

/// Maxwell Slip form: filter = stiffnesses (n = 0), parameters fixed.
std::vector<double> estimate_initial_deflections(const MaxwellSlipParameters<double>& parameters,
                                                 std::span<const double> x,
                                                 std::span<const double> force,
                                                 std::span<const double> guess = {},
                                                 const InitialStateOptions& options = {});

/// A free run of a Maxwell Slip model from an estimated initial state, and its errors.
struct FreeRun {
  std::vector<double> initial_deflections;  ///< estimated delta_i(0) [m]
  std::vector<double> simulated;            ///< Fhat [N]
  ErrorMetrics errors;                      ///< against the measured force, every sample
};

/// Validation of a Maxwell Slip model with fixed parameters on a record: the initial state is
/// estimated from the record (nothing else is), then the model runs free on its displacement.
FreeRun free_run_maxwell_slip(const MaxwellSlipParameters<double>& parameters,
                              std::span<const double> time, std::span<const double> x,
                              std::span<const double> force);

}  // namespace friction
