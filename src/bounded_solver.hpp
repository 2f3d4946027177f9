// Solver options of the bounded least-squares fits that run in Ceres (DNLRX, LG, the extended
// fits, NLR's joint solver; NLR's variable-projection search has its own bounded step,
// bounded_levenberg_marquardt.hpp).
//
// With bounds on a parameter block, Ceres' trust-region minimiser follows every step with a
// projected Armijo line search along it (TrustRegionMinimizer, "is_constrained").  Its default
// interpolation is CUBIC, which needs the gradient at each trial point: a full Jacobian of the
// residuals at x + delta, on top of the Jacobian the minimiser computes again at the accepted point
// and the cost it evaluates there.  With the Jacobians of the slip models that second Jacobian was
// the largest single cost of a diagnosis (41 % of `diagnose` on data/, perf).  QUADRATIC
// interpolation contracts a failed step from values alone: the trial at step 1 costs one
// evaluation of the residuals, and a step that meets the sufficient decrease at once (nearly all
// of them) needs nothing more.
#pragma once

#include <ceres/solver.h>

#include <cstddef>

namespace friction::detail {

inline void use_value_only_line_search(ceres::Solver::Options& so) {
  so.line_search_interpolation_type = ceres::QUADRATIC;
}

// The relative function tolerance of a fit of N residuals: a search stops once a step lowers the
// RSS by less than 1 % of one residual variance (RSS / N).  Near a minimum the remaining decrease
// is about delta^2 residual variances at a distance of delta standard errors, so the fit is then
// within about a tenth of a standard error of it.  The fixed tolerances before (1e-7 to 1e-9) were
// 10-100x tighter at N = 10^4: LG on data/ spent 8 of its 16 iterations (0.8 of 1.65 s) changing
// its RSS by 4e-5 of itself; the round-trip studies gave the same coverage either way (LG and
// DNLRX to three digits, NLR's z-scores within 0.002).
inline double resolved_function_tolerance(std::size_t residuals) {
  return 0.01 / static_cast<double>(residuals);
}

}  // namespace friction::detail
