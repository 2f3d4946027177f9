// Free-run simulation of a model over a whole record.
//
// The model is driven by displacement alone (never by measured force), from whatever state it is
// in when called: `reset()` it first for the virgin state, or set an estimated initial state.
// Sample 0 produces the force of the initial state (no motion); sample k > 0 advances over the
// interval (t_{k-1}, t_k] with the piecewise-constant velocity (x_k - x_{k-1}) / (t_k - t_{k-1})
// (see motion.hpp).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "friction/error.hpp"
#include "friction/model_concept.hpp"
#include "friction/motion.hpp"

namespace friction {

/// Simulate `model` on displacement `x` [m] sampled at `time` [s]; writes the force [N] to `force`.
/// `level`, when not empty, is the slip-force scale factor per sample (methods.md section 7).
template <class Model, typename T = typename Model::Scalar>
void simulate(Model& model, std::span<const double> time, std::span<const T> x, std::span<T> force,
              std::span<const T> level = {}) {
  static_assert(FrictionModel<Model>,
                "simulate() needs a friction model: Scalar, reset() and step(const Motion<T>&)");
  FRICTION_CHECK(time.size() == x.size() && force.size() == x.size(),
                 "simulate: time, displacement and force must have the same length");
  FRICTION_CHECK(level.empty() || level.size() == x.size(),
                 "simulate: level must be empty or as long as the record");
  for (std::size_t k = 0; k < x.size(); ++k)
    force[k] = model.step(motion_at(time, x, k, level.empty() ? T(1) : level[k]));
}

/// Convenience overload returning the simulated force.
template <class Model, typename T = typename Model::Scalar>
std::vector<T> simulate(Model& model, std::span<const double> time, std::span<const T> x) {
  std::vector<T> force(x.size());
  simulate(model, time, x, std::span<T>(force));
  return force;
}

}  // namespace friction
