// Levenberg-Marquardt in a box, with the bound-respecting step NLR's searches need.
//
// Ceres solves a bounded problem by computing the unconstrained trust-region step, clamping the
// trial point into the box and following it with a projected Armijo line search.  The predicted
// decrease it checks the clamped point against is the unclamped step's.  Where a parameter sits
// at its bound and the step pushes it outward, the clamped path does not descend as predicted:
// the search contracts 20 times, fails, and the step is taken or refused anyway.  Measured on
// NLR's fit of the envelope bench record (README, "The projected line search, measured"): 150
// evaluations of the cost for 21 Jacobians, a third of them in failed searches.
//
// Here the step is solved on the free parameters only, as in projected Newton methods
// (Bertsekas 1982): parameter i is held where it is when it lies on a bound and the gradient
// g = J^T r points out of the box there (x_i = l_i and g_i > 0, or x_i = u_i and g_i < 0); the
// others take the Levenberg-Marquardt step
//
//     (J_F^T J_F + D_F / radius) delta_F = -J_F^T r,     D = diag(J^T J) clamped to [1e-6, 1e32],
//
// in the columns scaled by 1 / (1 + |J_j|) at the first Jacobian (Ceres' Jacobi scaling, so that
// radius means what it means there).  The trial point is the step clamped into the box, and the
// ratio that accepts it compares the actual decrease with the decrease the linear model predicts
// for that clamped step p, -(g.p + |J p|^2 / 2): no line search, one evaluation per trial.  The
// radius follows Nielsen's rule as Ceres' does (grows by up to 3 after a step with ratio near 1,
// halves, then quarters, ... after a refused one).
//
// Stops, as Ceres' do: the projected gradient max_i |P(x - g) - x|_i below `gradient_tolerance`;
// a trial step shorter than `parameter_tolerance` (|x| + `parameter_tolerance`); a trial that
// changes the cost by less than `function_tolerance` of it, up or down; the radius below 1e-32;
// the iteration budget; or the caller's callback.
//
// The problem supplies the cost 0.5 |r(x)|^2 and, at a point, any rows (R, e) with R^T R = J^T J
// and R^T e = J^T r: the residuals and their Jacobian, or a compressed form of them (NLR's 2M + 1
// rows).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "friction/error.hpp"

