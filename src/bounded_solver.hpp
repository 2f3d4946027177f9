// Solver options of the bounded least-squares fits (NLR, DNLRX, the extended Maxwell Slip fits).
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

namespace friction::detail {

inline void use_value_only_line_search(ceres::Solver::Options& so) {
  so.line_search_interpolation_type = ceres::QUADRATIC;
}

}  // namespace friction::detail
