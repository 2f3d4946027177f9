// bounded_levenberg_marquardt (src/bounded_levenberg_marquardt.hpp), NLR's local search: against
// the exact minimiser of random box-constrained linear least-squares problems (found here by
// trying every assignment of the parameters to free, lower or upper), a curved valley with its
// minimum on a bound, and the ways it stops.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <span>
#include <vector>

#include "../src/bounded_levenberg_marquardt.hpp"

namespace test_bounded_levenberg_marquardt {
namespace {

using friction::detail::bounded_levenberg_marquardt;
using friction::detail::BoundedLmOptions;
using friction::detail::BoundedLmTermination;

// 0.5 |A x - b|^2, its rows given whole.
struct Linear {
  Eigen::MatrixXd a;
  Eigen::VectorXd b;
  int costs = 0;
  bool cost(std::span<const double> x, double& c) {
    ++costs;
    c = 0.5 * (a * Eigen::Map<const Eigen::VectorXd>(x.data(), a.cols()) - b).squaredNorm();
    return true;
  }
  bool linearise(std::span<const double> x, Eigen::MatrixXd& rows, Eigen::VectorXd& e) {
    rows = a;
    e = a * Eigen::Map<const Eigen::VectorXd>(x.data(), a.cols()) - b;
    return true;
  }
};

// The minimiser of 0.5 |A x - b|^2 over the box, by trying each parameter free, at its lower or at
// its upper bound (3^n least-squares problems on the free ones), and keeping the lowest cost among
// the assignments whose free parameters land inside the box.  The problem is convex, so that is
// the minimum.
Eigen::VectorXd exact_minimiser(const Linear& p, const Eigen::VectorXd& lo,
                                const Eigen::VectorXd& hi, double& best) {
  const Eigen::Index n = p.a.cols();
  long assignments = 1;
  for (Eigen::Index i = 0; i < n; ++i) assignments *= 3;
  best = std::numeric_limits<double>::infinity();
  Eigen::VectorXd best_x;
  for (long code = 0; code < assignments; ++code) {
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    std::vector<Eigen::Index> free;
    long c = code;
    for (Eigen::Index i = 0; i < n; ++i, c /= 3) {
      if (c % 3 == 0) free.push_back(i);
      if (c % 3 == 1) x(i) = lo(i);
      if (c % 3 == 2) x(i) = hi(i);
    }
    if (!free.empty()) {
      Eigen::MatrixXd af(p.a.rows(), static_cast<Eigen::Index>(free.size()));
      for (std::size_t j = 0; j < free.size(); ++j)
        af.col(static_cast<Eigen::Index>(j)) = p.a.col(free[j]);
      const Eigen::VectorXd xf = af.colPivHouseholderQr().solve(p.b - p.a * x);
      bool inside = true;
      for (std::size_t j = 0; j < free.size(); ++j) {
        x(free[j]) = xf(static_cast<Eigen::Index>(j));
        inside = inside && x(free[j]) >= lo(free[j]) && x(free[j]) <= hi(free[j]);
      }
      if (!inside) continue;
    }
    const double cost = 0.5 * (p.a * x - p.b).squaredNorm();
    if (cost < best) best = cost, best_x = x;
  }
  return best_x;
}

BoundedLmOptions tight() {
  BoundedLmOptions o;
  o.function_tolerance = 1e-15;
  o.gradient_tolerance = 1e-13;
  o.parameter_tolerance = 1e-15;
  o.max_iterations = 200;
  return o;
}

auto never_stop = [](int, double) { return true; };

// Random problems of 2-6 parameters with columns of scales 1e-3..1e3 and correlated columns,
// boxes that cut off the unconstrained minimum in some coordinates and not others, and starts
// anywhere in the box (a third of them on a corner).  The search must end at the exact
// minimiser.  A bound-blind step (the unconstrained step, clamped) fails here: on the first
// problem it stalls short of the minimiser with a parameter on a bound.
TEST(BoundedLevenbergMarquardt, ReachesTheMinimiserOfRandomBoxedLinearProblems) {
  std::mt19937_64 gen(20261202);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  int active_bounds = 0, worst_iterations = 0;
  for (int trial = 0; trial < 80; ++trial) {
    const Eigen::Index n = 2 + static_cast<Eigen::Index>(trial % 5);
    const Eigen::Index m = n + static_cast<Eigen::Index>(unit(gen) * 3.0 * static_cast<double>(n));
    Linear p;
    p.a.resize(m, n);
    const Eigen::VectorXd common = Eigen::VectorXd::NullaryExpr(m, [&] { return normal(gen); });
    for (Eigen::Index j = 0; j < n; ++j) {
      const double columns_scale = std::pow(10.0, 6.0 * unit(gen) - 3.0);
      for (Eigen::Index i = 0; i < m; ++i)
        p.a(i, j) = columns_scale * (normal(gen) + 0.8 * common(i));
    }
    const Eigen::VectorXd truth = Eigen::VectorXd::NullaryExpr(n, [&] { return normal(gen); });
    p.b = p.a * truth;
    for (Eigen::Index i = 0; i < m; ++i) p.b(i) += 0.1 * p.a.row(i).norm() * normal(gen);
    Eigen::VectorXd lo(n), hi(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const double centre = truth(i) + 1.5 * normal(gen), half = 0.2 + unit(gen);
      lo(i) = centre - half, hi(i) = centre + half;
    }
    double best = 0;
    const Eigen::VectorXd exact = exact_minimiser(p, lo, hi, best);
    for (Eigen::Index i = 0; i < n; ++i)
      active_bounds += exact(i) == lo(i) || exact(i) == hi(i) ? 1 : 0;
    std::vector<double> x(static_cast<std::size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i) {
      const double u = trial % 3 == 0 ? (unit(gen) < 0.5 ? 0.0 : 1.0) : unit(gen);
      x[static_cast<std::size_t>(i)] = lo(i) + u * (hi(i) - lo(i));
    }
    std::vector<double> l(lo.data(), lo.data() + n), h(hi.data(), hi.data() + n);
    const auto s = bounded_levenberg_marquardt(p, std::span<double>(x), l, h, tight(), never_stop);
    ASSERT_EQ(s.termination, BoundedLmTermination::converged) << "trial " << trial << ": "
                                                              << s.message;
    EXPECT_LE(s.final_cost - best, 1e-9 * best + 1e-12) << "trial " << trial;
    for (Eigen::Index i = 0; i < n; ++i)
      EXPECT_NEAR(x[static_cast<std::size_t>(i)], exact(i), 1e-6 * (hi(i) - lo(i)))
          << "trial " << trial << ", parameter " << i;
    EXPECT_LE(s.cost_evaluations, s.iterations + 1) << "one evaluation per trial step";
    worst_iterations = std::max(worst_iterations, s.iterations);
  }
  EXPECT_GT(active_bounds, 60) << "the boxes must cut off many minima";
  // Seen: 0-22 steps, most below 10 (the free set is found a bound at a time on the tail).
  EXPECT_LE(worst_iterations, 40);
}

// Rosenbrock's valley, 0.5 (100 (x2 - x1^2)^2 + (1 - x1)^2), with x1 <= 0.5: the minimum
// (0.5, 0.25) is on the bound, where the gradient points out of the box.
struct Valley {
  int costs = 0;
  bool cost(std::span<const double> x, double& c) {
    ++costs;
    const double r1 = 10.0 * (x[1] - x[0] * x[0]), r2 = 1.0 - x[0];
    c = 0.5 * (r1 * r1 + r2 * r2);
    return true;
  }
  bool linearise(std::span<const double> x, Eigen::MatrixXd& rows, Eigen::VectorXd& e) {
    rows.resize(2, 2);
    rows << -20.0 * x[0], 10.0, -1.0, 0.0;
    e.resize(2);
    e << 10.0 * (x[1] - x[0] * x[0]), 1.0 - x[0];
    return true;
  }
};

TEST(BoundedLevenbergMarquardt, FollowsACurvedValleyToAMinimumOnItsBound) {
  Valley p;
  std::vector<double> x{-1.2, 1.0};
  const std::vector<double> lo{-2.0, -1.0}, hi{0.5, 2.0};
  const auto s = bounded_levenberg_marquardt(p, std::span<double>(x), lo, hi, tight(), never_stop);
  EXPECT_EQ(s.termination, BoundedLmTermination::converged) << s.message;
  EXPECT_EQ(x[0], 0.5);
  EXPECT_NEAR(x[1], 0.25, 1e-10);
  EXPECT_NEAR(s.final_cost, 0.125, 1e-12);
  EXPECT_LT(s.final_cost, s.initial_cost);
  EXPECT_EQ(s.cost_evaluations, p.costs);
}

// r(x) = exp(x) - exp(1/4), not finite beyond x = 0.3.  From x = -5 the Gauss-Newton step
// (1.28 / exp(-5), about 190) overshoots far into the non-finite region: the refused steps shrink
// the region until a step lands where the cost is finite.
struct Cliff {
  bool cost(std::span<const double> x, double& c) {
    c = x[0] > 0.3 ? std::numeric_limits<double>::infinity()
                   : 0.5 * std::pow(std::exp(x[0]) - std::exp(0.25), 2);
    return std::isfinite(c);
  }
  bool linearise(std::span<const double> x, Eigen::MatrixXd& rows, Eigen::VectorXd& e) {
    rows = Eigen::MatrixXd::Constant(1, 1, std::exp(x[0]));
    e = Eigen::VectorXd::Constant(1, std::exp(x[0]) - std::exp(0.25));
    return true;
  }
};

TEST(BoundedLevenbergMarquardt, StepsIntoANonFiniteCostAreRefused) {
  Cliff p;
  std::vector<double> x{-5.0};
  const std::vector<double> lo{-10.0}, hi{20.0};
  const auto s = bounded_levenberg_marquardt(p, std::span<double>(x), lo, hi, tight(), never_stop);
  EXPECT_EQ(s.termination, BoundedLmTermination::converged) << s.message;
  EXPECT_NEAR(x[0], 0.25, 1e-6);
  EXPECT_GT(s.iterations, s.jacobian_evaluations) << "some steps must have been refused";
}

TEST(BoundedLevenbergMarquardt, TheCallerStopsItAndAStartWithoutACostFails) {
  Valley p;
  std::vector<double> x{-5.0, 1.0};  // clamped to the box first
  const std::vector<double> lo{-2.0, -1.0}, hi{0.5, 2.0};
  int calls = 0;
  const auto s = bounded_levenberg_marquardt(p, std::span<double>(x), lo, hi, tight(),
                                             [&](int iteration, double cost) {
                                               EXPECT_EQ(iteration, calls);
                                               EXPECT_GT(cost, 0.0);
                                               return ++calls < 3;
                                             });
  EXPECT_EQ(s.termination, BoundedLmTermination::stopped);
  EXPECT_EQ(calls, 3);
  EXPECT_EQ(s.iterations, 2);
  EXPECT_GE(x[0], -2.0);

  Cliff c;
  std::vector<double> y{0.5};
  const std::vector<double> l1{-10.0}, h1{1.0};
  const auto f = bounded_levenberg_marquardt(c, std::span<double>(y), l1, h1, tight(), never_stop);
  EXPECT_EQ(f.termination, BoundedLmTermination::failure);
  EXPECT_EQ(y[0], 0.5);
}

}  // namespace
}  // namespace test_bounded_levenberg_marquardt