namespace friction::detail {

struct BoundedLmOptions {
  int max_iterations = 100;  ///< trial steps, accepted or not
  double function_tolerance = 1e-6;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  double initial_radius = 1e4;
  double min_relative_decrease = 1e-3;  ///< the ratio a step needs to be accepted
};

enum class BoundedLmTermination { converged, no_convergence, stopped, failure };

struct BoundedLmSummary {
  double initial_cost = 0, final_cost = 0;
  int iterations = 0;  ///< trial steps, accepted or not
  int cost_evaluations = 0, jacobian_evaluations = 0;
  BoundedLmTermination termination = BoundedLmTermination::no_convergence;
  std::string message;
};

// Problem: bool cost(std::span<const double> x, double& cost);
//          bool linearise(std::span<const double> x, Eigen::MatrixXd& rows, Eigen::VectorXd& e);
//          (false: not finite there.  linearise is asked at points whose cost was just asked.)
// Callback: bool(int iteration, double cost), called at the start (iteration 0) and after every
// trial step with the cost at the current point; false stops the search where it is.
// x is moved into the box first.
template <class Problem, class Callback>
BoundedLmSummary bounded_levenberg_marquardt(Problem& problem, std::span<double> x,
                                             std::span<const double> lower,
                                             std::span<const double> upper,
                                             const BoundedLmOptions& o, Callback&& callback) {
  const std::size_t n = x.size();
  FRICTION_CHECK(lower.size() == n && upper.size() == n,
                 "bounded_levenberg_marquardt: bounds of the wrong length");
  for (std::size_t i = 0; i < n; ++i) {
    FRICTION_CHECK(lower[i] <= upper[i], "bounded_levenberg_marquardt: lower bound ", i,
                   " above the upper");
    x[i] = std::clamp(x[i], lower[i], upper[i]);
  }
  BoundedLmSummary s;
  auto stop = [&s](BoundedLmTermination t, std::string why, double value = 0, double bound = 0) {
    s.termination = t;
    s.message = std::move(why);
    if (bound > 0) {
      char numbers[64];
      std::snprintf(numbers, sizeof numbers, ": %e <= %e", value, bound);
      s.message += numbers;
    }
    return s;
  };
  const Eigen::Index ni = static_cast<Eigen::Index>(n);
  Eigen::Map<Eigen::VectorXd> xv(x.data(), ni);
  const Eigen::Map<const Eigen::VectorXd> lo(lower.data(), ni), hi(upper.data(), ni);
  double f = 0;
  ++s.cost_evaluations;
  if (!problem.cost(x, f) || !std::isfinite(f))
    return stop(BoundedLmTermination::failure, "the cost is not finite at the start");
  s.initial_cost = s.final_cost = f;
  Eigen::MatrixXd jac;
  Eigen::VectorXd e;
  ++s.jacobian_evaluations;
  if (!problem.linearise(x, jac, e) || !jac.allFinite() || !e.allFinite())
    return stop(BoundedLmTermination::failure, "the Jacobian is not finite at the start");
  FRICTION_CHECK(jac.cols() == ni && jac.rows() == e.size(),
                 "bounded_levenberg_marquardt: the problem's rows do not match its parameters");
  if (!callback(0, f)) return stop(BoundedLmTermination::stopped, "stopped by the caller");

  // Jacobi scaling from the first Jacobian.
  const Eigen::VectorXd scale = (1.0 + jac.colwise().norm().array()).inverse().matrix().transpose();
  double radius = o.initial_radius, decrease = 2.0;
  Eigen::VectorXd g, trial(ni), step(ni), free_step;
  Eigen::MatrixXd scaled, normal;
  std::vector<Eigen::Index> free;
  bool linearised = true;
  while (s.iterations < o.max_iterations) {
    if (linearised) {
      g.noalias() = jac.transpose() * e;
      double projected = 0;
      for (Eigen::Index i = 0; i < ni; ++i)
        projected = std::max(projected, std::abs(std::clamp(xv(i) - g(i), lo(i), hi(i)) - xv(i)));
      if (projected <= o.gradient_tolerance)
        return stop(BoundedLmTermination::converged,
                    "Gradient tolerance reached. max |P(x - g) - x|", projected,
                    o.gradient_tolerance);
      free.clear();
      for (Eigen::Index i = 0; i < ni; ++i)
        if (!((xv(i) <= lo(i) && g(i) > 0.0) || (xv(i) >= hi(i) && g(i) < 0.0))) free.push_back(i);
      if (free.empty())
        return stop(BoundedLmTermination::converged, "every parameter is held at a bound");
      const Eigen::Index nf = static_cast<Eigen::Index>(free.size());
      scaled.resize(jac.rows(), nf);
      for (Eigen::Index j = 0; j < nf; ++j) scaled.col(j) = jac.col(free[j]) * scale(free[j]);
      normal.noalias() = scaled.transpose() * scaled;
      linearised = false;
    }
    const Eigen::Index nf = static_cast<Eigen::Index>(free.size());
    Eigen::MatrixXd damped = normal;
    Eigen::VectorXd rhs(nf);
    for (Eigen::Index j = 0; j < nf; ++j) {
      damped(j, j) += std::clamp(normal(j, j), 1e-6, 1e32) / radius;
      rhs(j) = -scale(free[j]) * g(free[j]);
    }
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(damped);
    free_step = ldlt.solve(rhs);
    step.setZero();
    if (ldlt.info() == Eigen::Success && free_step.allFinite())
      for (Eigen::Index j = 0; j < nf; ++j) step(free[j]) = scale(free[j]) * free_step(j);
    trial = (xv + step).cwiseMax(lo).cwiseMin(hi);
    step = trial - xv;
    ++s.iterations;
    const double shortest = o.parameter_tolerance * (xv.norm() + o.parameter_tolerance);
    if (step.norm() <= shortest)
      return stop(BoundedLmTermination::converged, "Parameter tolerance reached. |step|",
                  step.norm(), shortest);
    const double predicted = -(g.dot(step) + 0.5 * (jac * step).squaredNorm());
    double ft = std::numeric_limits<double>::infinity();
    ++s.cost_evaluations;
    const bool finite = problem.cost(std::span<const double>(trial.data(), n), ft) &&
                        std::isfinite(ft);
    // As in Ceres, a trial that changes the cost by less than the tolerance, up or down, ends
    // the search (the better of the two points kept): the model has nothing left to offer here.
    if (finite && std::abs(f - ft) <= o.function_tolerance * f) {
      const double change = std::abs(f - ft) / f;
      if (ft < f) xv = trial, f = s.final_cost = ft;
      return stop(BoundedLmTermination::converged, "Function tolerance reached. |cost_change|/cost",
                  change, o.function_tolerance);
    }
    const double ratio = finite && predicted > 0.0 ? (f - ft) / predicted : -1.0;
    if (ratio > o.min_relative_decrease) {
      xv = trial;
      f = s.final_cost = ft;
      radius = std::min(1e16, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * ratio - 1.0, 3)));
      decrease = 2.0;
      ++s.jacobian_evaluations;
      if (!problem.linearise(x, jac, e) || !jac.allFinite() || !e.allFinite())
        return stop(BoundedLmTermination::failure,
                    "the Jacobian is not finite at an accepted step");
      linearised = true;
    } else {
      radius /= decrease;
      decrease *= 2.0;
      if (radius < 1e-32)
        return stop(BoundedLmTermination::converged,
                    "Minimum trust region radius reached (1e-32): no step lowers the cost");
    }
    if (!callback(s.iterations, f))
      return stop(BoundedLmTermination::stopped, "stopped by the caller");
  }
  return stop(BoundedLmTermination::no_convergence, "iteration budget used");
}

}  // namespace friction::detail
