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

#include <ceres/iteration_callback.h>
#include <ceres/solver.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

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

// Stops a local search (NLR's, and a restart's extended fits: extension_steps.hpp) in two cases,
// both judged on the pace of its last `kWindow` iterations (decrease of the best cost per
// iteration over the window; rejected steps count as iterations without progress, which is why
// the window is not shorter):
//  * Hopeless: it cannot reach `target` (Ceres cost) within its iteration budget even if it kept
//    that pace: (best cost - target) > (iterations left) x pace.  Searches that crawl along a
//    valley of this piecewise-smooth cost (one start on the README's record took all 100
//    iterations, at 1e-5 relative per iteration, to end 75 % above the minimum another start had
//    reached in 8) are the ones it stops; a search still descending fast, or one that can still
//    end within the stall tolerance of the target, continues.  The extrapolation is linear, which
//    over-estimates what a decelerating search will gain.
//  * Converged to the noise: at that pace its whole budget of iterations would lower the RSS by
//    less than one noise variance sigma^2 (`noise_cost`, in cost units: 0.5 sigma^2), i.e. by less
//    than half a unit of log-likelihood; no parameter can move by a visible part of its standard
//    error.  LM crawls like this from kink to kink of the cost near a minimum (a polish on the
//    multisine bench record spent 60 of its 101 iterations gaining 0.2 sigma^2 in all), and
//    Ceres' relative function tolerance, which knows nothing of the noise, does not stop it.
// With `settled_trust_region` (a diagnosis candidate's fit: diagnose.hpp, section 3) a Ceres
// search is judged hopeless only over a window in which its trust region shrank by less than a
// factor 4.  Levenberg-Marquardt halves the region after a step whose decrease the local model
// did not predict (ratio near 0) and keeps it after one it predicted to about a quarter or better,
// so a region still collapsing is a search that has not yet found its descent, and its pace says
// nothing of what follows: a Stribeck curve on a study record's offset model (seed 20261207,
// stribeck+offset) crawled 601.2 -> 599.2 over its first ten iterations as its region fell from
// 1e4 to 11, then sped up and ended below the RSS the rules asked for.  A crawl along a valley
// keeps its region (the position term of data/'s third round: 2.7e4 -> 1.7e4 over ten
// iterations, 2.2209 -> 2.2208 of a target 2.118).
class HopelessSearch final : public ceres::IterationCallback {
 public:
  static constexpr std::size_t kWindow = 10;
  static constexpr double kSettledShrink = 4.0;
  HopelessSearch(double target, double noise_cost, int max_iterations,
                 bool settled_trust_region = false)
      : target_(target),
        noise_cost_(noise_cost),
        max_iterations_(max_iterations),
        settled_trust_region_(settled_trust_region) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& it) override {
    return keep_going(it.cost, it.trust_region_radius) ? ceres::SOLVER_CONTINUE
                                                       : ceres::SOLVER_TERMINATE_SUCCESSFULLY;
  }
  // `cost`: the search's cost [0.5 RSS] after its next iteration (or at its start); `radius`: its
  // trust region's then (read with settled_trust_region only).
  bool keep_going(double cost, double radius = 0.0) {
    const double best = best_.empty() ? cost : std::min(best_.back(), cost);
    best_.push_back(best);
    radius_.push_back(radius);
    const std::size_t k = best_.size() - 1;
    if (k < kWindow) return true;
    const double pace = (best_[k - kWindow] - best) / static_cast<double>(kWindow);
    if (noise_cost_ > 0.0 && pace * static_cast<double>(max_iterations_) < noise_cost_) {
      converged_ = true;
      return false;
    }
    if (!std::isfinite(target_) || best <= target_) return true;
    if (settled_trust_region_ && !(radius_[k] * kSettledShrink > radius_[k - kWindow])) return true;
    const double left = static_cast<double>(std::max(0, max_iterations_ - static_cast<int>(k)));
    if (best - target_ <= left * pace) return true;
    stopped_ = true;
    return false;
  }
  bool stopped() const { return stopped_; }
  bool converged() const { return converged_; }

 private:
  double target_, noise_cost_;
  int max_iterations_;
  bool settled_trust_region_;
  std::vector<double> best_, radius_;
  bool stopped_ = false, converged_ = false;
};

}  // namespace friction::detail
