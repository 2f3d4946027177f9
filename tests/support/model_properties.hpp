// A property-test harness reused across every model type (in the spirit of Sophus/manif).
//
// A model is described to the harness by a generic factory: a callable that takes the model's
// parameter vector as `std::vector<T>` for any scalar T and returns the model built from it, e.g.
//
//   auto factory = [](const auto& theta) {
//     using T = typename std::decay_t<decltype(theta)>::value_type;
//     return friction::MaxwellSlip<T>({{theta[0], theta[1]}, {theta[2], theta[3]}});
//   };
//
// From that alone the harness checks, for any model:
//   * the model satisfies the FrictionModel concept (static_assert in simulate);
//   * simulating with ceres::Jet gives the same force as with double;
//   * the Jet derivative of the simulated force with respect to every parameter matches a central
//     finite difference of the double simulation;
//   * `step` does not allocate.
#pragma once

#include <gtest/gtest.h>

#include <ceres/jet.h>

#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

#include "friction/motion.hpp"
#include "friction/simulate.hpp"
#include "support/allocation_counter.hpp"

namespace friction::testing {

/// A smooth test excitation with reversals of decreasing amplitude (exercises nonlocal memory)
/// followed by a slide: n samples at period ts, peak amplitude `amplitude` [m].
inline void test_excitation(std::size_t n, double ts, double amplitude, std::vector<double>& time,
                            std::vector<double>& x) {
  time.resize(n);
  x.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * ts;
    const double T = static_cast<double>(n) * ts;
    const double envelope = 1.0 - 0.7 * t / T;
    time[k] = t;
    x[k] = amplitude * envelope * std::sin(2.0 * M_PI * 3.0 * t / T) +
           0.3 * amplitude * std::sin(2.0 * M_PI * 11.0 * t / T);
  }
}

template <class Factory>
std::vector<double> simulate_with(const Factory& factory, const std::vector<double>& theta,
                                  const std::vector<double>& time, const std::vector<double>& x) {
  auto model = factory(theta);
  model.reset();
  return simulate(model, std::span<const double>(time), std::span<const double>(x));
}

/// Jet and double agree; Jet derivatives match central finite differences within `rel_tol`
/// (relative to the norm of the derivative over the record, per parameter).
template <class Factory>
void expect_derivatives_match_finite_differences(const Factory& factory,
                                                 const std::vector<double>& theta,
                                                 const std::vector<double>& time,
                                                 const std::vector<double>& x,
                                                 double rel_tol = 1e-5) {
  using Jet = ceres::Jet<double, 1>;
  const std::vector<double> f0 = simulate_with(factory, theta, time, x);
  std::vector<Jet> xj(x.begin(), x.end());
  for (std::size_t p = 0; p < theta.size(); ++p) {
    std::vector<Jet> theta_j(theta.size());
    for (std::size_t i = 0; i < theta.size(); ++i) theta_j[i] = Jet(theta[i]);
    theta_j[p].v[0] = 1.0;
    auto model = factory(theta_j);
    model.reset();
    std::vector<Jet> fj(x.size());
    simulate(model, std::span<const double>(time), std::span<const Jet>(xj), std::span<Jet>(fj));

    const double h = 1e-6 * std::max(std::abs(theta[p]), 1e-12);
    std::vector<double> plus = theta, minus = theta;
    plus[p] += h;
    minus[p] -= h;
    const auto fp = simulate_with(factory, plus, time, x);
    const auto fm = simulate_with(factory, minus, time, x);

    double value_err = 0, num = 0, den = 0;
    for (std::size_t k = 0; k < x.size(); ++k) {
      value_err = std::max(value_err, std::abs(fj[k].a - f0[k]));
      const double fd = (fp[k] - fm[k]) / (2 * h);
      num += (fj[k].v[0] - fd) * (fj[k].v[0] - fd);
      den += fd * fd;
    }
    const double scale = std::max(
        1.0, *std::max_element(f0.begin(), f0.end(),
                               [](double a, double b) { return std::abs(a) < std::abs(b); }));
    EXPECT_LE(value_err, 1e-12 * scale) << "Jet and double simulations differ";
    EXPECT_GT(den, 0.0) << "parameter " << p << " has no effect on the force";
    EXPECT_LE(std::sqrt(num), rel_tol * std::sqrt(den) + 1e-9)
        << "Jet derivative and finite difference differ for parameter " << p;
  }
}

/// Steps the model over the record once (warm), then again while counting allocations: none.
template <class Model>
void expect_step_does_not_allocate(Model& model, const std::vector<double>& time,
                                   const std::vector<double>& x) {
  using T = typename Model::Scalar;
  std::vector<T> xs(x.begin(), x.end());
  std::vector<Motion<T>> motions(x.size());
  for (std::size_t k = 0; k < x.size(); ++k)
    motions[k] = motion_at(std::span<const double>(time), std::span<const T>(xs), k);
  model.reset();
  T sum(0);
  AllocationCounter counter;
  for (const auto& m : motions) sum += model.step(m);
  EXPECT_EQ(counter.count(), 0u) << "step() allocated on the heap";
  EXPECT_TRUE(std::isfinite(static_cast<double>(sum)));
}

}  // namespace friction::testing
